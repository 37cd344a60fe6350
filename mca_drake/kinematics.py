"""Numpy kinematics of the KR500 head frame and the motion-cueing plant output (equation 1).

All functions are batched over leading dimensions: joint arrays have shape (..., 6) and
results keep the leading shape. Units are SI (rad, rad/s, rad/s^2, m, m/s^2).

Method. Forward kinematics follows the DH table of the robot. Velocities and accelerations
use the revolute-joint screw form, with Z_i and O_i the world axis and origin of joint i
(fixed on link i-1) and w_i = qd_i Z_i:

    omega    = sum_i w_i                           angular velocity of H in W
    alpha    = sum_i qdd_i Z_i + qd_i dZ_i/dt      angular acceleration, dZ_i/dt = omega_<i x Z_i
    r_dot    = sum_i w_i x (r - O_i)
    r_ddot   = sum_i (dw_i/dt) x (r - O_i) + w_i x (r_dot - dO_i/dt)

The output y = [R^T omega, (R^T (r_ddot - g))_xy, (R^T r_ddot)_z] (`mca_drake.conventions`).

Jacobians are exact, by forward-mode differentiation: every quantity above carries its
tangent with respect to (q, qd), seeded with the exact derivatives of the geometry,
dZ_i/dq_k = Z_k x Z_i and dO_i/dq_k = Z_k x (O_i - O_k) for k < i, dr/dq_k = Z_k x (r - O_k)
and dR/dq_k = [Z_k]x R. y is affine in qdd, so dy/dqdd is read off in closed form.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mca_drake.conventions import GRAVITY_W
from mca_drake.input_checks import as_float_array, same_shapes
from mca_drake.robot import KR500, NUM_JOINTS, load_kr500


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (length 3), broadcasting the leading axes. Same result as
    np.cross, whose axis bookkeeping costs ten times the arithmetic on the small arrays of
    one NMPC step."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


# Directions of the forward-mode tangents: q_1..q_6, then qd_1..qd_6.
_NUM_TANGENTS = 2 * NUM_JOINTS


def _robot(robot: KR500 | None) -> KR500:
    return robot if robot is not None else load_kr500()


def _joint_array(name: str, value) -> np.ndarray:
    return as_float_array(name, value, last_dim=NUM_JOINTS)


def dh_transforms(q: np.ndarray, robot: KR500 | None = None) -> np.ndarray:
    """The six DH link transforms A_i(q_i) = X_(i-1),i, shape (..., 6, 4, 4)."""
    robot = _robot(robot)
    q = _joint_array("q", q)
    dh = robot.dh
    theta = q + dh.offset
    c, s = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(dh.alpha), np.sin(dh.alpha)
    A = np.zeros((*q.shape, 4, 4))
    A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = c, -s * ca, s * sa, dh.a * c
    A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = s, c * ca, -c * sa, dh.a * s
    A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = sa, ca, dh.d
    A[..., 3, 3] = 1.0
    return A


def dh_frames(q: np.ndarray, robot: KR500 | None = None) -> np.ndarray:
    """World poses of DH frames 0..6, X_W0 = I, shape (..., 7, 4, 4)."""
    A = dh_transforms(q, robot)
    frames = np.empty((*A.shape[:-3], NUM_JOINTS + 1, 4, 4))
    frames[..., 0, :, :] = np.eye(4)
    for i in range(NUM_JOINTS):  # a chain product: inherently sequential, 6 batched matmuls
        frames[..., i + 1, :, :] = frames[..., i, :, :] @ A[..., i, :, :]
    return frames


def head_pose(q, robot: KR500 | None = None) -> np.ndarray:
    """F(q) = X_WH, the head frame pose in the world, shape (..., 4, 4) (equation 1b)."""
    robot = _robot(robot)
    return dh_frames(q, robot)[..., -1, :, :] @ robot.X_6H


@dataclasses.dataclass(frozen=True)
class HeadMotion:
    """Motion of the head frame H in W (leading shape (...) of the joint arrays).

    Attributes:
        X_WH: pose, shape (..., 4, 4).
        omega_W: angular velocity of H, expressed in W, rad/s, shape (..., 3).
        alpha_W: angular acceleration of H, expressed in W, rad/s^2, shape (..., 3).
        v_W: velocity of H's origin, m/s, shape (..., 3).
        a_W: acceleration of H's origin (no gravity), m/s^2, shape (..., 3).
    """

    X_WH: np.ndarray
    omega_W: np.ndarray
    alpha_W: np.ndarray
    v_W: np.ndarray
    a_W: np.ndarray


class _Jet:
    """A vector value (..., 3) with its tangents (..., n, 3) or None (no derivatives)."""

    __slots__ = ("t", "v")

    def __init__(self, v: np.ndarray, t: np.ndarray | None):
        self.v, self.t = v, t

    def __add__(self, other: _Jet) -> _Jet:
        return _Jet(self.v + other.v, _add(self.t, other.t))

    def __sub__(self, other: _Jet) -> _Jet:
        return _Jet(self.v - other.v, _add(self.t, None if other.t is None else -other.t))

    def cross(self, other: _Jet) -> _Jet:
        t = None
        if self.t is not None:
            t = _cross(self.t, other.v[..., None, :])
        if other.t is not None:
            t = _add(t, _cross(self.v[..., None, :], other.t))
        return _Jet(_cross(self.v, other.v), t)

    def scaled(self, s: np.ndarray, ds: np.ndarray | None) -> _Jet:
        """s * self for a scalar jet (s (...), ds (..., n) or None)."""
        t = None if self.t is None else s[..., None, None] * self.t
        if ds is not None:
            t = _add(t, ds[..., :, None] * self.v[..., None, :])
        return _Jet(s[..., None] * self.v, t)

    # Per-joint jets have the joint axis at -2 in values and -3 in tangents.
    def cumsum_joints(self) -> _Jet:
        return _Jet(np.cumsum(self.v, axis=-2), None if self.t is None else np.cumsum(self.t, -3))

    def sum_joints(self) -> _Jet:
        return _Jet(self.v.sum(axis=-2), None if self.t is None else self.t.sum(axis=-3))

    def last_joint(self) -> _Jet:
        return _Jet(self.v[..., -1, :], None if self.t is None else self.t[..., -1, :, :])

    def per_joint(self) -> _Jet:
        """Inserts a joint axis of size 1 (to broadcast against per-joint jets)."""
        return _Jet(self.v[..., None, :], None if self.t is None else self.t[..., None, :, :])


def _add(a: np.ndarray | None, b: np.ndarray | None) -> np.ndarray | None:
    if a is None:
        return b
    return a if b is None else a + b


@dataclasses.dataclass(frozen=True)
class _Motion:
    R: np.ndarray  # (..., 3, 3) R_WH
    dR: np.ndarray | None  # (..., n, 3, 3)
    r: _Jet
    omega: _Jet
    alpha: _Jet
    r_dot: _Jet
    r_ddot: _Jet
    # dr_ddot/dqdd_i = Z_i x (r - O_i), shape (..., 6, 3)
    r_ddot_per_qdd: np.ndarray


def _motion(q, qd, qdd, robot: KR500 | None, with_tangents: bool) -> _Motion:
    robot = _robot(robot)
    q, qd, qdd = _joint_array("q", q), _joint_array("qd", qd), _joint_array("qdd", qdd)
    same_shapes(q=q, qd=qd, qdd=qdd)
    frames = dh_frames(q, robot)
    X_WH = frames[..., -1, :, :] @ robot.X_6H
    Z = frames[..., :-1, :3, 2]  # (..., 6, 3) axis of joint i = z of DH frame i-1
    O = frames[..., :-1, :3, 3]  # (..., 6, 3)
    R, r_value = X_WH[..., :3, :3], X_WH[..., :3, 3]

    dZ = dO = dr = dR = dqd = None
    if with_tangents:
        lead = q.shape[:-1]
        n = _NUM_TANGENTS
        # [i, k] = Z_k x (.)_i, kept where joint k moves the thing fixed on link i-1 (k < i).
        before = np.tril(np.ones((NUM_JOINTS, NUM_JOINTS)), k=-1)[..., None]
        Z_i, Z_k, O_i, O_k = (
            Z[..., :, None, :],
            Z[..., None, :, :],
            O[..., :, None, :],
            O[..., None, :, :],
        )
        dZ = np.zeros((*lead, NUM_JOINTS, n, 3))
        dO = np.zeros((*lead, NUM_JOINTS, n, 3))
        dZ[..., :NUM_JOINTS, :] = before * _cross(Z_k, Z_i)
        dO[..., :NUM_JOINTS, :] = before * _cross(Z_k, O_i - O_k)
        dr = np.zeros((*lead, n, 3))
        dr[..., :NUM_JOINTS, :] = _cross(Z, r_value[..., None, :] - O)
        dR = np.zeros((*lead, n, 3, 3))
        dR[..., :NUM_JOINTS, :, :] = _cross(
            Z[..., :, None, :], np.swapaxes(R, -1, -2)[..., None, :, :]
        ).swapaxes(-1, -2)  # column j of [Z_k]x R is Z_k x R[:, j]
        dqd = np.zeros((*lead, NUM_JOINTS, n))
        dqd[..., :, NUM_JOINTS:] = np.eye(NUM_JOINTS)

    Zj, Oj, r = _Jet(Z, dZ), _Jet(O, dO), _Jet(r_value, dr)
    w = Zj.scaled(qd, dqd)  # w_i = qd_i Z_i
    omega_upto = w.cumsum_joints()
    omega_before = omega_upto - w
    omega = omega_upto.last_joint()
    Z_dot = omega_before.cross(Zj)
    w_dot = Zj.scaled(qdd, None) + Z_dot.scaled(qd, dqd)
    alpha = w_dot.sum_joints()

    moment = Oj.cross(w)  # O_i x w_i: linear part of joint i's twist at the world origin
    v_origin_upto = moment.cumsum_joints()
    O_dot = (v_origin_upto - moment) + omega_before.cross(Oj)
    r_dot = v_origin_upto.last_joint() + omega.cross(r)
    r_rel = r.per_joint() - Oj
    r_ddot = (w_dot.cross(r_rel) + w.cross(r_dot.per_joint() - O_dot)).sum_joints()
    r_ddot_per_qdd = _cross(Z, r_rel.v)
    return _Motion(R, dR, r, omega, alpha, r_dot, r_ddot, r_ddot_per_qdd)


def head_motion(q, qd, qdd, robot: KR500 | None = None) -> HeadMotion:
    """Pose, velocity and acceleration of the head frame for joint states (..., 6) each."""
    m = _motion(q, qd, qdd, robot, with_tangents=False)
    X_WH = np.zeros((*m.R.shape[:-2], 4, 4))
    X_WH[..., :3, :3], X_WH[..., :3, 3], X_WH[..., 3, 3] = m.R, m.r.v, 1.0
    return HeadMotion(X_WH, m.omega.v, m.alpha.v, m.r_dot.v, m.r_ddot.v)


def _skew(v: np.ndarray) -> np.ndarray:
    S = np.zeros((*v.shape[:-1], 3, 3))
    S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    S[..., 1, 0], S[..., 2, 0], S[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return S


def head_pose_derivatives(
    q, qd, qdd, robot: KR500 | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """F, dF/dt and d^2F/dt^2 of equations (1b)-(1d), each shape (..., 4, 4).

    dF = [[R_dot, r_dot], [0, 0]] with R_dot = [omega]x R; ddF = [[R_ddot, r_ddot], [0, 0]]
    with R_ddot = ([alpha]x + [omega]x [omega]x) R.
    """
    return pose_derivatives_from_motion(head_motion(q, qd, qdd, robot))


def pose_derivatives_from_motion(motion: HeadMotion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F, dF, ddF) of an already computed `HeadMotion` (see `head_pose_derivatives`)."""
    F = motion.X_WH
    R = F[..., :3, :3]
    W = _skew(motion.omega_W)
    dF = np.zeros_like(F)
    dF[..., :3, :3], dF[..., :3, 3] = W @ R, motion.v_W
    ddF = np.zeros_like(F)
    ddF[..., :3, :3] = (_skew(motion.alpha_W) + W @ W) @ R
    ddF[..., :3, 3] = motion.a_W
    return F, dF, ddF


def output_from_motion(motion: HeadMotion) -> np.ndarray:
    """The plant output y of an already computed `HeadMotion`, shape (..., 6)."""
    R = motion.X_WH[..., :3, :3]
    omega_H = np.einsum("...ji,...j->...i", R, motion.omega_W)
    f_H = np.einsum("...ji,...j->...i", R, motion.a_W - GRAVITY_W)
    a_H_z = np.einsum("...j,...j->...", R[..., :, 2], motion.a_W)
    return np.concatenate([omega_H, f_H[..., :2], a_H_z[..., None]], axis=-1)


def _rotate_to_head(R: np.ndarray, dR: np.ndarray | None, v: _Jet) -> _Jet:
    """R^T v with its tangent R^T dv + dR^T v."""
    value = np.einsum("...ji,...j->...i", R, v.v)
    t = None
    if v.t is not None:
        t = np.einsum("...ji,...nj->...ni", R, v.t)
    if dR is not None:
        t = _add(t, np.einsum("...nji,...j->...ni", dR, v.v))
    return _Jet(value, t)


def _output(m: _Motion) -> tuple[np.ndarray, np.ndarray | None]:
    omega_H = _rotate_to_head(m.R, m.dR, m.omega)
    a_H = _rotate_to_head(m.R, m.dR, m.r_ddot)
    # f = R^T (r_ddot - g_W) = a_H - R^T g_W; only the x, y rows of f enter y.
    g_H = _rotate_to_head(m.R, m.dR, _Jet(np.broadcast_to(GRAVITY_W, m.r.v.shape), None))
    f_H = a_H - g_H
    y = np.concatenate([omega_H.v, f_H.v[..., :2], a_H.v[..., 2:]], axis=-1)
    if omega_H.t is None:
        return y, None
    t = np.concatenate([omega_H.t, f_H.t[..., :2], a_H.t[..., 2:]], axis=-1)
    return y, np.swapaxes(t, -1, -2)  # (..., 6 outputs, 12 tangents)


def plant_output(q, qd, qdd, robot: KR500 | None = None) -> np.ndarray:
    """The plant output y = [w_x, w_y, w_z, f_x, f_y, a_z] in H (equation 1), shape (..., 6).

    Args:
        q, qd, qdd: joint positions (rad), velocities (rad/s), accelerations (rad/s^2),
            each shape (..., 6) and the same shape.

    Raises:
        ValueError: wrong shapes or non-finite entries.
    """
    y, _ = _output(_motion(q, qd, qdd, robot, with_tangents=False))
    return y


@dataclasses.dataclass(frozen=True)
class OutputJacobians:
    """y and its exact Jacobians; each Jacobian has shape (..., 6 outputs, 6 joints)."""

    y: np.ndarray
    dy_dq: np.ndarray
    dy_dqd: np.ndarray
    dy_dqdd: np.ndarray


def plant_output_jacobians(q, qd, qdd, robot: KR500 | None = None) -> OutputJacobians:
    """y(q, qd, qdd) and its Jacobians with respect to q, qd and qdd (forward mode, exact).

    Cost is about 3x `plant_output`; batch over horizon nodes rather than looping.
    """
    m = _motion(q, qd, qdd, robot, with_tangents=True)
    y, dy = _output(m)
    # y is affine in qdd: only the accelerometer rows (f_x, f_y, a_z) depend on it.
    dy_dqdd = np.zeros_like(dy[..., :NUM_JOINTS])
    dy_dqdd[..., 3:, :] = np.einsum("...ji,...kj->...ik", m.R, m.r_ddot_per_qdd)
    return OutputJacobians(y, dy[..., :NUM_JOINTS], dy[..., NUM_JOINTS:], dy_dqdd)
