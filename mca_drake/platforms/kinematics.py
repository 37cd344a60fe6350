"""Numpy kinematics of a serial platform's head frame and the plant output (equation 1).

All functions take the platform (`mca_drake.platforms.serial.SerialChain`, n joints) and are
batched over leading dimensions: joint arrays have shape (..., n) and results keep the
leading shape. Units are SI (rad, rad/s, rad/s^2 for revolute joints, m, m/s, m/s^2 for
prismatic ones and for the head).

Method. Forward kinematics is the chain product of the platform's normal form (each joint
turns about, or slides along, the z axis of its frame). Velocities and accelerations use
twists: joint i (axis Z_i through O_i, in W) has the unit twist xi_i = (Z_i, O_i x Z_i)
(angular, linear at the world origin) if it is revolute and xi_i = (0, Z_i) if it is
prismatic, and with [., .] the Lie bracket of twists and P_i- = sum_(j<i) qd_j xi_j the
twist of the joints before i,

    V = (omega, v_0)  = sum_i qd_i xi_i                          the head's twist
    A = (alpha, a_0)  = sum_i qdd_i xi_i + [P_i-, qd_i xi_i]     its time derivative
    r_dot  = v_0 + omega x r,    r_ddot = a_0 + alpha x r + omega x r_dot

for the head's origin r. The output y = [R^T omega, (R^T (r_ddot - g))_xy, (R^T r_ddot)_z]
(`mca_drake.conventions`). The Jacobians are exact closed forms of the same quantities
(`plant_output_jacobians`): moving joint k turns every twist beyond it by [xi_k, .].
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mca_drake.conventions import GRAVITY_W
from mca_drake.input_checks import as_float_array, same_shapes
from mca_drake.platforms.serial import SerialChain


def _joint_array(name: str, value, robot: SerialChain) -> np.ndarray:
    return as_float_array(name, value, last_dim=robot.num_joints)


def joint_frames(q, robot: SerialChain) -> np.ndarray:
    """World poses of the joints' moving frames M_1..M_n (joint i turns about, or slides
    along, the z axis of M_i), shape (..., n, 4, 4)."""
    return _frames(_joint_array("q", q, robot), robot)


def _frames(q: np.ndarray, robot: SerialChain) -> np.ndarray:
    """joint_frames of an already checked q (the NMPC's hot path checks it once)."""
    P = robot.X_prev  # (n, 4, 4): X_prev[i] Rz(q_i) changes columns 0 and 1 only
    revolute = ~robot.prismatic
    c = np.where(revolute, np.cos(q), 1.0)[..., None]
    s = np.where(revolute, np.sin(q), 0.0)[..., None]
    A = np.empty((*q.shape, 4, 4))
    A[..., :, 0] = P[:, :, 0] * c + P[:, :, 1] * s
    A[..., :, 1] = P[:, :, 1] * c - P[:, :, 0] * s
    A[..., :, 2] = P[:, :, 2]
    # Tz(q_i) moves the origin along the joint's axis
    A[..., :, 3] = P[:, :, 3] + np.where(revolute, 0.0, q)[..., None] * P[:, :, 2]
    frames = np.empty_like(A)
    frames[..., 0, :, :] = A[..., 0, :, :]
    for i in range(1, robot.num_joints):  # a chain product: inherently sequential
        frames[..., i, :, :] = frames[..., i - 1, :, :] @ A[..., i, :, :]
    return frames


def head_pose(q, robot: SerialChain) -> np.ndarray:
    """F(q) = X_WH, the head frame pose in the world, shape (..., 4, 4) (equation 1b)."""
    return joint_frames(q, robot)[..., -1, :, :] @ robot.X_last_H


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


# [v]x: its six non-zero entries (row, column, component of v, sign).
_SKEW_ENTRIES = np.array(
    [(0, 1, 2, -1), (0, 2, 1, 1), (1, 0, 2, 1), (1, 2, 0, -1), (2, 0, 1, -1), (2, 1, 0, 1)]
)


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]x (..., 3, 3) of vectors v (..., 3): [v]x u = v x u; as rows, u x v = u @ [v]x."""
    rows, cols, comps, signs = _SKEW_ENTRIES.T
    S = np.zeros((*v.shape, 3))
    S[..., rows, cols] = v[..., comps] * signs
    return S


# ad(a) = [[ [w]x, 0 ], [ [v]x, [w]x ]] for a twist a = (w, v): ad(a) b = [a, b], the Lie
# bracket (w_a x w_b, w_a x v_b + v_a x w_b), the rate of change of b when what carries it
# turns with a. Its 18 non-zero entries: (row, column, component of a, sign).
_AD_ENTRIES = np.array(
    [
        (row + 3 * block_row, col + 3 * block_col, comp + 3 * from_v, sign)
        for block_row, block_col, from_v in ((0, 0, 0), (1, 1, 0), (1, 0, 1))
        for row, col, comp, sign in _SKEW_ENTRIES
    ]
)


def _ad(a: np.ndarray) -> np.ndarray:
    """The ad matrices (..., 6, 6) of twists a (..., 6) (see _AD_ENTRIES)."""
    rows, cols, comps, signs = _AD_ENTRIES.T
    out = np.zeros((*a.shape, 6))
    out[..., rows, cols] = a[..., comps] * signs
    return out


def _ad_times(ad: np.ndarray, *twists: np.ndarray) -> list[np.ndarray]:
    """[a, b] for each b in `twists` (..., 6), from ad = _ad(a), in one matrix product."""
    products = ad @ np.stack(twists, axis=-1)
    return [products[..., i] for i in range(len(twists))]


@dataclasses.dataclass(frozen=True)
class _Twists:
    """The twist quantities of one batch of joint states (see the module docstring);
    per-joint arrays have the joint axis at -2."""

    R: np.ndarray  # (..., 3, 3) R_WH
    r: np.ndarray  # (..., 3) the head's origin in W
    S_Z: np.ndarray  # (..., n, 3, 3) [Z_i]x of the twists' angular parts (0: prismatic)
    xi: np.ndarray  # (..., n, 6) joint twists
    r_per_q: np.ndarray  # (..., n, 3) xi_lin + xi_ang x r: dr/dq_i, and d r_ddot / d qdd_i
    W: np.ndarray  # (..., 6, 6) qd_i xi_i
    P: np.ndarray  # (..., 6, 6) twist through joint i
    before: np.ndarray  # (..., 6, 6) twist before joint i
    ad_before: np.ndarray  # (..., 6, 6, 6) ad(before)
    B: np.ndarray  # (..., 6, 6) [before_i, W_i]: joint i's velocity product
    Qdd: np.ndarray  # (..., 6, 6) qdd_i xi_i
    V: np.ndarray  # (..., 6) the head's twist
    A: np.ndarray  # (..., 6) its time derivative
    r_dot: np.ndarray  # (..., 3)
    r_ddot: np.ndarray  # (..., 3), without gravity


def _twists(q, qd, qdd, robot: SerialChain) -> _Twists:
    q, qd, qdd = (_joint_array(n, v, robot) for n, v in (("q", q), ("qd", qd), ("qdd", qdd)))
    same_shapes(q=q, qd=qd, qdd=qdd)
    frames = _frames(q, robot)
    X_WH = frames[..., -1, :, :] @ robot.X_last_H
    R, r = X_WH[..., :3, :3], X_WH[..., :3, 3]
    Z = frames[..., :3, 2]  # (..., n, 3): the joints' axes
    O = frames[..., :3, 3]  # a point on each axis
    prismatic = robot.prismatic[:, None]
    angular = np.where(prismatic, 0.0, Z)
    S_Z = _skew(angular)
    # the twist's linear part O_i x Z_i (revolute) or Z_i (prismatic), and the velocity it
    # gives the head: Z_i x (r - O_i) or Z_i
    lever = S_Z @ np.stack([-O, r[..., None, :] - O], axis=-1)
    linear = np.where(prismatic, Z, lever[..., 0])
    xi = np.concatenate([angular, linear], axis=-1)
    r_per_q = np.where(prismatic, Z, lever[..., 1])
    W = qd[..., None] * xi
    P = np.cumsum(W, axis=-2)
    before = P - W
    ad_before = _ad(before)
    (B,) = _ad_times(ad_before, W)
    Qdd = qdd[..., None] * xi
    V = P[..., -1, :]
    A = Qdd.sum(axis=-2) + B.sum(axis=-2)
    omega, alpha = V[..., :3], A[..., :3]
    r_dot = V[..., 3:] + _cross(omega, r)
    r_ddot = A[..., 3:] + _cross(alpha, r) + _cross(omega, r_dot)
    return _Twists(R, r, S_Z, xi, r_per_q, W, P, before, ad_before, B, Qdd, V, A, r_dot, r_ddot)


def head_motion(q, qd, qdd, robot: SerialChain) -> HeadMotion:
    """Pose, velocity and acceleration of the head frame for joint states (..., 6) each."""
    t = _twists(q, qd, qdd, robot)
    X_WH = np.zeros((*t.R.shape[:-2], 4, 4))
    X_WH[..., :3, :3], X_WH[..., :3, 3], X_WH[..., 3, 3] = t.R, t.r, 1.0
    return HeadMotion(X_WH, t.V[..., :3], t.A[..., :3], t.r_dot, t.r_ddot)


def head_pose_derivatives(
    q, qd, qdd, robot: SerialChain
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
    return _head_rows(motion.X_WH[..., :3, :3], motion.omega_W, motion.a_W)


def _head_rows(R: np.ndarray, omega: np.ndarray, r_ddot: np.ndarray) -> np.ndarray:
    """y from R_WH (..., 3, 3), omega (..., 3) and r_ddot (..., 3), all in W."""
    world = np.stack([omega, r_ddot - GRAVITY_W, r_ddot], axis=-2)  # rows before R^T
    head = world @ R  # each row x -> R^T x
    return np.concatenate([head[..., 0, :], head[..., 1, :2], head[..., 2, 2:]], axis=-1)


def plant_output(q, qd, qdd, robot: SerialChain) -> np.ndarray:
    """The plant output y = [w_x, w_y, w_z, f_x, f_y, a_z] in H (equation 1), shape (..., 6).

    Args:
        q: joint positions, rad, shape (..., 6).
        qd: joint velocities, rad/s, the shape of q.
        qdd: joint accelerations, rad/s^2, the shape of q.

    Raises:
        ValueError: wrong shapes or non-finite entries.
    """
    t = _twists(q, qd, qdd, robot)
    return _head_rows(t.R, t.V[..., :3], t.r_ddot)


@dataclasses.dataclass(frozen=True)
class OutputJacobians:
    """y and its exact Jacobians; each Jacobian has shape (..., 6 outputs, n joints)."""

    y: np.ndarray
    dy_dq: np.ndarray
    dy_dqd: np.ndarray
    dy_dqdd: np.ndarray


def plant_output_jacobians(q, qd, qdd, robot: SerialChain) -> OutputJacobians:
    """y(q, qd, qdd) and its exact Jacobians with respect to q, qd and qdd.

    Batch over horizon nodes rather than looping. Method (module docstring): turning joint k
    turns every twist beyond it by [xi_k, .], so with P_k and S_k the twists through and
    beyond joint k,

        dV/dq_k  = [xi_k, S_k]                       dV/dqd_k  = xi_k
        dA/dq_k  = [xi_k, Qdd_k + B_k - [P_k, S_k]] + [P_k, [xi_k, S_k]]
        dA/dqd_k = [xi_k, S_k] + [P_k-, xi_k]

    (Qdd_k, B_k: the sums beyond k of qdd_i xi_i and of the velocity products [P_i-, qd_i
    xi_i]; the Jacobi identity gathers the terms), dr/dq_k = Z_k x (r - O_k), and the
    rotation into H adds d(R^T x)/dq_k = -R^T (Z_k x x). y is affine in qdd: d r_ddot/d qdd_k
    = Z_k x (r - O_k). Every derivative is a closed form on arrays of (nodes, 6 joints, 6):
    a few dozen numpy calls (forward-mode jets through the screw formulas took several
    hundred, 3.5 times the time).
    """
    t = _twists(q, qd, qdd, robot)
    xi, P = t.xi, t.P
    S = t.V[..., None, :] - P  # twist beyond joint k
    # the brackets as products with ad matrices, each built once
    (before_xi,) = _ad_times(t.ad_before, xi)
    ad_xi = _ad(xi)
    (turn_S,) = _ad_times(ad_xi, S)
    P_S, P_turn_S = _ad_times(_ad(P), S, turn_S)
    B, Qdd = t.B, t.Qdd
    beyond = (B.sum(axis=-2) + Qdd.sum(axis=-2))[..., None, :] - np.cumsum(B + Qdd, axis=-2)
    (turn_rest,) = _ad_times(ad_xi, beyond - P_S)
    n = robot.num_joints
    # tangents along q_1..q_n, then qd_1..qd_n: (..., 2n, 6) twists, (..., 2n, 3) points
    dV = np.concatenate([turn_S, xi], axis=-2)
    dA = np.concatenate([turn_rest + P_turn_S, turn_S + before_xi], axis=-2)
    dr = np.zeros((*t.r.shape[:-1], 2 * n, 3))
    dr[..., :n, :] = t.r_per_q
    omega, alpha = t.V[..., :3], t.A[..., :3]
    skews = _skew(np.stack([t.r, -omega, -alpha, t.r_dot], axis=-2))  # (..., 4, 3, 3)
    S_r, S_r_dot = skews[..., 0, :, :], skews[..., 3, :, :]
    # the cross products with this node's vectors, as rows (u x v = u @ [v]x, v x u =
    # u @ [-v]x), in one matrix product each
    d_omega = dV[..., :3]
    d_r_dot = dV[..., 3:] + np.concatenate([d_omega, dr], axis=-1) @ np.concatenate(
        [S_r, skews[..., 1, :, :]], axis=-2
    )
    d_r_ddot = dA[..., 3:] + np.concatenate([dA[..., :3], dr, d_omega, d_r_dot], axis=-1) @ (
        np.concatenate([S_r, skews[..., 2, :, :], S_r_dot, skews[..., 1, :, :]], axis=-2)
    )
    # rows of y before the rotation into H: omega (wx wy wz), r_ddot - g (fx fy), r_ddot (az)
    world = np.stack([omega, t.r_ddot - GRAVITY_W, t.r_ddot], axis=-2)  # (..., 3, 3)
    d_world = np.stack([d_omega, d_r_ddot, d_r_ddot], axis=-2)  # (..., 12, 3, 3)
    d_world[..., :n, :, :] += world[..., None, :, :] @ t.S_Z  # - Z_k x (row)
    head, d_head = world @ t.R, d_world @ t.R[..., None, :, :]  # x -> R^T x, as rows
    y = np.concatenate([head[..., 0, :], head[..., 1, :2], head[..., 2, 2:]], axis=-1)
    dy = np.concatenate([d_head[..., 0, :], d_head[..., 1, :2], d_head[..., 2, 2:]], axis=-1)
    dy = np.swapaxes(dy, -1, -2)  # (..., 6 outputs, 2n tangents)
    dy_dqdd = np.zeros_like(dy[..., :n])
    dy_dqdd[..., 3:, :] = np.swapaxes(t.r_per_q @ t.R, -1, -2)
    return OutputJacobians(y, dy[..., :n], dy[..., n:], dy_dqdd)


def output_velocity_hessians(q, robot: SerialChain) -> np.ndarray:
    """d^2 y / dqd^2, the output's curvature in the joint velocities: shape (..., 6, n, n),
    [output, i, j], for joint positions q (..., n).

    y is quadratic in qd with coefficients that depend on q only, so this is independent of qd
    and qdd and exact. The rates are linear in qd (rows 0-2 zero); for the forces (rows 3-5:
    R^T r_ddot, gravity constant), with e_i = d r_dot / d qd_i (Z_i x (r - O_i), or Z_i for a
    prismatic joint, whose Z_i counts as 0 in the products below) and the
    velocity products of A = sum_(j<i) qd_j qd_i [xi_j, xi_i] + ...,

        d^2 r_ddot / dqd_i dqd_j = D_ij,lin + D_ij,ang x r + Z_i x e_j + Z_j x e_i,
        D_ij = [xi_min(i,j), xi_max(i,j)] (0 on the diagonal)

    (module docstring: r_ddot = a_0 + alpha x r + omega x r_dot, omega = sum qd_i Z_i).
    """
    q = _joint_array("q", q, robot)
    zeros = np.zeros_like(q)
    t = _twists(q, zeros, zeros, robot)
    xi, Z, e = t.xi, t.xi[..., :3], t.r_per_q
    bracket = np.swapaxes(_ad(xi) @ np.swapaxes(xi, -1, -2)[..., None, :, :], -1, -2)
    # bracket[..., i, j, :] = [xi_i, xi_j]; D = that for i < j, [xi_j, xi_i] = -that for i > j
    n = robot.num_joints
    order = np.sign(np.subtract.outer(np.arange(n), np.arange(n)))
    D = -order[:, :, None] * bracket
    Z_e = _cross(Z[..., :, None, :], e[..., None, :, :])  # [..., i, j] = Z_i x e_j
    h = D[..., 3:] + _cross(D[..., :3], t.r[..., None, None, :]) + Z_e + np.swapaxes(Z_e, -2, -3)
    out = np.zeros((*q.shape[:-1], 6, n, n))
    out[..., 3:, :, :] = np.moveaxis(h @ t.R[..., None, :, :], -1, -3)  # rows x -> R^T x
    return out


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (length 3), broadcasting the leading axes. Same result as
    np.cross, whose axis bookkeeping costs ten times the arithmetic on small arrays."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def cut_trajectory(
    X: np.ndarray, U: np.ndarray, R: np.ndarray, robot: SerialChain, n_p: int, dtype="float32"
) -> dict[str, np.ndarray]:
    """A trajectory's segment arrays (`mca_drake.segments`): states X (T, 2n), inputs U
    (T, n) and references R (T, 6), T a multiple of n_p, with the outputs and head pose they
    give, each cut into T / n_p segments of n_p steps (U, X, Y, F, dF, ddF, R) of `dtype`."""
    n_segments = U.shape[0] // n_p
    if n_segments * n_p != U.shape[0] or X.shape[0] != U.shape[0] or R.shape[0] != U.shape[0]:
        raise ValueError(f"X, U and R need the same length, a multiple of {n_p}")
    n = robot.num_joints
    motion = head_motion(X[:, :n], X[:, n:], U, robot)
    F, dF, ddF = pose_derivatives_from_motion(motion)
    signals = {"U": U, "X": X, "Y": output_from_motion(motion), "F": F, "dF": dF, "ddF": ddF}
    return {
        name: a.reshape(n_segments, n_p, *a.shape[1:]).astype(dtype)
        for name, a in {**signals, "R": R}.items()
    }
