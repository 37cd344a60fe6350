"""The legs of a platform moved by linear actuators, and their kinematics (numpy): the
pose of its moving platform and the lengths of its legs. A Stewart-platform hexapod has six
legs and moves in all six pose coordinates; a small rig (2 or 3 DOF) has two to four
actuators and moves in some of them, a mechanism holding the others at zero.

Frames: the base frame B (fixed, z up) has its origin in the plane of the base joints; the
platform frame P (moving) has its origin in the plane of the platform joints. At the
neutral pose P is B raised by `neutral_height` (m). A pose is six numbers relative to the
neutral pose, `(x, y, z, roll, pitch, yaw)` (m, rad): P's origin at (x, y, neutral_height +
z) in B and its rotation R = Rz(yaw) Ry(pitch) Rx(roll). Leg i joins the base joint b_i (in
B) to the platform joint p_i (in P); its length is

    l_i = |t + R p_i - b_i|,      t = (x, y, neutral_height + z).

`leg_lengths` is that inverse kinematics (batched over poses); `leg_jacobian` its exact
derivative dl/dpose (legs x 6); `leg_motion` the legs' lengths, speeds and accelerations of a
pose moving with given pose rates and accelerations (what the actuator limits bound);
`leg_linearisation` the exact derivatives of lengths and speeds along a motion (what a
planner's linearised limits need);
`forward_kinematics` inverts a hexapod's `leg_lengths` by Newton's method from the neutral
pose (or a guess), to 1e-12 m on the lengths. The torch twin (for training through
the legs) is `mca_drake.learning.legs`.
"""

import dataclasses
import math

import numpy as np

from mca_drake.input_checks import check_config_numbers

# A hexapod's legs.
LEGS = 6


@dataclasses.dataclass
class LegGeometry:
    """Where a platform's legs attach, and how far and fast they may move (every leg alike)."""

    # Base joints b_i in the base frame, m: one [x, y, z] per leg (a hexapod's six).
    base_joints: list[list[float]]
    # Platform joints p_i in the platform frame, m: one [x, y, z] per leg, leg i from b_i.
    platform_joints: list[list[float]]
    # Height of the platform frame above the base frame at the neutral pose, m.
    neutral_height: float
    # Leg length range, m (the actuators' stroke, from the joint centres).
    min_length: float
    max_length: float
    # Actuator speed and acceleration limits along the legs, m/s and m/s^2.
    max_speed: float
    max_acceleration: float

    def validate(self) -> None:
        """Raises ValueError for a geometry that cannot move, naming the field."""
        check_config_numbers(self)
        legs = np.shape(self.base_joints)
        if len(legs) != 2 or legs[1] != 3 or not legs[0] >= 1:
            raise ValueError("LegGeometry.base_joints must be [x, y, z] points, m, one per leg")
        if np.shape(self.platform_joints) != legs:
            raise ValueError(
                f"LegGeometry.platform_joints must be {legs[0]} [x, y, z] points, m, one per "
                "base joint"
            )
        for name in ("neutral_height", "min_length", "max_speed", "max_acceleration"):
            if not getattr(self, name) > 0:
                raise ValueError(f"LegGeometry.{name} must be positive")
        if not self.max_length > self.min_length:
            raise ValueError("LegGeometry.max_length must exceed min_length")
        neutral = leg_lengths(np.zeros(6), self)
        if np.any(neutral < self.min_length) or np.any(neutral > self.max_length):
            raise ValueError(
                f"the neutral pose's leg lengths {np.round(neutral, 4).tolist()} m are "
                f"outside the stroke [{self.min_length}, {self.max_length}] m"
            )

    @classmethod
    def symmetric(
        cls,
        base_radius: float,
        platform_radius: float,
        base_half_angle: float,
        platform_half_angle: float,
        neutral_height: float,
        stroke: float,
        max_speed: float,
        max_acceleration: float,
    ) -> "LegGeometry":
        """The classic 6-6 hexapod: joints in pairs on two circles, pairs 120 deg apart.

        Args:
            base_radius: the base joints' circle, m.
            platform_radius: the platform joints' circle, m.
            base_half_angle: half the angle between the two base joints of a pair, rad.
            platform_half_angle: the same on the platform, rad; the platform's pairs sit
                60 deg from the base's, so each leg runs from one base pair to the
                neighbouring platform pair.
            neutral_height: the platform frame's height at the neutral pose, m.
            stroke: the leg length range, centred on the neutral length, m.
            max_speed: the actuators' speed limit along the legs, m/s.
            max_acceleration: their acceleration limit, m/s^2.
        """
        base, platform = [], []
        for pair in range(3):
            centre = math.radians(120.0 * pair)
            for side in (-1, 1):
                a = centre + side * base_half_angle
                base.append([base_radius * math.cos(a), base_radius * math.sin(a), 0.0])
                # the leg from this base joint goes to the nearer joint of the platform pair
                # 60 deg along on its side
                p = centre + side * (math.radians(60.0) - platform_half_angle)
                platform.append([platform_radius * math.cos(p), platform_radius * math.sin(p), 0.0])
        lift = np.array([0.0, 0.0, neutral_height])
        neutral = float(np.linalg.norm(np.array(platform[0]) + lift - np.array(base[0])))
        return cls(
            base_joints=base,
            platform_joints=platform,
            neutral_height=neutral_height,
            min_length=neutral - 0.5 * stroke,
            max_length=neutral + 0.5 * stroke,
            max_speed=max_speed,
            max_acceleration=max_acceleration,
        )


def rotation(roll, pitch, yaw) -> np.ndarray:
    """Rz(yaw) Ry(pitch) Rx(roll), batched: angles of shape (...), result (..., 3, 3)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    rows = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def _legs(pose: np.ndarray, geometry: LegGeometry) -> np.ndarray:
    """The leg vectors t + R p_i - b_i in B, shape (..., 6, 3)."""
    pose = np.asarray(pose, dtype=float)
    if pose.shape[-1:] != (6,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"a pose is six finite numbers (x, y, z, roll, pitch, yaw); got {pose}")
    if pose.ndim == 1:  # one pose: from its factors' scalars, not the batched stack
        Rx, Ry, Rz = _factors(pose[3:])
        R = Rz @ Ry @ Rx
    else:
        R = rotation(pose[..., 3], pose[..., 4], pose[..., 5])
    t = pose[..., :3] + np.array([0.0, 0.0, geometry.neutral_height])
    p = np.asarray(geometry.platform_joints, dtype=float)
    b = np.asarray(geometry.base_joints, dtype=float)
    return t[..., None, :] + np.einsum("...jk,ik->...ij", R, p) - b


def leg_lengths(pose, geometry: LegGeometry) -> np.ndarray:
    """The leg lengths (m) of `pose` (..., 6) relative to the neutral pose: (..., legs)."""
    return np.linalg.norm(_legs(pose, geometry), axis=-1)


def leg_jacobian(pose, geometry: LegGeometry) -> np.ndarray:
    """dl/dpose at one pose (6,): (legs, 6 pose coordinates), exact.

    d l_i = u_i . (dt + dR p_i) with u_i the leg's unit vector; the angle columns use
    dR/dangle of R = Rz Ry Rx (`_rotation_derivatives`).
    """
    pose = np.asarray(pose, dtype=float)
    legs = _legs(pose, geometry)
    units = legs / np.linalg.norm(legs, axis=-1, keepdims=True)
    derivatives = _rotation_derivatives(pose[3:], second=False)[0]
    p = np.asarray(geometry.platform_joints, dtype=float)
    J = np.empty((legs.shape[0], 6))
    J[:, :3] = units
    for k, dR in enumerate(derivatives):
        J[:, 3 + k] = np.einsum("ij,ij->i", units, p @ dR.T)
    return J


_K = (
    np.array([[0, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float),  # about x: roll
    np.array([[0, 0, 1], [0, 0, 0], [-1, 0, 0]], dtype=float),  # about y: pitch
    np.array([[0, -1, 0], [1, 0, 0], [0, 0, 0]], dtype=float),  # about z: yaw
)


# Each axis' cross-product matrix to the powers 0, 1 and 2.
_K_POWERS = tuple(tuple(np.linalg.matrix_power(K, m) for m in range(3)) for K in _K)


def _factors(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rx(roll), Ry(pitch), Rz(yaw) of angles (..., 3); one pose's from scalars (a clamp
    evaluates one pose a period, where numpy's batched stacking costs most of the time)."""
    if angles.ndim == 1:
        (cr, cp, cy), (sr, sp, sy) = np.cos(angles).tolist(), np.sin(angles).tolist()
        return (
            np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]]),
            np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]]),
            np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]]),
        )
    zero = np.zeros_like(angles[..., 0])
    return (
        rotation(angles[..., 0], zero, zero),
        rotation(zero, angles[..., 1], zero),
        rotation(zero, zero, angles[..., 2]),
    )


def _rotation_derivatives(angles: np.ndarray, second: bool = True) -> tuple[list, list]:
    """dR/dangle_k (3) and, with `second`, d2R/dangle_k dangle_l (3 x 3; else []) of
    R = Rz Ry Rx at angles (..., 3) = (roll, pitch, yaw), each (..., 3, 3): each factor's
    derivative is the factor times its axis' cross-product matrix."""
    Rx, Ry, Rz = _factors(angles)
    Kx, Ky, Kz = _K_POWERS

    def product(marks: dict) -> np.ndarray:
        # R with each factor f of `marks` replaced by its derivative (K f, or f K^m)
        zs = marks.get("z", 0)
        out = Kz[zs] @ Rz if zs else Rz
        out = out @ Ry
        if marks.get("y"):
            out = out @ Ky[marks["y"]]
        out = out @ Rx
        if marks.get("x"):
            out = out @ Kx[marks["x"]]
        return out

    names = ("x", "y", "z")
    first = [product({names[k]: 1}) for k in range(3)]
    if not second:
        return first, []
    seconds = [
        [product({names[k]: 1, names[m]: 1} if k != m else {names[k]: 2}) for m in range(3)]
        for k in range(3)
    ]
    return first, seconds


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...ij,...ij->...i", a, b)


def leg_motion(pose, pose_rate, pose_acceleration, geometry: LegGeometry):
    """The legs' lengths (m), speeds (m/s) and accelerations (m/s^2), each (..., legs), of
    poses (..., 6) moving at `pose_rate` with `pose_acceleration` (the six pose
    coordinates' first and second time derivatives, same shape; angles as Euler-angle
    rates, rad/s and rad/s^2).

    With v_i = t + R p_i - b_i: l_i = |v_i|, l'_i = u_i . v'_i and
    l''_i = (|v'_i|^2 - l'_i^2) / l_i + u_i . v''_i, exactly.
    """
    pose = np.asarray(pose, dtype=float)
    rate = np.broadcast_to(np.asarray(pose_rate, dtype=float), pose.shape)
    accel = np.broadcast_to(np.asarray(pose_acceleration, dtype=float), pose.shape)
    legs = _legs(pose, geometry)
    lengths = np.linalg.norm(legs, axis=-1)
    units = legs / lengths[..., None]
    first, second = _rotation_derivatives(pose[..., 3:])

    def angle(values: np.ndarray, k: int) -> np.ndarray:
        return values[..., 3 + k, None, None]

    R_dot = sum(first[k] * angle(rate, k) for k in range(3))
    R_ddot = sum(first[k] * angle(accel, k) for k in range(3)) + sum(
        second[k][m] * angle(rate, k) * angle(rate, m) for k in range(3) for m in range(3)
    )
    p = np.asarray(geometry.platform_joints, dtype=float)
    # R' p_i for every leg i: (..., 6, 3)
    v_dot = rate[..., None, :3] + np.einsum("...jk,ik->...ij", R_dot, p)
    v_ddot = accel[..., None, :3] + np.einsum("...jk,ik->...ij", R_ddot, p)
    speeds = _dot(units, v_dot)
    accelerations = (_dot(v_dot, v_dot) - speeds**2) / lengths + _dot(units, v_ddot)
    return lengths, speeds, accelerations


def leg_rates(pose, pose_rate, geometry: LegGeometry):
    """One pose (6,) moving at `pose_rate` (6,): the legs' lengths (m), speeds (m/s) and
    accelerations at zero pose acceleration (m/s^2), each (legs,), and dl/dpose (legs, 6),
    from one pass over the rotation's derivatives. A leg's acceleration under a pose
    acceleration a is that drift plus J a (`leg_motion`'s l'' is linear in a): what a
    clamp needs every period."""
    pose = np.asarray(pose, dtype=float)
    rate = np.asarray(pose_rate, dtype=float)
    legs = _legs(pose, geometry)
    lengths = np.linalg.norm(legs, axis=-1)
    units = legs / lengths[:, None]
    first, second = _rotation_derivatives(pose[3:])
    R_dot = sum(first[k] * rate[3 + k] for k in range(3))
    R_ddot = sum(second[k][m] * (rate[3 + k] * rate[3 + m]) for k in range(3) for m in range(3))
    p = np.asarray(geometry.platform_joints, dtype=float)
    v_dot = rate[:3] + p @ R_dot.T
    speeds = _dot(units, v_dot)
    drift = (_dot(v_dot, v_dot) - speeds**2) / lengths + _dot(units, p @ R_ddot.T)
    J = np.empty((lengths.size, 6))
    J[:, :3] = units
    for k, dR in enumerate(first):
        J[:, 3 + k] = _dot(units, p @ dR.T)
    return lengths, speeds, drift, J


def leg_linearisation(pose, pose_rate, geometry: LegGeometry):
    """Poses (..., 6) moving at `pose_rate` (..., 6): the legs' lengths l (m) and speeds
    l' (m/s), each (..., legs), and their exact first derivatives: J = dl/dpose =
    dl'/dpose_rate and S = dl'/dpose, each (..., legs, 6). What a planner needs to bound
    the legs' stroke and speed along a planned motion, linearised about it.

    With v_i = t + R p_i - b_i, u_i = v_i / l_i and l'_i = u_i . v'_i:
    dl'_i/dpose_j = (dv_i/dpose_j . v'_i - (u_i . dv_i/dpose_j) l'_i) / l_i
                    + u_i . (dv'_i/dpose_j),
    dv'_i/dpose_j zero for the position coordinates and d2R/dangle_j dangle_k rate_k p_i
    for the angles.
    """
    pose = np.asarray(pose, dtype=float)
    rate = np.broadcast_to(np.asarray(pose_rate, dtype=float), pose.shape)
    legs = _legs(pose, geometry)
    lengths = np.linalg.norm(legs, axis=-1)
    units = legs / lengths[..., None]
    first, second = _rotation_derivatives(pose[..., 3:])
    p = np.asarray(geometry.platform_joints, dtype=float)

    def angle(values: np.ndarray, k: int) -> np.ndarray:
        return values[..., 3 + k, None, None]

    R_dot = sum(first[k] * angle(rate, k) for k in range(3))
    v_dot = rate[..., None, :3] + np.einsum("...jk,ik->...ij", R_dot, p)
    speeds = _dot(units, v_dot)
    # dv_i/dpose_j (..., legs, 6, 3): the unit vectors for x, y, z; dR/dangle p_i for angles
    dv = np.zeros((*legs.shape[:-1], 6, 3))
    dv[..., :, [0, 1, 2], [0, 1, 2]] = 1.0
    for k in range(3):
        dv[..., :, 3 + k, :] = np.einsum("...jk,ik->...ij", first[k], p)
    J = np.einsum("...ic,...ijc->...ij", units, dv)
    S = (np.einsum("...ijc,...ic->...ij", dv, v_dot) - J * speeds[..., None]) / lengths[..., None]
    for k in range(3):
        dR_dot = sum(second[k][m] * angle(rate, m) for m in range(3))
        S[..., 3 + k] += _dot(units, np.einsum("...jk,ik->...ij", dR_dot, p))
    return lengths, speeds, J, S


def forward_kinematics(
    lengths,
    geometry: LegGeometry,
    guess=None,
    tolerance: float = 1e-12,
    max_iterations: int = 50,
) -> np.ndarray:
    """A hexapod's pose (6,) whose legs have `lengths` (6, m), by Newton's method from
    `guess` (default the neutral pose): the pose nearest the guess where it has several.

    Raises:
        ValueError: a geometry of other than six legs, lengths that are not six finite
            numbers, or no pose within
            `max_iterations` (the lengths are beyond what the legs can reach together).
    """
    if np.shape(geometry.base_joints)[0] != LEGS:
        raise ValueError("forward kinematics is a hexapod's: six legs, six pose coordinates")
    target = np.asarray(lengths, dtype=float)
    if target.shape != (LEGS,) or not np.all(np.isfinite(target)):
        raise ValueError(f"forward kinematics needs six finite leg lengths; got {lengths}")
    pose = np.zeros(6) if guess is None else np.array(guess, dtype=float)
    for _ in range(max_iterations):
        error = leg_lengths(pose, geometry) - target
        if np.max(np.abs(error)) <= tolerance:
            return pose
        step = np.linalg.solve(leg_jacobian(pose, geometry), error)
        pose = pose - step
    error = np.max(np.abs(leg_lengths(pose, geometry) - target))
    if error <= 1e3 * tolerance:
        return pose  # converged to the precision the lengths carry
    raise ValueError(
        f"forward kinematics did not converge in {max_iterations} iterations (leg length "
        f"error {error:.3g} m): the lengths may be beyond the hexapod's workspace"
    )


__all__ = [
    "LEGS",
    "LegGeometry",
    "forward_kinematics",
    "leg_jacobian",
    "leg_lengths",
    "leg_motion",
    "leg_rates",
    "rotation",
]
