"""Second derivatives of the plant output at the NMPC's horizon nodes, learnt along the solves.

The converged NMPC minimises sum_k w_k ||y(v_k) - r_k||^2_W + convex quadratic terms, where
v_k = (q_k, qd_k, u_k) (3n for n joints) is affine in the plan U (N, n). Its exact Hessian is
Gauss-Newton's 2 J^T W J plus the residual curvature

    S = sum_k G_k^T B_k G_k,    B_k = sum_a c_ka d^2 y_a / dv_k^2,    c_ka = 2 w_k W_a (y_a - r_a)

(G_k = dv_k / dU). Gauss-Newton leaves S out. Where the reference cannot be rendered (a 3 g
step) the residuals stay large, S matters, and Gauss-Newton converges only linearly: 14
iterations at the median on a 3 g surge step, 9 on a flight.

This module keeps an estimate M (N, 6, 3n, 3n) of the output Hessians d^2 y_a / dv_k^2 of
every node and output, not of their residual-weighted sum, so that it stays right when the
residuals change (the reference moves every control step; the output's geometry does not):

- `finite_difference_hessians`: exact Jacobians differenced along the n directions of q
  at every node (one batched call) and the closed-form (qd, qd) block: the start of a run
  and a refresh.
- `psb_update`: after each Gauss-Newton step s, every node's and output's Powell-symmetric-
  Broyden update from the change of that output's exact Jacobian row along s_k = G_k s: the
  least change (Frobenius) that makes M_ka s_k equal the observed change. Unlike the
  symmetric rank-one update it cannot blow up (SR1 did, on the first step of a 3 g surge).
- `structure(n)`: y is affine in u with coefficients that depend on q only, and the angular
  velocity is linear in qd and independent of u; those blocks are exactly zero and are kept so
  (a projection: it never moves M away from a Hessian with that structure).

`NodeCondensing` maps a step in U to the node steps s_k and assembles S from the B_k.
"""

from __future__ import annotations

import functools

import numpy as np

from mca_drake.conventions import NUM_CHANNELS
from mca_drake.platforms.kinematics import output_velocity_hessians, plant_output_jacobians
from mca_drake.platforms.serial import SerialChain

NUM_OUTPUTS = NUM_CHANNELS
# Steps of the node's variables shorter than this (Euclidean, mixed rad, rad/s and rad/s^2)
# carry round-off rather than curvature: no update from them.
MIN_SECANT_STEP = 1e-6
# Finite-difference step of `finite_difference_hessians` (rad, rad/s): the exact Jacobians
# are differenced, so the error is O(step) ~ 1e-6 relative.
DIFFERENCE_STEP = 1e-6


@functools.lru_cache(maxsize=8)
def structure(joints: int) -> np.ndarray:
    """(6, 3n, 3n) of 1 where d^2 y_a / dv^2 may be non-zero, 0 where it is zero exactly, for
    nodes v = (q, qd, u) of n `joints`."""
    mask = np.ones((NUM_OUTPUTS, 3 * joints, 3 * joints))
    qd, u = (slice(i * joints, (i + 1) * joints) for i in (1, 2))
    # every output: affine in u, with coefficients that depend on q only
    mask[:, u, u] = mask[:, u, qd] = mask[:, qd, u] = 0.0
    # the angular velocity R^T sum_i qd_i z_i(q): no u at all, linear in qd
    mask[:3, u, :] = mask[:3, :, u] = mask[:3, qd, qd] = 0.0
    mask.setflags(write=False)
    return mask


def node_jacobians(jac) -> np.ndarray:
    """dy / dv at every node, shape (N, 6, 3n), from `kinematics.OutputJacobians`."""
    return np.concatenate([jac.dy_dq, jac.dy_dqd, jac.dy_dqdd], axis=-1)


def finite_difference_hessians(
    q: np.ndarray, qd: np.ndarray, u: np.ndarray, robot: SerialChain, jacobian: np.ndarray
) -> np.ndarray:
    """d^2 y_a / dv^2 at N nodes (q, qd, u each (N, n)), shape (N, 6, 3n, 3n).

    The exact Jacobians (`jacobian`, (N, 6, 3n), at the nodes) differenced forward along q
    give every block with a q in it; the (qd, qd) block is the closed form of
    `kinematics.output_velocity_hessians` (y is quadratic in qd); the u columns follow by
    symmetry (y is affine in u). Differencing along q only halves the cost of a refresh
    against differencing along (q, qd) (120 Jacobian nodes instead of 240 at N = 20).
    """
    n, nu = q.shape[0], robot.num_joints
    Q = np.repeat(q[None], nu, 0)
    for j in range(nu):
        Q[j, :, j] += DIFFERENCE_STEP
    shifted = plant_output_jacobians(
        Q.reshape(-1, nu), np.tile(qd, (nu, 1)), np.tile(u, (nu, 1)), robot
    )
    moved = node_jacobians(shifted).reshape(nu, n, NUM_OUTPUTS, 3 * nu)
    columns = (moved - jacobian[None]) / DIFFERENCE_STEP  # [j, k, a, i] = d/dq_j (dy_a/dv_i)
    M = np.zeros((n, NUM_OUTPUTS, 3 * nu, 3 * nu))
    M[..., :nu] = columns.transpose(1, 2, 3, 0)
    M[..., :nu, nu:] = np.swapaxes(M[..., nu:, :nu], -1, -2)
    M[..., :nu, :nu] = 0.5 * (M[..., :nu, :nu] + np.swapaxes(M[..., :nu, :nu], -1, -2))
    M[..., nu : 2 * nu, nu : 2 * nu] = output_velocity_hessians(q, robot)
    return M * structure(nu)


def psb_update(M: np.ndarray, steps: np.ndarray, jacobian_change: np.ndarray) -> np.ndarray:
    """M after the Powell-symmetric-Broyden update of every node and output.

    Args:
        M: the output Hessians, shape (N, 6, 3n, 3n).
        steps: the node steps s_k, shape (N, 3n).
        jacobian_change: dy/dv at the new point less at the old, shape (N, 6, 3n).

    M_ka + (r s^T + s r^T) / s^T s - (r^T s) s s^T / (s^T s)^2 with r = change - M_ka s, then
    the exact zeros of `structure`; nodes with |s_k| < MIN_SECANT_STEP are left as they are.
    """
    ss = np.einsum("ki,ki->k", steps, steps)
    moved = ss > MIN_SECANT_STEP**2
    # per node: the step scaled by 1/s^T s (0 where it did not move: no update there)
    s = steps[:, None, :]  # (N, 1, 3n)
    s_scaled = np.where(moved, 1.0 / np.where(moved, ss, 1.0), 0.0)[:, None, None] * s
    r = jacobian_change - (M @ steps[:, None, :, None])[..., 0]  # (N, 6, 3n)
    # the projection of r on s, taken out once so that the update stays symmetric
    r = r - 0.5 * np.einsum("kai,kbi->ka", r, s)[..., None] * s_scaled
    rsT = r[..., :, None] * s_scaled[..., None, :]
    return (M + rsT + np.swapaxes(rsT, -1, -2)) * structure(M.shape[-1] // 3)


def residual_curvature(M: np.ndarray, weighted_residual: np.ndarray) -> np.ndarray:
    """B_k = sum_a c_ka M_ka, shape (N, 3n, 3n), for c (N, 6) = 2 w_k W_a (y - r)_ka."""
    return np.einsum("ka,kaij->kij", weighted_residual, M)


class NodeCondensing:
    """The affine map from the plan U (N, n) to the node variables v_k = (q_k, qd_k, u_k):
    q_k = sum_j Sq[k, j] u_j + ..., qd_k = sum_j Sqd[k, j] u_j + ..., u_k = u_k.

    Args:
        Sq: the OCP's condensing coefficients of the positions, shape (>= N, N) (rows
            0..N-1 used).
        Sqd: those of the velocities, the same shape.
        joints: the joint count n.
    """

    def __init__(self, Sq: np.ndarray, Sqd: np.ndarray, joints: int):
        n = Sq.shape[1]
        self.joints = joints
        # coefficients[k, b, j]: d (block b of v_k) / d u_j, b in (q, qd, u)
        self.coefficients = np.stack([Sq[:n], Sqd[:n], np.eye(n)], axis=1)  # (N, 3, N)
        self.N = n

    def node_steps(self, step: np.ndarray) -> np.ndarray:
        """s_k = G_k s for a plan step (N, n) or (nN,): shape (N, 3n)."""
        s = np.reshape(step, (self.N, self.joints))
        return np.einsum("kbj,jx->kbx", self.coefficients, s).reshape(self.N, 3 * self.joints)

    def gradient(self, node_gradients: np.ndarray) -> np.ndarray:
        """sum_k G_k^T n_k for node gradients n (N, 3n): shape (nN,)."""
        n = node_gradients.reshape(self.N, 3, self.joints)
        return np.einsum("kbj,kbx->jx", self.coefficients, n).reshape(-1)

    def jacobian(self, node_jacobian: np.ndarray) -> np.ndarray:
        """The condensed Jacobian d y_k / d U of node Jacobians dy/dv (N, 6, 3n): shape
        (6N, nN), rows (node, output), columns (interval, joint)."""
        blocks = node_jacobian.reshape(self.N, NUM_OUTPUTS, 3, self.joints)
        J = np.einsum("kabx,kbj->kajx", blocks, self.coefficients)
        return J.reshape(self.N * NUM_OUTPUTS, self.N * self.joints)

    def assemble(self, B: np.ndarray) -> np.ndarray:
        """sum_k G_k^T B_k G_k for node matrices B (N, 3n, 3n): shape (nN, nN)."""
        n, nu, c = self.N, self.joints, self.coefficients
        # T[k, a, x, y, l] = sum_b B[k, (a, x), (b, y)] c[k, b, l]
        blocks = B.reshape(n, 3 * nu, 3, nu).transpose(0, 1, 3, 2)  # (N, 3n, n, 3)
        T = blocks @ c[:, None, :, :]  # (N, 3n, n, N)
        # S[j, x, y, l] = sum_(k, a) c[k, a, j] T[k, a, x, y, l]
        S = c.reshape(3 * n, n).T @ T.reshape(3 * n, nu * nu * n)
        return S.reshape(n, nu, nu, n).transpose(0, 1, 3, 2).reshape(n * nu, n * nu)
