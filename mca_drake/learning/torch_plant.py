"""The exact motion-cueing plant in torch: batched, differentiable, float32 or float64.

This is the plant the DPC policy is trained against, so it is written for speed:
joints and time steps are tensor dimensions, never Python loops, except the n-link
chain product of forward kinematics, which is inherently sequential.

State transition (equation 1a), the exact zero-order-hold discretisation of one double
integrator per joint with period dt:

    q_(t+1)  = q_t + dt qd_t + dt^2/2 u_t
    qd_(t+1) = qd_t + dt u_t

Time indexing: for inputs U[:, t] (t = 0..T-1) a rollout returns states X[:, t]
(t = 0..T, X[:, 0] = x0) and outputs Y[:, t] = y(X[:, t], U[:, t]), the output felt while
U[:, t] is applied (so Y[:, t] is the paper's y_(t+1), predicted from x_t and u_t).

Shapes: x (..., 2n) = [q, qd]; u (..., n) = qdd; y (..., 6) = [w_x, w_y, w_z, f_x, f_y, a_z].
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from mca_drake.conventions import CONTROL_PERIOD_S, GRAVITY
from mca_drake.platforms.serial import SerialChain
from mca_drake.safety import VIABILITY_TOLERANCE


def _check(name: str, tensor: torch.Tensor, last_dim: int) -> None:
    if not isinstance(tensor, torch.Tensor):
        raise ValueError(f"{name} must be a torch.Tensor; got {type(tensor).__name__}")
    if tensor.ndim == 0 or tensor.shape[-1] != last_dim:
        raise ValueError(f"{name} must have shape (..., {last_dim}); got {tuple(tensor.shape)}")
    if not torch.isfinite(tensor).all():
        raise ValueError(f"{name} has non-finite entries")


Vec3 = tuple[torch.Tensor, torch.Tensor, torch.Tensor]


def _add(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def _cross(a: Vec3, p: tuple[float, float, float]) -> Vec3:
    """a x p for a constant vector p (zero components skipped)."""
    px, py, pz = p
    return (a[1] * pz - a[2] * py, a[2] * px - a[0] * pz, a[0] * py - a[1] * px)


def _rigid_acceleration(w: Vec3, w_dot: Vec3, p: tuple[float, float, float]) -> Vec3:
    """Acceleration of a point at constant offset p on a body: w_dot x p + w x (w x p)."""
    if p == (0.0, 0.0, 0.0):
        return (0.0, 0.0, 0.0)  # type: ignore[return-value]
    wp = _cross(w, p)
    a = _cross(w_dot, p)
    return (
        a[0] + w[1] * wp[2] - w[2] * wp[1],
        a[1] + w[2] * wp[0] - w[0] * wp[2],
        a[2] + w[0] * wp[1] - w[1] * wp[0],
    )


def _constant(values: np.ndarray) -> list:
    """A constant array as (nested) Python floats, with |v| < 1e-12 made exactly 0."""
    return np.where(np.abs(values) < 1e-12, 0.0, values).tolist()


def _apply(R: list[list[float]], v: Vec3) -> Vec3:
    """R^T v for a constant rotation R given as rows (so (R^T v)_k = sum_j R[j][k] v_j)."""
    return tuple(  # type: ignore[return-value]
        sum(R[j][k] * v[j] for j in range(3) if R[j][k] != 0.0) for k in range(3)
    )


def integrate_double_integrator(
    x0: torch.Tensor, U: torch.Tensor, dt: float, exact: bool = True
) -> torch.Tensor:
    """States of q'' = u per joint for inputs U (..., T, 6) from x0 (..., 12): (..., T+1, 12).

    Closed form with cumulative sums (no loop over time): qd_t = qd_0 + dt sum_(k<t) u_k and
    q_t = q_0 + dt sum_(k<t) qd_k, plus dt^2/2 sum_(k<t) u_k when `exact` (the zero-order-hold
    discretisation; without it, forward Euler).
    """
    n = U.shape[-1]
    q0, qd0 = x0[..., None, :n], x0[..., None, n:]
    zero = torch.zeros_like(U[..., :1, :])
    sum_u = torch.cat([zero, torch.cumsum(U, dim=-2)], dim=-2)  # (..., T+1, 6)
    qd = qd0 + dt * sum_u
    # sum_(k<t) qd_k = t qd_0 + dt sum_(k<t) sum_u_k
    steps = torch.arange(U.shape[-2] + 1, dtype=U.dtype, device=U.device)[:, None]
    sum_sum_u = torch.cat([zero, torch.cumsum(sum_u[..., :-1, :], dim=-2)], dim=-2)
    q = q0 + dt * steps * qd0 + dt * dt * sum_sum_u
    if exact:
        q = q + (0.5 * dt * dt) * sum_u
    return torch.cat([q, qd], dim=-1)


class TorchPlant(nn.Module):
    """Exact analytical motion-cueing plant (equation 1) of a serial platform, in torch.

    No learnable parameters; the platform's constant transforms are buffers, so `.to(dtype)`
    and `.to(device)` move them. Inputs must match the module's dtype and device.

    Args:
        robot: the platform (`mca_drake.platforms.serial.SerialChain`, n joints).
        dt: control period, s.
        dtype: torch.float32 or torch.float64.
        check_inputs: validate shapes and finiteness on every call (a small cost; switch
            off inside training loops whose inputs are known good).
    """

    def __init__(
        self,
        robot: SerialChain,
        dt: float = CONTROL_PERIOD_S,
        dtype: torch.dtype = torch.float32,
        check_inputs: bool = True,
    ):
        super().__init__()
        if not dt > 0:
            raise ValueError(f"dt must be positive; got {dt}")
        self.robot = robot
        self.n = robot.num_joints
        self.dt = float(dt)
        self.check_inputs = check_inputs

        def buffer(name: str, value: np.ndarray) -> None:
            self.register_buffer(name, torch.tensor(np.array(value), dtype=dtype), persistent=False)

        buffer("R_prev", robot.X_prev[:, :3, :3])
        buffer("p_prev", robot.X_prev[:, :3, 3])
        buffer("R_last_H", robot.X_last_H[:3, :3])
        self.register_buffer("revolute", torch.tensor(~robot.prismatic), persistent=False)
        buffer("p_last_H", robot.X_last_H[:3, 3])
        # Constants of the recursive output computation, as Python floats (dtype-free), with
        # round-off zeros of the URDF's rpy (cos(pi/2) = 6e-17) made exact so that the
        # products they would scale are skipped.
        self._prismatic = [bool(v) for v in robot.prismatic]
        self._R_prev = [_constant(X[:3, :3]) for X in robot.X_prev]
        self._p_prev = [tuple(_constant(X[:3, 3])) for X in robot.X_prev]
        self._R_last_H = _constant(robot.X_last_H[:3, :3])
        self._p_last_H = tuple(_constant(robot.X_last_H[:3, 3]))

    # ----------------------------------------------------------------- state transition
    def step(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """One exact step: x (..., 2n), u (..., n) -> x_next (..., 2n)."""
        n = self.n
        if self.check_inputs:
            _check("x", x, 2 * n)
            _check("u", u, n)
        q, qd = x[..., :n], x[..., n:]
        dt = self.dt
        return torch.cat([q + dt * qd + (0.5 * dt * dt) * u, qd + dt * u], dim=-1)

    def rollout_states(self, x0: torch.Tensor, U: torch.Tensor) -> torch.Tensor:
        """States for inputs U (B, T, n) from x0 (B, 2n): X (B, T+1, 2n), X[:, 0] = x0.

        Closed form with cumulative sums (no loop over time):
        qd_t = qd_0 + dt sum_(k<t) u_k and q_t = q_0 + dt sum_(k<t) qd_k + dt^2/2 sum_(k<t) u_k.
        """
        n = self.n
        if self.check_inputs:
            _check("x0", x0, 2 * n)
            _check("U", U, n)
            if U.ndim != x0.ndim + 1 or U.shape[:-2] != x0.shape[:-1]:
                raise ValueError(
                    f"U must have shape (*batch, T, {n}) for x0 of shape (*batch, {2 * n}); "
                    f"got x0 {tuple(x0.shape)}, U {tuple(U.shape)}"
                )
        return integrate_double_integrator(x0, U, self.dt, exact=True)

    # ----------------------------------------------------------------- kinematics
    def joint_frames(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """World rotations and origins of the joints' moving frames and of H.

        Returns:
            (R, p): R (..., n+1, 3, 3) and p (..., n+1, 3); entries 0..n-1 are the moving
            frames M_1..M_n (`mca_drake.platforms.kinematics.joint_frames`), entry n is H.
        """
        c, s = torch.cos(q), torch.sin(q)
        zero, one = torch.zeros_like(c), torch.ones_like(c)
        # Rz(q_i) of every joint, (..., n, 3, 3); the identity for a prismatic joint
        c, s = torch.where(self.revolute, c, one), torch.where(self.revolute, s, zero)
        Rz = torch.stack([c, -s, zero, s, c, zero, zero, zero, one], dim=-1).unflatten(-1, (3, 3))
        R = torch.eye(3, dtype=q.dtype, device=q.device).expand(*q.shape[:-1], 3, 3)
        p = torch.zeros(*q.shape[:-1], 3, dtype=q.dtype, device=q.device)
        rotations, origins = [], []
        for i in range(self.n):  # a chain product: inherently sequential
            p = p + (R @ self.p_prev[i, :, None])[..., 0]
            R = R @ self.R_prev[i]
            if self._prismatic[i]:
                p = p + R[..., :, 2] * q[..., i, None]
            R = R @ Rz[..., i, :, :]
            rotations.append(R)
            origins.append(p)
        p_WH = p + (R @ self.p_last_H[:, None])[..., 0]
        R_WH = R @ self.R_last_H
        return torch.stack([*rotations, R_WH], dim=-3), torch.stack([*origins, p_WH], dim=-2)

    def head_pose(self, q: torch.Tensor) -> torch.Tensor:
        """F(q) = X_WH, shape (..., 4, 4)."""
        if self.check_inputs:
            _check("q", q, self.n)
        R, p = self.joint_frames(q)
        top = torch.cat([R[..., -1, :, :], p[..., -1, :, None]], dim=-1)
        bottom = torch.zeros_like(top[..., :1, :])
        bottom[..., 0, 3] = 1.0
        return torch.cat([top, bottom], dim=-2)

    def output(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Plant output y(x, u) of equation (1), shape (..., 6), for x (..., 2n), u (..., n)."""
        if self.check_inputs:
            _check("x", x, 2 * self.n)
            _check("u", u, self.n)
            if x.shape[:-1] != u.shape[:-1]:
                raise ValueError(f"x {tuple(x.shape)} and u {tuple(u.shape)} batch shapes differ")
        return self._output(x, u)

    def _output(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        # Recursive Newton-Euler forward pass in the moving frames: angular velocity,
        # angular acceleration and origin acceleration of frame M_i, expressed in M_i.
        # Vectors are (x, y, z) tuples of (...)-shaped tensors: elementwise kernels, no
        # batched 3x3 matmuls (which are slow in torch for tiny matrices). Starting the base
        # at acceleration -g_W gives the specific force f directly (the gravity trick);
        # the vector -g_W = (0, 0, g) carried along gives a_z = f_z - (R_WH^T (0, 0, g))_z.
        n = self.n
        q, qd, qdd = x[..., :n].unbind(-1), x[..., n:].unbind(-1), u.unbind(-1)
        cos, sin = torch.cos(x[..., :n]).unbind(-1), torch.sin(x[..., :n]).unbind(-1)
        zero = torch.zeros_like(qd[0])
        g = torch.full_like(qd[0], GRAVITY)
        w, w_dot, acc, up = (zero, zero, zero), (zero, zero, zero), (zero, zero, g), (zero, zero, g)
        for i in range(n):
            # to the joint's frame F_i: its origin's acceleration, then its axes
            acc = _add(acc, _rigid_acceleration(w, w_dot, self._p_prev[i]))
            w, w_dot, acc, up = (_apply(self._R_prev[i], v) for v in (w, w_dot, acc, up))
            if self._prismatic[i]:
                # M_i slides along z by q: acc += w_dot x d + w x (w x d) + 2 w x d_dot + d_ddot
                d, d_dot = q[i], qd[i]
                slide = (w_dot[1] * d + 2 * w[1] * d_dot, -w_dot[0] * d - 2 * w[0] * d_dot, zero)
                wd = (w[1] * d, -w[0] * d, zero)  # w x d
                acc = _add(
                    acc,
                    (
                        slide[0] + w[1] * wd[2] - w[2] * wd[1],
                        slide[1] + w[2] * wd[0] - w[0] * wd[2],
                        w[0] * wd[1] - w[1] * wd[0] + qdd[i],
                    ),
                )
                continue
            # M_i turns about z: w += qd z; w_dot += qdd z + qd (w x z); then Rz(q)^T
            w_dot = (w_dot[0] + qd[i] * w[1], w_dot[1] - qd[i] * w[0], w_dot[2] + qdd[i])
            w = (w[0], w[1], w[2] + qd[i])
            c, s = cos[i], sin[i]
            w, w_dot, acc, up = (
                (c * v[0] + s * v[1], c * v[1] - s * v[0], v[2]) for v in (w, w_dot, acc, up)
            )
        acc = _add(acc, _rigid_acceleration(w, w_dot, self._p_last_H))
        R = self._R_last_H  # rows of R^T are the columns of R
        omega_H = _apply(R, w)
        f_H = _apply(R, acc)
        up_H_z = sum(R[k][2] * up[k] for k in range(3) if R[k][2] != 0.0)
        return torch.stack([*omega_H, f_H[0], f_H[1], f_H[2] - up_H_z], dim=-1)

    def forward(self, x0: torch.Tensor, U: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Open-loop rollout: x0 (B, 2n), U (B, T, n) -> (X (B, T+1, 2n), Y (B, T, 6))."""
        X = self.rollout_states(x0, U)  # checks x0 and U
        return X, self._output(X[..., :-1, :], U)


def viable_acceleration_bounds_torch(x, q_min, q_max, qd_max, qdd_max, h: float):
    """`viable_acceleration_bounds` in torch for states x = [q, qd] (..., 12): (lo, hi),
    each (..., 6), differentiable almost everywhere. Limits are tensors of shape (6,).
    For DPC training rollouts, so that the policy learns inside the same safety filter it
    runs behind (a non-viable state gets lo = hi = the braking command)."""
    n = q_min.shape[-1]
    q, qd = x[..., :n], x[..., n:]
    a = qdd_max

    def upper(q, qd, limit):
        A2 = h * h / (2 * a)
        B1 = h * h / 2 + h * qd / a
        C = q + h * qd + qd * qd / (2 * a) - limit
        disc = B1 * B1 - 4 * A2 * C
        root = (torch.sqrt(torch.clamp(disc, min=1e-12)) - B1) / (2 * A2)
        stop = torch.where((disc >= 0) & (qd + h * root >= 0), root, -qd / h)
        velocity = (qd_max - qd) / h
        position = 2 * (limit - q - h * qd) / (h * h)
        bound = torch.minimum(torch.minimum(stop, velocity), torch.minimum(position, a))
        # a reversal inside the step must not peak beyond the limit (`mca_drake.safety`)
        room = limit - q
        peak = torch.maximum(-qd * qd / (2 * torch.clamp(room, min=1e-12)), -a)
        return torch.where((qd > 0) & (2 * room < h * qd), torch.minimum(bound, peak), bound)

    hi = torch.minimum(upper(q, qd, q_max), a)
    lo = torch.maximum(-upper(-q, -qd, -q_min), -a)
    viable = lo <= hi + VIABILITY_TOLERANCE
    brake = torch.clamp(-qd / h, -a, a)
    hi = torch.where(viable, torch.maximum(hi, lo), brake)
    lo = torch.where(viable, lo, brake)
    return lo, hi
