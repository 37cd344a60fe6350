"""Platform files: a motion platform described in YAML, packaged ones chosen by name.

A platform file holds one tagged description (`!SerialRobot`, `!Hexapod`, `!Rig`); a scenario's
`platform` field takes the serial robot's inline:

    !SerialRobot
    name: kr500
    urdf: kr500.urdf          # relative to the file's folder
    head_frame: head
    home: [0, 0, 0, 0, 0, 0]

The package carries its platforms in `models/` (`packaged_platforms`); a command's
`--platform` takes a packaged name or a file (`load_platform`). Files are read with PyYAML's
safe loader (no code runs, no Drake needed), each tag building its typed description.
(No `from __future__ import annotations` here: Drake's YAML loader reads a scenario's
inline description through the real field types.)
"""

import dataclasses
import os
from pathlib import Path
from typing import Union

import yaml

from mca_drake.platforms.leg_platform import COORDINATES, LegPlatform, leg_platform
from mca_drake.platforms.legs import Cranks, LegGeometry
from mca_drake.platforms.serial import SerialChain, serial_chain_from_urdf
from mca_drake.resources import packaged_folder

# The platform every scenario and command means when it names none.
DEFAULT_PLATFORM = "kr500"


@dataclasses.dataclass
class SerialRobot:
    """A serial robot, with or without a rail, from its URDF (`mca_drake.platforms.serial`)."""

    # The platform's name, as results and policy files record it; a file's stem if empty.
    name: str = ""
    # The URDF: a path relative to the platform file's folder (or absolute).
    urdf: str = ""
    # The URDF link or frame that is the occupant's head (x forward, y left, z up at home).
    head_frame: str = "head"
    # The neutral pose, one value per joint (rad, m for a prismatic joint); empty: zeros.
    home: list[float] = dataclasses.field(default_factory=list)
    # The classical washout's working pose, away from singularities; empty: home.
    washout_home: list[float] = dataclasses.field(default_factory=list)
    # Per joint, for a URDF without drake:acceleration limits (rad/s^2 or m/s^2).
    acceleration_limits: list[float] = dataclasses.field(default_factory=list)
    # Per joint, the signs that mirror the cabin's motion left to right; empty: none.
    mirror_joint_signs: list[float] = dataclasses.field(default_factory=list)
    # Where the description says its numbers come from (maker's data sheet, paper, ...).
    source: str = ""

    def build(self, base_dir: str | os.PathLike = ".") -> SerialChain:
        """The kinematic description, with `urdf` read relative to `base_dir`."""
        if not self.urdf:
            raise ValueError("a !SerialRobot platform needs `urdf`: the robot's URDF file")
        if not self.name:
            raise ValueError("a !SerialRobot platform needs a `name`")
        return serial_chain_from_urdf(
            Path(base_dir) / self.urdf,
            name=self.name,
            head_frame=self.head_frame,
            home=self.home,
            washout_home=self.washout_home,
            acceleration_limits=self.acceleration_limits,
            mirror_joint_signs=self.mirror_joint_signs,
        )


@dataclasses.dataclass
class _Legs:
    """What every platform moved by legs states: its legs' joints and limits, its head and
    its payload (`Hexapod` and `Rig` add how its pose is laid out)."""

    # The platform's name, as results and policy files record it; a file's stem if empty.
    name: str = ""
    # Where each leg attaches: on the base (base frame: x forward, y left, z up; origin in
    # the joints' plane), m, one [x, y, z] per leg, and on the moving platform (its frame,
    # whose origin is the point it turns about), m, leg i from base joint i.
    base_joints: list[list[float]] = dataclasses.field(default_factory=list)
    platform_joints: list[list[float]] = dataclasses.field(default_factory=list)
    # The moving platform's origin above the base frame at the neutral pose, m.
    neutral_height: float = 0.0
    # The legs' length range between joint centres, m (linear legs, listed joints).
    min_length: float = 0.0
    max_length: float = 0.0
    # The actuators' speed and acceleration limits: m/s and m/s^2 along linear legs, rad/s
    # and rad/s^2 of a crank's arm.
    max_speed: float = 0.0
    max_acceleration: float = 0.0
    # Rotary actuators (`legs.Cranks`): a motor at each base joint turns an arm of this
    # length, m, and a rod joins the arm's tip to the platform joint; the actuators'
    # positions are the arms' angles, rad. 0: linear legs.
    arm_length: float = 0.0
    # With cranks and listed joints: the rods' length, m; each arm's direction at angle 0
    # and its motor's axis (unit [x, y, z] in the base frame, one per leg; positive angles
    # turn the arm about the axis by the right-hand rule); the arms' angle range, rad.
    rod_length: float = 0.0
    arm_directions: list[list[float]] = dataclasses.field(default_factory=list)
    motor_axes: list[list[float]] = dataclasses.field(default_factory=list)
    min_angle: float = 0.0
    max_angle: float = 0.0
    # The occupant's head in the moving platform's frame, m.
    head_position: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 1.0])
    # The moving mass (platform, cabin or seat, occupant), kg, and its principal inertias,
    # kg m^2.
    payload_mass: float = 1000.0
    payload_inertia: list[float] = dataclasses.field(default_factory=lambda: [500.0] * 3)
    # Where the description says its numbers come from (maker's data sheet, paper, ...).
    source: str = ""

    def listed_geometry(self) -> LegGeometry:
        """The legs as listed, validated (`LegGeometry.validate`)."""
        cranks, low, high = None, self.min_length, self.max_length
        if self.arm_length:
            if self.min_length or self.max_length:
                raise ValueError(
                    "legs turned by cranks (arm_length) give min_angle and max_angle, rad, "
                    "not min_length and max_length"
                )
            cranks = Cranks(
                arm_length=self.arm_length,
                rod_length=self.rod_length,
                arm_directions=self.arm_directions,
                motor_axes=self.motor_axes,
            )
            low, high = self.min_angle, self.max_angle
        else:
            self._no_crank_fields("linear legs (no arm_length)")
        geometry = LegGeometry(
            base_joints=self.base_joints,
            platform_joints=self.platform_joints,
            neutral_height=self.neutral_height,
            min_position=low,
            max_position=high,
            max_speed=self.max_speed,
            max_acceleration=self.max_acceleration,
            cranks=cranks,
        )
        geometry.validate()
        return geometry

    def _no_crank_fields(self, what: str) -> None:
        """Raises ValueError where a crank's listed fields are set for `what`."""
        listed = ("rod_length", "arm_directions", "motor_axes", "min_angle", "max_angle")
        given = [name for name in listed if getattr(self, name)]
        if given:
            raise ValueError(f"{', '.join(given)} describe listed cranks; {what} take none")

    def _build(self, geometry: LegGeometry, coordinates, tag: str) -> LegPlatform:
        if not self.name:
            raise ValueError(f"a {tag} platform needs a `name`")
        return leg_platform(
            geometry,
            name=self.name,
            coordinates=coordinates,
            head_position=self.head_position,
            payload_mass=self.payload_mass,
            payload_inertia=self.payload_inertia,
            source=self.source,
        )


@dataclasses.dataclass
class Hexapod(_Legs):
    """A Stewart-platform hexapod from its legs' geometry and limits
    (`mca_drake.platforms.leg_platform`): its six legs' joints listed, or the symmetric 6-6
    layout of `LegGeometry.symmetric` by radii and angles (then `stroke`, centred on the
    neutral position, instead of min_length and max_length); linear legs, or rotary
    actuators with `arm_length` (a hobby hexapod's servos)."""

    # The symmetric layout (where no joints are listed): the joint circles' radii, m, and
    # half the angle between a pair's two joints on each, rad.
    base_radius: float = 0.0
    platform_radius: float = 0.0
    base_half_angle: float = 0.0
    platform_half_angle: float = 0.0
    # The actuators' range centred on their neutral position: m of leg length; rad of arm
    # angle with cranks (the arms horizontal at the neutral pose).
    stroke: float = 0.0

    def geometry(self) -> LegGeometry:
        """The legs, validated (`LegGeometry.validate`)."""
        listed = bool(self.base_joints or self.platform_joints)
        symmetric = (
            self.base_radius,
            self.platform_radius,
            self.base_half_angle,
            self.platform_half_angle,
        )
        if listed and any(symmetric):
            raise ValueError(
                "a !Hexapod lists its joints (base_joints, platform_joints) or gives the "
                "symmetric layout (base_radius, platform_radius, base_half_angle, "
                "platform_half_angle), not both"
            )
        if listed:
            if self.stroke:
                raise ValueError("a !Hexapod with listed joints gives min_length and max_length")
            return self.listed_geometry()
        if not all(v > 0 for v in symmetric[:2]) or self.stroke <= 0:
            raise ValueError(
                "a !Hexapod needs base_joints and platform_joints, or base_radius, "
                "platform_radius, base_half_angle, platform_half_angle and stroke"
            )
        if self.min_length or self.max_length:
            raise ValueError("a symmetric !Hexapod gives stroke, not min/max_length")
        self._no_crank_fields("a symmetric !Hexapod (its cranks follow from arm_length)")
        geometry = LegGeometry.symmetric(
            *symmetric,
            neutral_height=self.neutral_height,
            stroke=self.stroke,
            max_speed=self.max_speed,
            max_acceleration=self.max_acceleration,
            arm_length=self.arm_length,
        )
        geometry.validate()
        return geometry

    def build(self, base_dir: str | os.PathLike = ".") -> LegPlatform:
        """The platform (`leg_platform`); `base_dir` is unused (nothing to read)."""
        geometry = self.geometry()
        if len(geometry.base_joints) != 6:
            raise ValueError(
                f"a !Hexapod has six legs; got {len(geometry.base_joints)} (a rig with fewer "
                "is a !Rig)"
            )
        return self._build(geometry, COORDINATES, "!Hexapod")


@dataclasses.dataclass
class Rig(_Legs):
    """A 2- or 3-DOF motion rig moved by linear actuators (`mca_drake.platforms.leg_platform`):
    the pose coordinates its mechanism leaves free, and its actuators' joints."""

    # The pose coordinates it moves in, in chain order: [pitch, roll] (a 2-DOF seat on a
    # pivot), [heave, pitch, roll] (a 3-DOF rig); the mechanism holds the others at zero.
    coordinates: list[str] = dataclasses.field(default_factory=list)

    def build(self, base_dir: str | os.PathLike = ".") -> LegPlatform:
        """The platform (`leg_platform`); `base_dir` is unused (nothing to read)."""
        if not self.coordinates:
            raise ValueError("a !Rig lists the coordinates it moves in, e.g. [pitch, roll]")
        return self._build(self.listed_geometry(), self.coordinates, "!Rig")


# The descriptions a platform file or a scenario's `platform` field can hold, by YAML tag.
PLATFORM_KINDS = {"!SerialRobot": SerialRobot, "!Hexapod": Hexapod, "!Rig": Rig}
PlatformDescription = SerialRobot | Hexapod | Rig
# A config's `platform` field: a packaged name or a file, or a description inline (Drake's
# YAML loader reads the tag: !SerialRobot {...}, !Hexapod {...}, !Rig {...}).
PlatformField = Union[str, SerialRobot, Hexapod, Rig]  # noqa: UP007 (YAML loader)


def _loader() -> type[yaml.SafeLoader]:
    """PyYAML's safe loader that builds the platform descriptions from their tags."""

    class PlatformLoader(yaml.SafeLoader):
        pass

    for tag, kind in PLATFORM_KINDS.items():

        def construct(loader, node, kind=kind, tag=tag):
            if not isinstance(node, yaml.MappingNode):
                raise ValueError(f"{tag} needs a mapping of its fields")
            fields = loader.construct_mapping(node, deep=True)
            return _typed(kind, fields, tag)

        PlatformLoader.add_constructor(tag, construct)
    return PlatformLoader


def _is_number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _typed(kind: type, fields: dict, tag: str):
    """`kind(**fields)` after checking names and value types (by each field's type)."""
    valid = {f.name: f for f in dataclasses.fields(kind)}
    unknown = sorted(set(fields) - set(valid))
    if unknown:
        raise ValueError(f"{tag}: unknown fields {unknown}; valid: {', '.join(valid)}")
    for name, value in fields.items():
        declared = valid[name].type
        if declared == list[float]:
            if not isinstance(value, list) or not all(_is_number(v) for v in value):
                raise ValueError(f"{tag}: {name} must be a list of numbers; got {value!r}")
            fields[name] = [float(v) for v in value]
        elif declared == list[list[float]]:
            if not isinstance(value, list) or not all(
                isinstance(row, list) and all(_is_number(v) for v in row) for row in value
            ):
                raise ValueError(f"{tag}: {name} must be a list of [x, y, z] points; got {value!r}")
            fields[name] = [[float(v) for v in row] for row in value]
        elif declared == list[str]:
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise ValueError(f"{tag}: {name} must be a list of names; got {value!r}")
        elif declared is float:
            if not _is_number(value):
                raise ValueError(f"{tag}: {name} must be a number; got {value!r}")
            fields[name] = float(value)
        elif not isinstance(value, str):
            raise ValueError(f"{tag}: {name} must be text; got {value!r}")
    return kind(**fields)


def read_platform_file(path: str | os.PathLike) -> PlatformDescription:
    """The description a platform file holds (not yet built; see `load_platform`).

    Raises:
        FileNotFoundError: no such file.
        ValueError: not YAML, no platform tag, unknown fields or wrong types.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"platform file not found: {path}")
    try:
        document = yaml.load(path.read_text(), Loader=_loader())
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not a platform file: {err}") from err
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err
    if not isinstance(document, tuple(PLATFORM_KINDS.values())):
        raise ValueError(
            f"{path}: a platform file holds one tagged description "
            f"({', '.join(PLATFORM_KINDS)}); got {type(document).__name__}"
        )
    if not document.name:
        document = dataclasses.replace(document, name=path.stem)
    return document


def model_path(name: str) -> Path:
    """Absolute path of a file in the package's models folder, e.g. `model_path("kr500.urdf")`.

    Raises:
        FileNotFoundError: no such file; the message lists the folder's files.
    """
    folder = packaged_folder("models")
    path = folder / name
    if not path.is_file():
        available = sorted(p.name for p in folder.iterdir())
        raise FileNotFoundError(f"no model '{name}' in {folder}; available: {available}")
    return path


def packaged_platforms() -> dict[str, Path]:
    """The platform files the package carries, by name (file name without `.yaml`)."""
    return {p.stem: p for p in sorted(packaged_folder("models").glob("*.yaml"))}


def packaged_name(platform) -> str:
    """The packaged platform's name that `platform` (a name, a file or a description) is,
    or "" for a user's file or description."""
    return platform if isinstance(platform, str) and platform in packaged_platforms() else ""


def platform_file(name_or_path: str | os.PathLike) -> Path:
    """A platform file given by its packaged name or its path.

    Raises:
        FileNotFoundError: neither; the message lists the packaged names.
    """
    packaged = packaged_platforms()
    if str(name_or_path) in packaged:
        return packaged[str(name_or_path)]
    path = Path(name_or_path)
    if path.is_file():
        return path
    raise FileNotFoundError(
        f"unknown platform '{name_or_path}': not a file, nor a packaged platform; "
        f"packaged: {', '.join(packaged)}"
    )


def load_platform(
    platform: str | os.PathLike | PlatformDescription, base_dir: str | os.PathLike = "."
) -> SerialChain:
    """The platform's description, ready for the MCAs and plants.

    Args:
        platform: a packaged name ("kr500", "kr500-rail"), a platform file, or a description
            (as a scenario's `platform` field holds it): a serial robot's
            `SerialChain`, a hexapod's `LegPlatform` (a `SerialChain` too).
        base_dir: where a description's relative `urdf` path starts (a scenario's folder).

    Raises:
        FileNotFoundError: an unknown name or a missing file.
        ValueError: a file or URDF that does not describe a platform (see
            `serial_chain_from_urdf`).
    """
    if isinstance(platform, tuple(PLATFORM_KINDS.values())):
        return platform.build(base_dir)
    path = platform_file(platform)
    return read_platform_file(path).build(path.parent)
