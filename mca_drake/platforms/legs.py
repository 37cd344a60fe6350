"""The legs of a platform moved by actuators between a base and a moving platform, and
their kinematics (numpy): the pose of its moving platform and the positions of its
actuators. A Stewart-platform hexapod has six legs and moves in all six pose coordinates;
a small rig (2 or 3 DOF) has two to four actuators and moves in some of them, a mechanism
holding the others at zero.

Frames: the base frame B (fixed, z up) has its origin in the plane of the base joints; the
platform frame P (moving) has its origin in the plane of the platform joints. At the
neutral pose P is B raised by `neutral_height` (m). A pose is six numbers relative to the
neutral pose, `(x, y, z, roll, pitch, yaw)` (m, rad): P's origin at (x, y, neutral_height +
z) in B and its rotation R = Rz(yaw) Ry(pitch) Rx(roll). Leg i joins the base joint b_i (in
B) to the platform joint p_i (in P) along the leg vector

    v_i = t + R p_i - b_i,      t = (x, y, neutral_height + z).

An actuator's position a_i is a function of its leg vector alone:
- a linear actuator (the legs of most hexapods and rigs): the leg's length a_i = |v_i|, m;
- a rotary one (`Cranks`: a motor at b_i turns an arm of length c, a rod of fixed length r
  joins the arm's tip to p_i): the arm's angle a_i, rad, the solution of
  |v_i - c (cos a_i e_i + sin a_i f_i)| = r nearer zero, e_i the arm's direction at angle 0
  and f_i = axis_i x e_i.
Every function here works through `_actuators`, the positions and their first and second
derivatives by the leg vector, so either kind gets the same exact kinematics:

`actuator_positions` is the inverse kinematics (batched over poses); `leg_jacobian` its
exact derivative da/dpose (legs x 6); `leg_motion` the actuators' positions, speeds and
accelerations of a pose moving with given pose rates and accelerations (what the actuator
limits bound); `leg_linearisation` the exact derivatives of positions and speeds along a
motion (what a planner's linearised limits need); `forward_kinematics` inverts a hexapod's
`actuator_positions` by Newton's method from the neutral pose (or a guess), to 1e-12 on the
positions. `leg_lengths` is the distance between each leg's joints (a linear leg's
position). The torch twin (for training through the legs) is `mca_drake.learning.legs`.
"""

import dataclasses
import math

import numpy as np

from mca_drake.input_checks import check_config_numbers

# A hexapod's legs.
LEGS = 6


@dataclasses.dataclass
class Cranks:
    """Rotary actuators: at each base joint b_i a motor turns an arm of `arm_length` about
    its axis; a rod of `rod_length` joins the arm's tip to the platform joint p_i (ball
    joints at both ends). The actuator's position is the arm's angle, rad: 0 along the
    arm's zero direction e_i, positive turning about the motor's axis by the right-hand
    rule (towards f_i = axis_i x e_i)."""

    # The arm from the motor's axis to the rod's joint, m, and the rod between joints, m.
    arm_length: float
    rod_length: float
    # Each arm's direction at angle 0, and its motor's axis (perpendicular to it): unit
    # [x, y, z] in the base frame, one per leg.
    arm_directions: list[list[float]]
    motor_axes: list[list[float]]

    def turn_directions(self) -> np.ndarray:
        """Each arm's direction at +90 deg, f_i = axis_i x e_i: (legs, 3)."""
        e = np.asarray(self.arm_directions, dtype=float)
        return np.cross(np.asarray(self.motor_axes, dtype=float), e)

    def validate(self, legs: int) -> None:
        """Raises ValueError for arms that cannot turn, naming the field."""
        check_config_numbers(self)
        if not (self.arm_length > 0 and self.rod_length > 0):
            raise ValueError("Cranks.arm_length and Cranks.rod_length must be positive, m")
        for name in ("arm_directions", "motor_axes"):
            vectors = np.asarray(getattr(self, name), dtype=float)
            if vectors.shape != (legs, 3) or not np.allclose(
                np.linalg.norm(vectors, axis=1), 1.0, atol=1e-9
            ):
                raise ValueError(
                    f"Cranks.{name} must be {legs} unit [x, y, z] vectors, one per leg"
                )
        e, axis = np.asarray(self.arm_directions), np.asarray(self.motor_axes)
        if not np.allclose(np.einsum("ij,ij->i", e, axis), 0.0, atol=1e-9):
            raise ValueError("each of Cranks.motor_axes must be perpendicular to its arm direction")


@dataclasses.dataclass
class LegGeometry:
    """Where a platform's legs attach, what moves them and how far and fast their actuators
    may move (every leg alike). An actuator's position is its leg's length (m) for linear
    actuators, its arm's angle (rad) where `cranks` turns the legs; speeds and
    accelerations are in the same unit per s and s^2."""

    # Base joints b_i in the base frame, m: one [x, y, z] per leg (a hexapod's six); where
    # cranks turn the legs, the arms' pivots on the motors' axes.
    base_joints: list[list[float]]
    # Platform joints p_i in the platform frame, m: one [x, y, z] per leg, leg i from b_i.
    platform_joints: list[list[float]]
    # Height of the platform frame above the base frame at the neutral pose, m.
    neutral_height: float
    # The actuators' position range (m of leg length between joint centres; rad of arm
    # angle), and their speed and acceleration limits (per s, per s^2).
    min_position: float
    max_position: float
    max_speed: float
    max_acceleration: float
    # Rotary actuators (`Cranks`); None: linear legs.
    cranks: Cranks | None = None

    def __post_init__(self):
        if isinstance(self.cranks, dict):  # from a JSON or YAML round trip
            self.cranks = Cranks(**self.cranks)

    @property
    def unit(self) -> str:
        """The actuators' position unit: "m" (linear legs) or "rad" (cranks)."""
        return "m" if self.cranks is None else "rad"

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
        for name in ("neutral_height", "max_speed", "max_acceleration"):
            if not getattr(self, name) > 0:
                raise ValueError(f"LegGeometry.{name} must be positive")
        if self.cranks is None and not self.min_position > 0:
            raise ValueError(
                "LegGeometry.min_position (a linear leg's shortest length) must be positive"
            )
        if not self.max_position > self.min_position:
            raise ValueError("LegGeometry.max_position must exceed min_position")
        if self.cranks is not None:
            self.cranks.validate(legs[0])
            if not (self.min_position > -math.pi and self.max_position < math.pi):
                raise ValueError("a crank's angle range must lie inside (-pi, pi), rad")
        neutral = actuator_positions(np.zeros(6), self)
        if np.any(neutral < self.min_position) or np.any(neutral > self.max_position):
            raise ValueError(
                f"the neutral pose's actuator positions {np.round(neutral, 4).tolist()} "
                f"{self.unit} are outside the range [{self.min_position}, "
                f"{self.max_position}] {self.unit}"
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
        arm_length: float = 0.0,
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
            stroke: the actuators' range, centred on their neutral position: m of leg
                length, or rad of arm angle with cranks.
            max_speed: the actuators' speed limit, m/s (rad/s with cranks).
            max_acceleration: their acceleration limit, m/s^2 (rad/s^2 with cranks).
            arm_length: with a positive length, rotary actuators (`Cranks`): each base
                joint a motor whose arm (this long, m) lies horizontal at the neutral pose,
                along the base circle's tangent towards its leg's platform joint, turning
                about the radius (up positive); each rod as long as the arm's tip is from
                its platform joint there. 0: linear legs.
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
        tops = np.array(platform) + lift
        if arm_length > 0:
            # each arm along its circle's tangent on its leg's side; its axis the radius,
            # signed so that turning up is positive (axis x e = +z)
            tangents, axes = [], []
            for b in base:
                radial = np.array([b[0], b[1], 0.0]) / math.hypot(b[0], b[1])
                tangent = np.array([-radial[1], radial[0], 0.0])
                side = 1.0 if np.dot(tops[len(tangents)] - np.array(b), tangent) > 0 else -1.0
                e = side * tangent
                axis = np.cross(e, [0.0, 0.0, 1.0])  # axis x e = z for e horizontal
                tangents.append(e.tolist())
                axes.append(axis.tolist())
            tips = np.array(base) + arm_length * np.array(tangents)
            rods = np.linalg.norm(tops - tips, axis=1)
            cranks = Cranks(
                arm_length=arm_length,
                rod_length=float(rods[0]),
                arm_directions=tangents,
                motor_axes=axes,
            )
            return cls(
                base_joints=base,
                platform_joints=platform,
                neutral_height=neutral_height,
                min_position=-0.5 * stroke,
                max_position=0.5 * stroke,
                max_speed=max_speed,
                max_acceleration=max_acceleration,
                cranks=cranks,
            )
        neutral = float(np.linalg.norm(tops[0] - np.array(base[0])))
        return cls(
            base_joints=base,
            platform_joints=platform,
            neutral_height=neutral_height,
            min_position=neutral - 0.5 * stroke,
            max_position=neutral + 0.5 * stroke,
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


def _pose(pose) -> np.ndarray:
    """`pose` as floats, after checking it is poses of six finite numbers (..., 6)."""
    pose = np.asarray(pose, dtype=float)
    if pose.shape[-1:] != (6,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"a pose is six finite numbers (x, y, z, roll, pitch, yaw); got {pose}")
    return pose


def _legs(pose: np.ndarray, geometry: LegGeometry, R: np.ndarray | None = None) -> np.ndarray:
    """The leg vectors t + R p_i - b_i in B, shape (..., legs, 3), of poses (..., 6) (checked
    by `_pose`) whose rotations are R (..., 3, 3) (default: from their angles)."""
    if R is None:
        pose = _pose(pose)
        X, Y, Z = _factors(pose[..., 3:])
        R = Z[0] @ Y[0] @ X[0]
    t = pose[..., :3] + np.array([0.0, 0.0, geometry.neutral_height])
    p = np.asarray(geometry.platform_joints, dtype=float)
    b = np.asarray(geometry.base_joints, dtype=float)
    return t[..., None, :] + np.einsum("...jk,ik->...ij", R, p) - b


def _crank_angles(legs: np.ndarray, cranks: Cranks):
    """The arms' angles (..., legs) of leg vectors (..., legs, 3), with the arms' unit
    directions c(a) and their derivatives c'(a) (..., legs, 3); NaN where the rod cannot
    reach (the pose is beyond the mechanism).

    |v - c_len c(a)|^2 = r^2 is M cos a + N sin a = K with M = v.e, N = v.f and
    K = (|v|^2 + c_len^2 - r^2) / (2 c_len): a = phi -+ acos(K / rho) with
    (rho, phi) the polar form of (M, N); the sign that gives the solution nearer zero is
    N's (cos a is then the larger).
    """
    e, f = np.asarray(cranks.arm_directions, dtype=float), cranks.turn_directions()
    arm, rod = cranks.arm_length, cranks.rod_length
    M, N = _dot(legs, e), _dot(legs, f)
    K = (_dot(legs, legs) + arm**2 - rod**2) / (2.0 * arm)
    with np.errstate(invalid="ignore"):
        spread = np.arccos(K / np.hypot(M, N))
    angles = np.arctan2(N, M) - np.where(N >= 0.0, 1.0, -1.0) * spread
    cos, sin = np.cos(angles)[..., None], np.sin(angles)[..., None]
    return angles, cos * e + sin * f, cos * f - sin * e


def _actuators(legs: np.ndarray, geometry: LegGeometry, derivatives: bool = True):
    """The actuators' positions a (..., legs) of leg vectors v (..., legs, 3) and, with
    `derivatives`, da/dv (..., legs, 3) and d2a/dv2 (..., legs, 3, 3) (else None, None).

    A linear leg: a = |v|, da/dv = u = v / |v|, d2a/dv2 = (I - u u^T) / |v|.
    A crank (implicit in F(a, v) = |w|^2 - r^2 = 0, w = v - c_len c(a)):
    da/dv = g = w / D with D = c_len (w . c'(a)), and differentiating g once more,
    d2a/dv2 = (I - c_len (c' g^T + g c'^T) + c_len (c_len + w . c) g g^T) / D.
    """
    if geometry.cranks is None:
        lengths = np.linalg.norm(legs, axis=-1)
        if not derivatives:
            return lengths, None, None
        g = legs / lengths[..., None]
        H = (np.eye(3) - g[..., :, None] * g[..., None, :]) / lengths[..., None, None]
        return lengths, g, H
    angles, c, c_dot = _crank_angles(legs, geometry.cranks)
    if not derivatives:
        return angles, None, None
    arm = geometry.cranks.arm_length
    w = legs - arm * c
    D = arm * _dot(w, c_dot)[..., None]
    g = w / D
    cross = c_dot[..., :, None] * g[..., None, :]
    H = (
        np.eye(3)
        - arm * (cross + np.swapaxes(cross, -1, -2))
        + (arm * (arm + _dot(w, c)))[..., None, None] * (g[..., :, None] * g[..., None, :])
    ) / D[..., None]
    return angles, g, H


def actuator_positions(pose, geometry: LegGeometry) -> np.ndarray:
    """The actuators' positions of `pose` (..., 6) relative to the neutral pose: leg
    lengths (m), or arm angles (rad) where cranks turn the legs; (..., legs)."""
    return _actuators(_legs(pose, geometry), geometry, derivatives=False)[0]


def arm_tips(pose, geometry: LegGeometry) -> np.ndarray:
    """Where cranks turn the legs: each arm's tip (the rod's lower joint) in the base frame
    at `pose` (..., 6), m: (..., legs, 3).

    Raises:
        ValueError: a geometry of linear legs (no arms).
    """
    if geometry.cranks is None:
        raise ValueError("linear legs have no arms")
    _, directions, _ = _crank_angles(_legs(pose, geometry), geometry.cranks)
    base = np.asarray(geometry.base_joints, dtype=float)
    return base + geometry.cranks.arm_length * directions


def leg_lengths(pose, geometry: LegGeometry) -> np.ndarray:
    """The distances (m) between each leg's joints at `pose` (..., 6): (..., legs); a
    linear leg's position."""
    return np.linalg.norm(_legs(pose, geometry), axis=-1)


def leg_jacobian(pose, geometry: LegGeometry) -> np.ndarray:
    """da/dpose of the actuators' positions at one pose (6,): (legs, 6 pose coordinates),
    exact.

    d a_i = g_i . (dt + dR p_i) with g_i = da_i/dv_i (`_actuators`); the angle columns use
    dR/dangle of R = Rz Ry Rx (`_rotation_derivatives`).
    """
    pose = _pose(pose)
    R, derivatives, _ = _rotation_derivatives(pose[3:], second=False)
    legs = _legs(pose, geometry, R)
    g = _actuators(legs, geometry)[1]
    p = np.asarray(geometry.platform_joints, dtype=float)
    J = np.empty((legs.shape[0], 6))
    J[:, :3] = g
    for k, dR in enumerate(derivatives):
        J[:, 3 + k] = np.einsum("ij,ij->i", g, p @ dR.T)
    return J


def _factors(angles: np.ndarray, order: int = 0) -> tuple[tuple[np.ndarray, ...], ...]:
    """Rx(roll), Ry(pitch), Rz(yaw) of angles (..., 3) and their derivatives by their own
    angle up to `order` (0, 1 or 2): three tuples (factor, d factor, d2 factor)[: order + 1],
    each (..., 3, 3); one pose's from scalars (a clamp evaluates one pose a period, where
    numpy's batched stacking costs most of the time)."""
    c, s = np.cos(angles), np.sin(angles)
    if angles.ndim == 1:  # one pose: plain nested lists are faster than filling arrays
        (cr, cp, cy), (sr, sp, sy) = c.tolist(), s.tolist()
        rows = (
            (
                [[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]],
                [[0.0, 0.0, 0.0], [0.0, -sr, -cr], [0.0, cr, -sr]],
                [[0.0, 0.0, 0.0], [0.0, -cr, sr], [0.0, -sr, -cr]],
            ),
            (
                [[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]],
                [[-sp, 0.0, cp], [0.0, 0.0, 0.0], [-cp, 0.0, -sp]],
                [[-cp, 0.0, -sp], [0.0, 0.0, 0.0], [sp, 0.0, -cp]],
            ),
            (
                [[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]],
                [[-sy, -cy, 0.0], [cy, -sy, 0.0], [0.0, 0.0, 0.0]],
                [[-cy, sy, 0.0], [-sy, -cy, 0.0], [0.0, 0.0, 0.0]],
            ),
        )
        return tuple(tuple(np.array(m) for m in axis[: order + 1]) for axis in rows)
    # a rotation about axis a by angle t: its two other axes (i, j) carry [[c, -s], [s, c]];
    # the first derivative [[-s, -c], [c, -s]], the second [[-c, s], [-s, -c]]; the axis
    # itself 1, 0, 0
    out = []
    for axis, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
        ca, sa = c[..., axis], s[..., axis]
        blocks = ((ca, -sa, sa, ca), (-sa, -ca, ca, -sa), (-ca, sa, -sa, -ca))
        factors = []
        for m in range(order + 1):
            F = np.zeros((*angles.shape[:-1], 3, 3))
            if m == 0:
                F[..., axis, axis] = 1.0
            F[..., i, i], F[..., i, j], F[..., j, i], F[..., j, j] = blocks[m]
            factors.append(F)
        out.append(tuple(factors))
    return tuple(out)


def _rotation_derivatives(angles: np.ndarray, second: bool = True):
    """R = Rz Ry Rx at angles (..., 3) = (roll, pitch, yaw), dR/dangle_k (3) and, with
    `second`, d2R/dangle_k dangle_l (3 x 3; else []), each (..., 3, 3): a derivative of R
    is the product with each factor replaced by its own derivative (`_factors`), and the
    products share their Rz Ry parts."""
    X, Y, Z = _factors(angles, 2 if second else 1)
    ZY = {(0, 0): Z[0] @ Y[0], (0, 1): Z[0] @ Y[1], (1, 0): Z[1] @ Y[0]}
    R = ZY[0, 0] @ X[0]
    # by roll (x), pitch (y), yaw (z)
    first = [ZY[0, 0] @ X[1], ZY[0, 1] @ X[0], ZY[1, 0] @ X[0]]
    if not second:
        return R, first, []
    xx = ZY[0, 0] @ X[2]
    yy = (Z[0] @ Y[2]) @ X[0]
    zz = (Z[2] @ Y[0]) @ X[0]
    xy = ZY[0, 1] @ X[1]
    xz = ZY[1, 0] @ X[1]
    yz = (Z[1] @ Y[1]) @ X[0]
    return R, first, [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...ij,...ij->...i", a, b)


def _quadratic(x: np.ndarray, H: np.ndarray, y: np.ndarray) -> np.ndarray:
    """x_i^T H_i y_i per leg: x, y (..., legs, 3), H (..., legs, 3, 3) -> (..., legs)."""
    return np.einsum("...i,...ij,...j->...", x, H, y)


def leg_motion(pose, pose_rate, pose_acceleration, geometry: LegGeometry):
    """The actuators' positions, speeds and accelerations (m, m/s, m/s^2 for linear legs;
    rad, rad/s, rad/s^2 for cranks), each (..., legs), of poses (..., 6) moving at
    `pose_rate` with `pose_acceleration` (the six pose coordinates' first and second time
    derivatives, same shape; angles as Euler-angle rates, rad/s and rad/s^2).

    With v_i = t + R p_i - b_i and g_i, H_i the position's first and second derivatives by
    v_i (`_actuators`): a'_i = g_i . v'_i and a''_i = v'_i^T H_i v'_i + g_i . v''_i,
    exactly (for a linear leg, (|v'_i|^2 - l'_i^2) / l_i + u_i . v''_i).
    """
    pose = _pose(pose)
    rate = np.broadcast_to(np.asarray(pose_rate, dtype=float), pose.shape)
    accel = np.broadcast_to(np.asarray(pose_acceleration, dtype=float), pose.shape)
    R, first, second = _rotation_derivatives(pose[..., 3:])
    legs = _legs(pose, geometry, R)
    positions, g, H = _actuators(legs, geometry)

    def angle(values: np.ndarray, k: int) -> np.ndarray:
        return values[..., 3 + k, None, None]

    R_dot = sum(first[k] * angle(rate, k) for k in range(3))
    R_ddot = sum(first[k] * angle(accel, k) for k in range(3)) + sum(
        second[k][m] * angle(rate, k) * angle(rate, m) for k in range(3) for m in range(3)
    )
    p = np.asarray(geometry.platform_joints, dtype=float)
    # R' p_i for every leg i: (..., legs, 3)
    v_dot = rate[..., None, :3] + np.einsum("...jk,ik->...ij", R_dot, p)
    v_ddot = accel[..., None, :3] + np.einsum("...jk,ik->...ij", R_ddot, p)
    speeds = _dot(g, v_dot)
    accelerations = _quadratic(v_dot, H, v_dot) + _dot(g, v_ddot)
    return positions, speeds, accelerations


def leg_rates(pose, pose_rate, geometry: LegGeometry):
    """One pose (6,) moving at `pose_rate` (6,): the actuators' positions, speeds and
    accelerations at zero pose acceleration (`leg_motion`'s units), each (legs,), and
    da/dpose (legs, 6), from one pass over the rotation's derivatives. An actuator's
    acceleration under a pose acceleration a is that drift plus J a (`leg_motion`'s a'' is
    linear in the pose acceleration): what a clamp needs every period."""
    pose = _pose(pose)
    rate = np.asarray(pose_rate, dtype=float)
    R, first, second = _rotation_derivatives(pose[3:])
    legs = _legs(pose, geometry, R)
    positions, g, H = _actuators(legs, geometry)
    R_dot = sum(first[k] * rate[3 + k] for k in range(3))
    R_ddot = sum(second[k][m] * (rate[3 + k] * rate[3 + m]) for k in range(3) for m in range(3))
    p = np.asarray(geometry.platform_joints, dtype=float)
    v_dot = rate[:3] + p @ R_dot.T
    speeds = _dot(g, v_dot)
    drift = _quadratic(v_dot, H, v_dot) + _dot(g, p @ R_ddot.T)
    J = np.empty((positions.size, 6))
    J[:, :3] = g
    for k, dR in enumerate(first):
        J[:, 3 + k] = _dot(g, p @ dR.T)
    return positions, speeds, drift, J


def leg_linearisation(pose, pose_rate, geometry: LegGeometry):
    """Poses (..., 6) moving at `pose_rate` (..., 6): the actuators' positions a and speeds
    a' (`leg_motion`'s units), each (..., legs), and their exact first derivatives:
    J = da/dpose = da'/dpose_rate and S = da'/dpose, each (..., legs, 6). What a planner
    needs to bound the actuators' range and speed along a planned motion, linearised about
    it.

    With v_i = t + R p_i - b_i, g_i and H_i the position's derivatives by v_i and
    a'_i = g_i . v'_i:
    da'_i/dpose_j = (dv_i/dpose_j)^T H_i v'_i + g_i . (dv'_i/dpose_j),
    dv'_i/dpose_j zero for the position coordinates and d2R/dangle_j dangle_k rate_k p_i
    for the angles.
    """
    pose = _pose(pose)
    rate = np.broadcast_to(np.asarray(pose_rate, dtype=float), pose.shape)
    R, first, second = _rotation_derivatives(pose[..., 3:])
    legs = _legs(pose, geometry, R)
    positions, g, H = _actuators(legs, geometry)
    p = np.asarray(geometry.platform_joints, dtype=float)

    def angle(values: np.ndarray, k: int) -> np.ndarray:
        return values[..., 3 + k, None, None]

    R_dot = sum(first[k] * angle(rate, k) for k in range(3))
    v_dot = rate[..., None, :3] + np.einsum("...jk,ik->...ij", R_dot, p)
    speeds = _dot(g, v_dot)
    # dv_i/dpose_j (..., legs, 6, 3): the unit vectors for x, y, z; dR/dangle p_i for angles
    dv = np.zeros((*legs.shape[:-1], 6, 3))
    dv[..., :, [0, 1, 2], [0, 1, 2]] = 1.0
    for k in range(3):
        dv[..., :, 3 + k, :] = np.einsum("...jk,ik->...ij", first[k], p)
    J = np.einsum("...ic,...ijc->...ij", g, dv)
    S = np.einsum("...ijc,...ic->...ij", dv, np.einsum("...icd,...id->...ic", H, v_dot))
    for k in range(3):
        dR_dot = sum(second[k][m] * angle(rate, m) for m in range(3))
        S[..., 3 + k] += _dot(g, np.einsum("...jk,ik->...ij", dR_dot, p))
    return positions, speeds, J, S


def forward_kinematics(
    positions,
    geometry: LegGeometry,
    guess=None,
    tolerance: float = 1e-12,
    max_iterations: int = 50,
) -> np.ndarray:
    """A hexapod's pose (6,) whose actuators are at `positions` (6: leg lengths, m, or arm
    angles, rad), by Newton's method from `guess` (default the neutral pose): the pose
    nearest the guess where it has several.

    Raises:
        ValueError: a geometry of other than six legs, positions that are not six finite
            numbers, or no pose within `max_iterations` (the positions are beyond what the
            legs can reach together).
    """
    if np.shape(geometry.base_joints)[0] != LEGS:
        raise ValueError("forward kinematics is a hexapod's: six legs, six pose coordinates")
    target = np.asarray(positions, dtype=float)
    if target.shape != (LEGS,) or not np.all(np.isfinite(target)):
        raise ValueError(f"forward kinematics needs six finite actuator positions; got {positions}")
    pose = np.zeros(6) if guess is None else np.array(guess, dtype=float)
    for _ in range(max_iterations):
        error = actuator_positions(pose, geometry) - target
        if not np.all(np.isfinite(error)):
            break  # a step left the mechanism's reach
        if np.max(np.abs(error)) <= tolerance:
            return pose
        try:
            step = np.linalg.solve(leg_jacobian(pose, geometry), error)
        except np.linalg.LinAlgError:
            break  # a singular pose: Newton's method cannot go on from it
        pose = pose - step
    error = np.max(np.abs(actuator_positions(pose, geometry) - target))
    if np.isfinite(error) and error <= 1e3 * tolerance:
        return pose  # converged to the precision the positions carry
    raise ValueError(
        f"forward kinematics did not converge in {max_iterations} iterations (actuator "
        f"position error {error:.3g} {geometry.unit}): the positions may be beyond the "
        "hexapod's workspace"
    )


__all__ = [
    "LEGS",
    "Cranks",
    "LegGeometry",
    "actuator_positions",
    "arm_tips",
    "forward_kinematics",
    "leg_jacobian",
    "leg_lengths",
    "leg_linearisation",
    "leg_motion",
    "leg_rates",
    "rotation",
]
