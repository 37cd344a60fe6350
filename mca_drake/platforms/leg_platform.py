"""A platform moved by legs (linear actuators) as a motion platform: a Stewart-platform
hexapod, or a 2- or 3-DOF rig. Its pose as the coordinates every MCA plans in, its legs as
the actuators whose limits are physical.

Every MCA, plant and station works on a `SerialChain`: coordinates q with box limits, the
head's pose as a chain product. A legged platform's coordinates are its moving platform's
pose relative to the neutral pose, and that pose *is* a chain: prismatic joints along the
base's x, y and z (surge, sway, heave), then revolute joints about z, y' and x'' (yaw,
pitch, roll: R = Rz Ry Rx, `legs.rotation`). A hexapod moves in all six; a rig moves in
those its mechanism leaves free (pitch and roll about a pivot; heave, pitch and roll), the
others held at zero. So `LegPlatform` is a `SerialChain` of those virtual joints (the
numpy and torch plants, the NMPC and the MultibodyPlant station use it unchanged) plus its
legs (`LegGeometry`), whose lengths, speeds and accelerations (`legs.leg_motion`) are the
limits that matter. Its viability clamp (`leg_clamp.LegClamp`) holds every command to
them; the summaries count them.

The chain's box limits are each coordinate's reach alone (`single_axis_limits`): from the
neutral pose, the excursion each coordinate reaches before a leg reaches its stroke's end,
and the speed and acceleration it reaches at the neutral pose before a leg reaches its own.
They are what a maker's data sheet gives per axis and what the MCAs plan with; combined
motions inside that box can still ask more of a leg than it has, which the clamp refuses.

Coordinates q (rad or m) in chain order, a subsequence of `COORDINATES` (surge, sway,
heave, yaw, pitch, roll); `legs.leg_lengths` and friends take full poses (x, y, z, roll,
pitch, yaw): `pose_of` maps one to the other.
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
from mca_drake.platforms.legs import (
    LEGS,
    LegGeometry,
    actuator_positions,
    leg_jacobian,
    leg_linearisation,
    leg_motion,
    leg_rates,
)
from mca_drake.platforms.serial import SerialChain, serial_chain_from_urdf

# The virtual joints a legged platform may have, base to head in chain order.
COORDINATES = ("surge", "sway", "heave", "yaw", "pitch", "roll")
# Each coordinate's place in a pose (x, y, z, roll, pitch, yaw).
POSE_INDEX = {"surge": 0, "sway": 1, "heave": 2, "yaw": 5, "pitch": 4, "roll": 3}
# Each coordinate's joint: kind and axis.
JOINTS = {
    "surge": ("prismatic", (1, 0, 0)),
    "sway": ("prismatic", (0, 1, 0)),
    "heave": ("prismatic", (0, 0, 1)),
    "yaw": ("revolute", (0, 0, 1)),
    "pitch": ("revolute", (0, 1, 0)),
    "roll": ("revolute", (1, 0, 0)),
}
# The pose coordinate that moves each head velocity component [w_x, w_y, w_z, v_x, v_y, v_z].
VELOCITY_COMPONENTS = ("roll", "pitch", "yaw", "surge", "sway", "heave")
# Mirroring the motion about the base's x-z plane turns sway, yaw and roll round.
MIRROR_SIGN = {"surge": 1.0, "sway": -1.0, "heave": 1.0, "yaw": -1.0, "pitch": 1.0, "roll": -1.0}
# How far a rotation's single-axis reach is searched, rad (the chain's Euler angles are
# singular at a pitch of 90 deg; no hexapod tilts near that).
MAX_ANGLE = 1.2
# The virtual joints' effort limits (N, N m): the legs are what is limited, not them.
VIRTUAL_EFFORT = 1e6
# Mass (kg) and inertia (kg m^2) of each virtual link between the joints: Drake needs a
# body there; small beside the payload.
VIRTUAL_LINK_MASS = 1.0
VIRTUAL_LINK_INERTIA = 0.01


def check_coordinates(coordinates) -> tuple[str, ...]:
    """`coordinates` as a tuple, after checking they are distinct names of `COORDINATES`
    in chain order.

    Raises:
        ValueError: an unknown, repeated or misordered coordinate, or none.
    """
    names = tuple(coordinates)
    unknown = [c for c in names if c not in COORDINATES]
    if unknown or not names:
        raise ValueError(f"coordinates must be some of {', '.join(COORDINATES)}; got {list(names)}")
    if list(names) != [c for c in COORDINATES if c in names]:
        raise ValueError(
            f"list the coordinates once each, in chain order ({', '.join(COORDINATES)}); "
            f"got {list(names)}"
        )
    return names


def pose_of(q, coordinates=COORDINATES) -> np.ndarray:
    """The pose (x, y, z, roll, pitch, yaw) (..., 6) of coordinates q (..., k) named by
    `coordinates` (default all six: q = (x, y, z, yaw, pitch, roll)); the others zero."""
    q = np.asarray(q, dtype=float)
    pose = np.zeros((*q.shape[:-1], 6))
    pose[..., [POSE_INDEX[c] for c in coordinates]] = q
    return pose


@dataclasses.dataclass(frozen=True)
class LegPlatform(SerialChain):
    """A platform moved by legs: the virtual chain of its pose (`SerialChain` fields, one
    joint per coordinate) and its legs.

    Attributes:
        actuators: the legs' attachment points and limits.
        coordinates: the pose coordinates it moves in, in chain order (the joints' names).
        head_position: the head H in the moving platform's frame, m (3,).
        source: where the geometry and limits come from.
    """

    actuators: LegGeometry
    coordinates: tuple[str, ...]
    head_position: tuple[float, float, float]
    source: str = ""

    @property
    def kind(self) -> str:
        """ "hexapod" (six legs, six coordinates), else "rig-<k>dof"."""
        if len(self.coordinates) == 6 and len(self.actuator_names) == LEGS:
            return "hexapod"
        return f"rig-{len(self.coordinates)}dof"

    @property
    def actuator_names(self) -> tuple[str, ...]:
        """The legs, in the order of `actuators`' joints: leg_1, leg_2, ..."""
        return tuple(f"leg_{i + 1}" for i in range(len(self.actuators.base_joints)))

    @property
    def head_velocity_components(self) -> tuple[bool, ...]:
        """All six on a hexapod; on a rig, the head velocity components its coordinates
        move (a pitch/roll seat: w_x and w_y)."""
        if len(self.coordinates) == len(COORDINATES):
            return (True,) * 6
        return tuple(c in self.coordinates for c in VELOCITY_COMPONENTS)

    def pose(self, q) -> np.ndarray:
        """The pose (x, y, z, roll, pitch, yaw) (..., 6) of coordinates q (..., k)."""
        return pose_of(q, self.coordinates)

    def actuator_positions(self, q) -> np.ndarray:
        """The actuators' positions (leg lengths, m; arm angles, rad) of coordinates q
        (..., k): (..., legs)."""
        return actuator_positions(self.pose(q), self.actuators)

    def actuator_motion(self, q, qd, qdd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The legs' lengths (m), speeds (m/s) and accelerations (m/s^2), each (..., legs),
        of coordinates q moving at qd with qdd (each (..., k)), exactly."""
        return leg_motion(self.pose(q), self.pose(qd), self.pose(qdd), self.actuators)

    def actuator_rates(self, q, qd) -> tuple[np.ndarray, ...]:
        """At one state (q, qd), each (k,): the legs' lengths, speeds and accelerations at
        qdd = 0 (each (legs,)) and d(leg lengths)/dq (legs, k), in one pass
        (`legs.leg_rates`): the legs' accelerations under qdd are drift + J qdd."""
        lengths, speeds, drift, J = leg_rates(self.pose(q), self.pose(qd), self.actuators)
        return lengths, speeds, drift, J[:, [POSE_INDEX[c] for c in self.coordinates]]

    def actuator_linearisation(self, q, qd) -> tuple[np.ndarray, ...]:
        """At states (q, qd), each (..., k): the legs' lengths (m) and speeds (m/s), each
        (..., legs), and their exact derivatives J = dl/dq = dl'/dqd and S = dl'/dq, each
        (..., legs, k) (`legs.leg_linearisation`): what the NMPC bounds the legs with."""
        lengths, speeds, J, S = leg_linearisation(self.pose(q), self.pose(qd), self.actuators)
        columns = [POSE_INDEX[c] for c in self.coordinates]
        return lengths, speeds, J[..., columns], S[..., columns]

    def actuator_jacobian(self, q) -> np.ndarray:
        """d(leg lengths)/dq at one pose q (k,): (legs, k), exact."""
        columns = [POSE_INDEX[c] for c in self.coordinates]
        return leg_jacobian(self.pose(q), self.actuators)[:, columns]

    def summary(self) -> dict:
        """As `SerialChain.summary`, with the actuators' kind, range and limits (in their
        unit: m for linear legs, rad for cranks)."""
        geometry = self.actuators
        return {
            **super().summary(),
            "actuators": {
                "names": list(self.actuator_names),
                "kind": "linear" if geometry.cranks is None else "rotary",
                "unit": geometry.unit,
                "min_position": geometry.min_position,
                "max_position": geometry.max_position,
                "max_speed": geometry.max_speed,
                "max_acceleration": geometry.max_acceleration,
            },
        }


@dataclasses.dataclass(frozen=True)
class AxisLimits:
    """Each coordinate's reach alone (q order), each (k,): excursions
    `q_min` < 0 < `q_max` (m or rad), symmetric speed `qd_max` and acceleration `qdd_max`."""

    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    qdd_max: np.ndarray


def _within_stroke(pose: np.ndarray, geometry: LegGeometry) -> np.ndarray:
    positions = actuator_positions(pose, geometry)
    return np.all(
        (positions >= geometry.min_position) & (positions <= geometry.max_position), axis=-1
    )


def _reach(coordinate: str, sign: float, geometry: LegGeometry) -> float:
    """How far `coordinate` alone moves from neutral towards `sign` before a leg
    leaves its stroke: a scan of 400 steps for the first pose outside, then bisection to
    1e-9 (so a workspace that is not convex along the axis is cut at its first edge)."""
    axis = POSE_INDEX[coordinate]
    if axis >= 3:
        limit = MAX_ANGLE
    elif geometry.cranks is None:
        limit = geometry.max_position  # no leg reaches further than its longest
    else:
        limit = geometry.cranks.arm_length + geometry.cranks.rod_length
    steps = np.linspace(0.0, limit, 401)
    poses = np.zeros((steps.size, 6))
    poses[:, axis] = sign * steps
    inside = _within_stroke(poses, geometry)
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


def single_axis_limits(geometry: LegGeometry, coordinates=COORDINATES) -> AxisLimits:
    """Each coordinate's reach alone (module docstring): the excursions by `_reach`, the
    speed and acceleration at the neutral pose where the fastest leg (the largest
    |dl/dq_k|) reaches `max_speed` or `max_acceleration`.

    Raises:
        ValueError: a leg at its stroke's end at the neutral pose, a coordinate that moves no
            leg, or fewer legs than coordinates (dl/dq of less than full column rank: a
            motion the legs do not hold).
    """
    geometry.validate()
    coordinates = check_coordinates(coordinates)
    q_max = np.array([_reach(c, 1.0, geometry) for c in coordinates])
    q_min = -np.array([_reach(c, -1.0, geometry) for c in coordinates])
    if not (np.all(q_max > 0) and np.all(q_min < 0)):
        raise ValueError(
            "the platform cannot move every coordinate from its neutral pose (a leg is at its "
            "stroke's end there)"
        )
    J = leg_jacobian(np.zeros(6), geometry)[:, [POSE_INDEX[c] for c in coordinates]]
    lever = np.max(np.abs(J), axis=0)
    if not np.all(lever > 0):
        raise ValueError("a coordinate moves no leg at the neutral pose: a singular platform")
    if np.linalg.matrix_rank(J) < len(coordinates):
        raise ValueError(
            f"the legs do not hold every coordinate of {list(coordinates)} at the neutral "
            "pose (dl/dq has rank below the coordinates' count)"
        )
    return AxisLimits(
        q_min=q_min,
        q_max=q_max,
        qd_max=geometry.max_speed / lever,
        qdd_max=geometry.max_acceleration / lever,
    )


def _is_mirror_symmetric(geometry: LegGeometry) -> bool:
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
    geometry: LegGeometry,
    coordinates: tuple[str, ...],
    limits: AxisLimits,
    head_position,
    payload_mass: float,
    payload_inertia,
) -> str:
    """The URDF of a legged platform's virtual chain (module docstring): a base plate, one
    joint per coordinate with `limits`, the moving platform carrying the payload (its centre
    of mass at half the head's height) and the head frame `head`."""
    radii = np.linalg.norm(np.asarray(geometry.base_joints)[:, :2], axis=1)
    base_radius = float(np.max(radii))
    top_radius = float(np.max(np.linalg.norm(np.asarray(geometry.platform_joints)[:, :2], axis=1)))
    small = VIRTUAL_LINK_INERTIA
    lines = [
        '<?xml version="1.0"?>',
        f"<!-- The virtual chain of hexapod '{name}' (mca_drake.platforms.leg_platform):",
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
    last = len(coordinates) - 1
    for k, joint in enumerate(coordinates):
        kind, axis = JOINTS[joint]
        child = "platform" if k == last else f"{joint}_carriage"
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


def leg_platform(
    geometry: LegGeometry,
    *,
    name: str,
    coordinates=COORDINATES,
    head_position=(0.0, 0.0, 1.0),
    payload_mass: float = 1000.0,
    payload_inertia=(500.0, 500.0, 500.0),
    source: str = "",
) -> LegPlatform:
    """A legged platform (a hexapod; a rig) from its legs' geometry.

    Args:
        geometry: the legs (validated here).
        name: the platform's name.
        coordinates: the pose coordinates it moves in, in chain order (default all six: a
            hexapod; a 2-DOF rig: pitch, roll; a 3-DOF rig: heave, pitch, roll).
        head_position: the head H in the moving platform's frame (x forward, y left, z up),
            m: where the occupant's vestibular system sits above the platform.
        payload_mass: the moving mass (platform, cabin, occupant), kg, for the station.
        payload_inertia: its principal moments of inertia (ixx, iyy, izz), kg m^2.
        source: where the numbers come from.

    Raises:
        ValueError: a geometry that cannot move (`LegGeometry.validate`,
            `single_axis_limits`), unknown coordinates, a head position that is not three
            finite numbers, or a payload that is not positive.
    """
    coordinates = check_coordinates(coordinates)
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
        coordinates,
        tuple(head.tolist()),
        float(payload_mass),
        tuple(inertia.tolist()),
        source,
    )


@functools.lru_cache(maxsize=32)
def _build_cached(
    geometry_json, name, coordinates, head, payload_mass, inertia, source
) -> LegPlatform:
    """One shared description per geometry and settings (the serial chains are cached the
    same way); its geometry is a copy that nobody else holds."""
    geometry = LegGeometry(**json.loads(geometry_json))
    limits = single_axis_limits(geometry, coordinates)
    text = virtual_chain_urdf(name, geometry, coordinates, limits, head, payload_mass, inertia)
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = generated_models_folder() / f"{name}-{digest}.urdf"
    if not path.is_file() or path.read_text() != text:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, text)
    mirror = [MIRROR_SIGN[c] for c in coordinates] if _is_mirror_symmetric(geometry) else ()
    chain = serial_chain_from_urdf(path, name=name, head_frame="head", mirror_joint_signs=mirror)
    fields = {f.name: getattr(chain, f.name) for f in dataclasses.fields(SerialChain)}
    return LegPlatform(
        **fields, actuators=geometry, coordinates=coordinates, head_position=head, source=source
    )


__all__ = [
    "COORDINATES",
    "AxisLimits",
    "LegPlatform",
    "check_coordinates",
    "generated_models_folder",
    "leg_platform",
    "pose_of",
    "single_axis_limits",
    "virtual_chain_urdf",
]
