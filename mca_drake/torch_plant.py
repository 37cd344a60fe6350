"""The exact motion-cueing plant in torch: batched, differentiable, float32 or float64.

This is the plant the DPC policy is trained against, so it is written for speed:
joints and time steps are tensor dimensions, never Python loops, except the six-link
chain product of forward kinematics, which is inherently sequential.

State transition (equation 1a), the exact zero-order-hold discretisation of one double
integrator per joint with period dt:

    q_(t+1)  = q_t + dt qd_t + dt^2/2 u_t
    qd_(t+1) = qd_t + dt u_t

Time indexing: for inputs U[:, t] (t = 0..T-1) a rollout returns states X[:, t]
(t = 0..T, X[:, 0] = x0) and outputs Y[:, t] = y(X[:, t], U[:, t]), the output felt while
U[:, t] is applied (so Y[:, t] is the paper's y_(t+1), predicted from x_t and u_t).

Shapes: x (..., 12) = [q, qd]; u (..., 6) = qdd; y (..., 6) = [w_x, w_y, w_z, f_x, f_y, a_z].
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from mca_drake.kinematics import GRAVITY
from mca_drake.robot import KR500, NUM_JOINTS, load_kr500

DEFAULT_DT = 0.01


def _check(name: str, tensor: torch.Tensor, last_dim: int) -> None:
    if not isinstance(tensor, torch.Tensor):
        raise ValueError(f"{name} must be a torch.Tensor; got {type(tensor).__name__}")
    if tensor.ndim == 0 or tensor.shape[-1] != last_dim:
        raise ValueError(f"{name} must have shape (..., {last_dim}); got {tuple(tensor.shape)}")
    if not torch.isfinite(tensor).all():
        raise ValueError(f"{name} has non-finite entries")


class TorchPlant(nn.Module):
    """Exact analytical KR500 motion-cueing plant (equation 1) as a torch module.

    No learnable parameters; the DH table and X_6H are buffers, so `.to(dtype)` and
    `.to(device)` move them. Inputs must match the module's dtype and device.

    Args:
        robot: the KR500 description (default: models/kr500.urdf).
        dt: control period, s.
        dtype: torch.float32 or torch.float64.
        check_inputs: validate shapes and finiteness on every call (a small cost; switch
            off inside training loops whose inputs are known good).
    """

    def __init__(
        self,
        robot: KR500 | None = None,
        dt: float = DEFAULT_DT,
        dtype: torch.dtype = torch.float32,
        check_inputs: bool = True,
    ):
        super().__init__()
        if not dt > 0:
            raise ValueError(f"dt must be positive; got {dt}")
        robot = robot if robot is not None else load_kr500()
        self.dt = float(dt)
        self.check_inputs = check_inputs
        dh = robot.dh

        def buffer(name: str, value: np.ndarray) -> None:
            self.register_buffer(name, torch.tensor(np.array(value), dtype=dtype), persistent=False)

        buffer("dh_a", dh.a)
        buffer("dh_d", dh.d)
        buffer("dh_offset", dh.offset)
        buffer("cos_alpha", np.cos(dh.alpha))
        buffer("sin_alpha", np.sin(dh.alpha))
        buffer("R_6H", robot.R_6H)
        buffer("p_6H", robot.p_6H)
        buffer("gravity_W", np.array([0.0, 0.0, -GRAVITY]))

    # ----------------------------------------------------------------- state transition
    def step(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """One exact step: x (..., 12), u (..., 6) -> x_next (..., 12)."""
        if self.check_inputs:
            _check("x", x, 2 * NUM_JOINTS)
            _check("u", u, NUM_JOINTS)
        q, qd = x[..., :NUM_JOINTS], x[..., NUM_JOINTS:]
        dt = self.dt
        return torch.cat([q + dt * qd + (0.5 * dt * dt) * u, qd + dt * u], dim=-1)

    def rollout_states(self, x0: torch.Tensor, U: torch.Tensor) -> torch.Tensor:
        """States for inputs U (B, T, 6) from x0 (B, 12): X (B, T+1, 12), X[:, 0] = x0.

        Closed form with cumulative sums (no loop over time):
        qd_t = qd_0 + dt sum_(k<t) u_k and q_t = q_0 + dt sum_(k<t) qd_k + dt^2/2 sum_(k<t) u_k.
        """
        if self.check_inputs:
            _check("x0", x0, 2 * NUM_JOINTS)
            _check("U", U, NUM_JOINTS)
            if U.ndim != x0.ndim + 1 or U.shape[:-2] != x0.shape[:-1]:
                raise ValueError(
                    f"U must have shape (*batch, T, 6) for x0 of shape (*batch, 12); got "
                    f"x0 {tuple(x0.shape)}, U {tuple(U.shape)}"
                )
        dt = self.dt
        q0, qd0 = x0[..., None, :NUM_JOINTS], x0[..., None, NUM_JOINTS:]
        zero = torch.zeros_like(U[..., :1, :])
        sum_u = torch.cat([zero, torch.cumsum(U, dim=-2)], dim=-2)  # (B, T+1, 6)
        qd = qd0 + dt * sum_u
        # sum_(k<t) qd_k = t qd_0 + dt sum_(k<t) sum_u_k
        steps = torch.arange(U.shape[-2] + 1, dtype=U.dtype, device=U.device)[:, None]
        sum_sum_u = torch.cat([zero, torch.cumsum(sum_u[..., :-1, :], dim=-2)], dim=-2)
        q = q0 + dt * steps * qd0 + dt * dt * sum_sum_u + (0.5 * dt * dt) * sum_u
        return torch.cat([q, qd], dim=-1)

    # ----------------------------------------------------------------- kinematics
    def dh_frames(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """World rotations and origins of DH frames 0..5 and of H.

        Returns:
            (R, p): R (..., 7, 3, 3) and p (..., 7, 3); entries 0..5 are DH frames 0..5
            (the frames whose z axes are joints 1..6), entry 6 is the head frame H.
        """
        theta = q + self.dh_offset
        c, s = torch.cos(theta), torch.sin(theta)
        ca, sa = self.cos_alpha.expand_as(c), self.sin_alpha.expand_as(c)
        zero = torch.zeros_like(c)
        # rotation and translation of every DH link transform at once, (..., 6, 3, 3) and (..., 6, 3)
        A_R = torch.stack(
            [c, -s * ca, s * sa, s, c * ca, -c * sa, zero, sa, ca], dim=-1
        ).unflatten(-1, (3, 3))
        A_p = torch.stack([self.dh_a * c, self.dh_a * s, self.dh_d.expand_as(c)], dim=-1)
        R = [torch.eye(3, dtype=q.dtype, device=q.device).expand(*q.shape[:-1], 3, 3)]
        p = [torch.zeros_like(A_p[..., 0, :])]
        for i in range(NUM_JOINTS):
            p.append(p[-1] + (R[-1] @ A_p[..., i, :, None])[..., 0])
            R.append(R[-1] @ A_R[..., i, :, :])
        R_WH = R[-1] @ self.R_6H
        p_WH = p[-1] + (R[-1] @ self.p_6H[:, None])[..., 0]
        return torch.stack([*R[:-1], R_WH], dim=-3), torch.stack([*p[:-1], p_WH], dim=-2)

    def head_pose(self, q: torch.Tensor) -> torch.Tensor:
        """F(q) = X_WH, shape (..., 4, 4)."""
        if self.check_inputs:
            _check("q", q, NUM_JOINTS)
        R, p = self.dh_frames(q)
        top = torch.cat([R[..., -1, :, :], p[..., -1, :, None]], dim=-1)
        bottom = torch.zeros_like(top[..., :1, :])
        bottom[..., 0, 3] = 1.0
        return torch.cat([top, bottom], dim=-2)

    def output(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Plant output y(x, u) of equation (1), shape (..., 6), for x (..., 12), u (..., 6)."""
        if self.check_inputs:
            _check("x", x, 2 * NUM_JOINTS)
            _check("u", u, NUM_JOINTS)
            if x.shape[:-1] != u.shape[:-1]:
                raise ValueError(f"x {tuple(x.shape)} and u {tuple(u.shape)} batch shapes differ")
        return self._output(x, u)

    def _output(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        qd, qdd = x[..., NUM_JOINTS:, None], u[..., :, None]  # (..., 6, 1)
        R, p = self.dh_frames(x[..., :NUM_JOINTS])
        Z, O = R[..., :NUM_JOINTS, :, 2], p[..., :NUM_JOINTS, :]  # (..., 6, 3)
        R_WH, r = R[..., -1, :, :], p[..., -1, :]
        w = qd * Z  # angular velocity contributed by each joint
        omega_upto = torch.cumsum(w, dim=-2)
        omega_before = omega_upto - w
        omega = omega_upto[..., -1, :]
        w_dot = qdd * Z + qd * torch.linalg.cross(omega_before, Z, dim=-1)
        moment = torch.linalg.cross(O, w, dim=-1)
        v_origin_upto = torch.cumsum(moment, dim=-2)
        O_dot = v_origin_upto - moment + torch.linalg.cross(omega_before, O, dim=-1)
        r_dot = v_origin_upto[..., -1, :] + torch.linalg.cross(omega, r, dim=-1)
        r_rel = r[..., None, :] - O
        r_ddot = (
            torch.linalg.cross(w_dot, r_rel, dim=-1)
            + torch.linalg.cross(w, r_dot[..., None, :] - O_dot, dim=-1)
        ).sum(dim=-2)
        # Into H: v_H = R_WH^T v_W, written as v_W @ R_WH.
        omega_H = (omega[..., None, :] @ R_WH)[..., 0, :]
        a_H = (r_ddot[..., None, :] @ R_WH)[..., 0, :]
        g_H = (self.gravity_W @ R_WH)  # (..., 3)
        return torch.cat([omega_H, a_H[..., :2] - g_H[..., :2], a_H[..., 2:]], dim=-1)

    def forward(self, x0: torch.Tensor, U: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Open-loop rollout: x0 (B, 12), U (B, T, 6) -> (X (B, T+1, 12), Y (B, T, 6))."""
        X = self.rollout_states(x0, U)  # checks x0 and U
        return X, self._output(X[..., :-1, :], U)
