"""A Stewart-platform hexapod as a motion platform: its pose as the coordinates every MCA
plans in, its six legs as the actuators whose limits are physical.

Every MCA, plant and station works on a `SerialChain`: coordinates q with box limits, the
head's pose as a chain product. A hexapod's coordinates are its moving platform's pose
relative to the neutral pose, and that pose *is* a chain: three prismatic joints along the
base's x, y and z (surge, sway, heave), then three revolute joints about z, y' and x''
(yaw, pitch, roll: R = Rz Ry Rx, `hexapod.rotation`). So `HexapodPlatform` is a
`SerialChain` of those six virtual joints (the numpy and torch plants, the NMPC and the
MultibodyPlant station use it unchanged) plus what makes it a hexapod: its legs
(`HexapodGeometry`), whose lengths, speeds and accelerations (`hexapod.leg_motion`) are the
limits that matter. The viability clamp of a hexapod (`hexapod_clamp.HexapodClamp`) holds
every command to them; the summaries count them.

The chain's box limits are each coordinate's reach alone (`single_axis_limits`): from the
neutral pose, the excursion each coordinate reaches before a leg reaches its stroke's end,
and the speed and acceleration it reaches at the neutral pose before a leg reaches its own.
They are what a maker's data sheet gives per axis and what the MCAs plan with; combined
motions inside that box can still ask more of a leg than it has, which the clamp refuses.

Coordinates q (rad or m): (x, y, z, yaw, pitch, roll); `hexapod.leg_lengths` and friends
take poses (x, y, z, roll, pitch, yaw): `pose_of` maps one to the other.
"""

import dataclasses
import functools
import hashlib
import json
import math
import os
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_text
from mca_drake.platforms.hexapod import (
    LEGS,
    HexapodGeometry,
    leg_jacobian,
    leg_lengths,
    leg_motion,
)
from mca_drake.platforms.serial import SerialChain, serial_chain_from_urdf

# The virtual joints, base to head, and the pose coordinate each one is.
COORDINATES = ("surge", "sway", "heave", "yaw", "pitch", "roll")
# q index of each pose coordinate (x, y, z, roll, pitch, yaw), and the reverse (its own
# inverse: it swaps roll and yaw).
POSE_ORDER = (0, 1, 2, 5, 4, 3)
# Mirroring the motion about the base's x-z plane turns sway, yaw and roll round.
MIRROR_SIGNS = (1.0, -1.0, 1.0, -1.0, 1.0, -1.0)
# How far a rotation's single-axis reach is searched, rad (the chain's Euler angles are
# singular at a pitch of 90 deg; no hexapod tilts near that).
MAX_ANGLE = 1.2
# The virtual joints' effort limits (N, N m): the legs are what is limited, not them.
VIRTUAL_EFFORT = 1e6
# Mass (kg) and inertia (kg m^2) of each virtual link between the joints: Drake needs a
# body there; small beside the payload.
VIRTUAL_LINK_MASS = 1.0
VIRTUAL_LINK_INERTIA = 0.01


def pose_of(q) -> np.ndarray:
    """The hexapod pose (x, y, z, roll, pitch, yaw) (..., 6) of coordinates q (..., 6)."""
    return np.asarray(q, dtype=float)[..., POSE_ORDER]


@dataclasses.dataclass(frozen=True)
class HexapodPlatform(SerialChain):
    """A hexapod: the virtual chain of its pose (`SerialChain` fields) and its legs.

    Attributes:
        actuators: the legs' attachment points and limits.
        head_position: the head H in the moving platform's frame, m (3,).
        source: where the geometry and limits come from.
    """

    actuators: HexapodGeometry
    head_position: tuple[float, float, float]
    source: str = ""

    kind = "hexapod"

    @property
    def actuator_names(self) -> tuple[str, ...]:
        """The legs, in the order of `actuators`' joints: leg_1 ... leg_6."""
        return tuple(f"leg_{i + 1}" for i in range(LEGS))

    def actuator_positions(self, q) -> np.ndarray:
        """The leg lengths (m) of coordinates q (..., 6): (..., 6)."""
        return leg_lengths(pose_of(q), self.actuators)

    def actuator_motion(self, q, qd, qdd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The legs' lengths (m), speeds (m/s) and accelerations (m/s^2), each (..., 6), of
        coordinates q moving at qd with qdd (each (..., 6)), exactly."""
        return leg_motion(pose_of(q), pose_of(qd), pose_of(qdd), self.actuators)

    def actuator_jacobian(self, q) -> np.ndarray:
        """d(leg lengths)/dq at one pose q (6,): (6 legs, 6 coordinates), exact."""
        return leg_jacobian(pose_of(q), self.actuators)[:, POSE_ORDER]

    def summary(self) -> dict:
        """As `SerialChain.summary`, with the legs' stroke and limits."""
        geometry = self.actuators
        return {
            **super().summary(),
            "actuators": {
                "names": list(self.actuator_names),
                "min_length_m": geometry.min_length,
                "max_length_m": geometry.max_length,
                "max_speed_m_s": geometry.max_speed,
                "max_acceleration_m_s2": geometry.max_acceleration,
            },
        }


@dataclasses.dataclass(frozen=True)
class AxisLimits:
    """Each coordinate's reach alone (q order, `COORDINATES`), each (6,): excursions
    `q_min` < 0 < `q_max` (m or rad), symmetric speed `qd_max` and acceleration `qdd_max`."""

    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    qdd_max: np.ndarray


def _within_stroke(q: np.ndarray, geometry: HexapodGeometry) -> np.ndarray:
    lengths = leg_lengths(pose_of(q), geometry)
    return np.all((lengths >= geometry.min_length) & (lengths <= geometry.max_length), axis=-1)


def _reach(axis: int, sign: float, geometry: HexapodGeometry) -> float:
    """How far coordinate `axis` alone moves from neutral towards `sign` before a leg
    leaves its stroke: a scan of 400 steps for the first pose outside, then bisection to
    1e-9 (so a workspace that is not convex along the axis is cut at its first edge)."""
    limit = MAX_ANGLE if axis >= 3 else geometry.max_length
    steps = np.linspace(0.0, limit, 401)
    q = np.zeros((steps.size, 6))
    q[:, axis] = sign * steps
    inside = _within_stroke(q, geometry)
    if inside.all():
        return limit
    first_out = int(np.argmin(inside))
    lo, hi = steps[first_out - 1], steps[first_out]
    while hi - lo > 1e-9:
        mid = 0.5 * (lo + hi)
        pose = np.zeros(6)
        pose[axis] = sign * mid
        lo, hi = (mid, hi) if _within_stroke(pose, geometry) else (lo, mid)
    return lo


def single_axis_limits(geometry: HexapodGeometry) -> AxisLimits:
    """Each coordinate's reach alone (module docstring): the excursions by `_reach`, the
    speed and acceleration at the neutral pose where the fastest leg (the largest
    |dl/dq_k|) reaches `max_speed` or `max_acceleration`."""
    geometry.validate()
    q_max = np.array([_reach(k, 1.0, geometry) for k in range(6)])
    q_min = -np.array([_reach(k, -1.0, geometry) for k in range(6)])
    if not (np.all(q_max > 0) and np.all(q_min < 0)):
        raise ValueError(
            "the hexapod cannot move every coordinate from its neutral pose (a leg is at its "
            "stroke's end there)"
        )
    J = leg_jacobian(np.zeros(6), geometry)[:, POSE_ORDER]
    lever = np.max(np.abs(J), axis=0)
    if not np.all(lever > 0):
        raise ValueError("a coordinate moves no leg at the neutral pose: a singular hexapod")
    return AxisLimits(
        q_min=q_min,
        q_max=q_max,
        qd_max=geometry.max_speed / lever,
        qdd_max=geometry.max_acceleration / lever,
    )


def _is_mirror_symmetric(geometry: HexapodGeometry) -> bool:
    """Whether the legs, mirrored about the base's x-z plane, are the legs again (then the
    mirrored motion has mirrored leg lengths and the same limits)."""
    flip = np.array([1.0, -1.0, 1.0])
    base = np.asarray(geometry.base_joints, dtype=float)
    platform = np.asarray(geometry.platform_joints, dtype=float)
    legs = np.concatenate([base, platform], axis=1)
    mirrored = np.concatenate([base * flip, platform * flip], axis=1)
    return all(np.min(np.linalg.norm(legs - leg, axis=1)) < 1e-9 for leg in mirrored)


def _format(values) -> str:
    return " ".join(f"{float(v):.17g}" for v in values)


def virtual_chain_urdf(
    name: str,
    geometry: HexapodGeometry,
    limits: AxisLimits,
    head_position,
    payload_mass: float,
    payload_inertia,
) -> str:
    """The URDF of a hexapod's virtual chain (module docstring): a base plate, the six
    joints with `limits`, the moving platform carrying the payload (its centre of mass at
    half the head's height) and the head frame `head`."""
    axes = ((1, 0, 0), (0, 1, 0), (0, 0, 1), (0, 0, 1), (0, 1, 0), (1, 0, 0))
    kinds = ("prismatic",) * 3 + ("revolute",) * 3
    base_radius = float(np.max(np.linalg.norm(np.asarray(geometry.base_joints)[:, :2], axis=1)))
    top_radius = float(np.max(np.linalg.norm(np.asarray(geometry.platform_joints)[:, :2], axis=1)))
    small = VIRTUAL_LINK_INERTIA
    lines = [
        '<?xml version="1.0"?>',
        f"<!-- The virtual chain of hexapod '{name}' (mca_drake.platforms.hexapod_platform):",
        "     its coordinates surge, sway, heave, yaw, pitch, roll; generated from its",
        "     platform description, do not edit. -->",
        f'<robot name="{name}" xmlns:drake="http://drake.mit.edu">',
        '  <link name="base">',
        '    <visual><origin xyz="0 0 -0.025" rpy="0 0 0"/>',
        f'      <geometry><cylinder radius="{base_radius:.6g}" length="0.05"/></geometry>',
        "    </visual>",
        "  </link>",
        '  <joint name="base_weld" type="fixed"><parent link="world"/><child link="base"/>'
        '<origin xyz="0 0 0" rpy="0 0 0"/></joint>',
    ]
    parent = "base"
    for k, (joint, axis, kind) in enumerate(zip(COORDINATES, axes, kinds, strict=True)):
        child = "platform" if k == 5 else f"{joint}_carriage"
        if child == "platform":
            x, y, z = (float(v) for v in head_position)
            ixx, iyy, izz = (float(v) for v in payload_inertia)
            lines += [
                f'  <link name="{child}">',
                f'    <inertial><origin xyz="{x:.6g} {y:.6g} {0.5 * z:.6g}" rpy="0 0 0"/>'
                f'<mass value="{payload_mass:.6g}"/><inertia ixx="{ixx:.6g}" ixy="0" ixz="0" '
                f'iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/></inertial>',
                '    <visual><origin xyz="0 0 0.025" rpy="0 0 0"/>',
                f'      <geometry><cylinder radius="{top_radius:.6g}" length="0.05"/></geometry>',
                "    </visual>",
                f'    <visual><origin xyz="{x:.6g} {y:.6g} {0.5 * z:.6g}" rpy="0 0 0"/>',
                f'      <geometry><box size="0.6 0.5 {max(z, 0.1):.6g}"/></geometry>',
                "    </visual>",
                "  </link>",
            ]
        else:
            lines += [
                f'  <link name="{child}"><inertial><mass value="{VIRTUAL_LINK_MASS}"/>'
                f'<inertia ixx="{small}" ixy="0" ixz="0" iyy="{small}" iyz="0" izz="{small}"/>'
                "</inertial></link>",
            ]
        origin = f"0 0 {geometry.neutral_height:.17g}" if k == 0 else "0 0 0"
        lines += [
            f'  <joint name="{joint}" type="{kind}">',
            f'    <parent link="{parent}"/><child link="{child}"/>',
            f'    <origin xyz="{origin}" rpy="0 0 0"/><axis xyz="{_format(axis)}"/>',
            f'    <limit lower="{limits.q_min[k]:.17g}" upper="{limits.q_max[k]:.17g}" '
            f'velocity="{limits.qd_max[k]:.17g}" effort="{VIRTUAL_EFFORT:g}" '
            f'drake:acceleration="{limits.qdd_max[k]:.17g}"/>',
            "  </joint>",
            f'  <transmission name="{joint}_transmission" type="SimpleTransmission">'
            f'<joint name="{joint}"/><actuator name="{joint}_motor"/></transmission>',
        ]
        parent = child
    lines += [
        '  <link name="head"/>',
        '  <joint name="head_weld" type="fixed"><parent link="platform"/><child link="head"/>'
        f'<origin xyz="{_format(head_position)}" rpy="0 0 0"/></joint>',
        "</robot>",
        "",
    ]
    return "\n".join(lines)


def generated_models_folder() -> Path:
    """Where generated virtual-chain URDFs are kept: `$XDG_CACHE_HOME/mca-drake/platforms`
    (default ~/.cache/mca-drake/platforms). Each file is named by its content's hash, so
    processes (Ray workers too) that build the same platform share it and none overwrites
    another's."""
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "mca-drake" / "platforms"


def hexapod_platform(
    geometry: HexapodGeometry,
    *,
    name: str,
    head_position=(0.0, 0.0, 1.0),
    payload_mass: float = 1000.0,
    payload_inertia=(500.0, 500.0, 500.0),
    source: str = "",
) -> HexapodPlatform:
    """A hexapod platform from its legs' geometry.

    Args:
        geometry: the legs (validated here).
        name: the platform's name.
        head_position: the head H in the moving platform's frame (x forward, y left, z up),
            m: where the occupant's vestibular system sits above the platform.
        payload_mass: the moving mass (platform, cabin, occupant), kg, for the station.
        payload_inertia: its principal moments of inertia (ixx, iyy, izz), kg m^2.
        source: where the numbers come from.

    Raises:
        ValueError: a geometry that cannot move (`HexapodGeometry.validate`,
            `single_axis_limits`), a head position that is not three finite numbers, or a
            payload that is not positive.
    """
    head = np.asarray(head_position, dtype=float)
    if head.shape != (3,) or not np.all(np.isfinite(head)):
        raise ValueError(f"head_position must be three finite numbers, m; got {head_position}")
    inertia = np.asarray(payload_inertia, dtype=float)
    if not (math.isfinite(payload_mass) and payload_mass > 0):
        raise ValueError(f"payload_mass must be positive, kg; got {payload_mass}")
    if inertia.shape != (3,) or not np.all(np.isfinite(inertia) & (inertia > 0)):
        raise ValueError(f"payload_inertia must be three positive numbers; got {payload_inertia}")
    return _build_cached(
        json.dumps(dataclasses.asdict(geometry)),
        name,
        tuple(head.tolist()),
        float(payload_mass),
        tuple(inertia.tolist()),
        source,
    )


@functools.lru_cache(maxsize=32)
def _build_cached(geometry_json, name, head, payload_mass, inertia, source) -> HexapodPlatform:
    """One shared description per geometry and settings (the serial chains are cached the
    same way); its geometry is a copy that nobody else holds."""
    geometry = HexapodGeometry(**json.loads(geometry_json))
    limits = single_axis_limits(geometry)
    text = virtual_chain_urdf(name, geometry, limits, head, payload_mass, inertia)
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = generated_models_folder() / f"{name}-{digest}.urdf"
    if not path.is_file() or path.read_text() != text:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, text)
    chain = serial_chain_from_urdf(
        path,
        name=name,
        head_frame="head",
        mirror_joint_signs=MIRROR_SIGNS if _is_mirror_symmetric(geometry) else (),
    )
    fields = {f.name: getattr(chain, f.name) for f in dataclasses.fields(SerialChain)}
    return HexapodPlatform(**fields, actuators=geometry, head_position=head, source=source)


__all__ = [
    "COORDINATES",
    "AxisLimits",
    "HexapodPlatform",
    "generated_models_folder",
    "hexapod_platform",
    "pose_of",
    "single_axis_limits",
    "virtual_chain_urdf",
]
