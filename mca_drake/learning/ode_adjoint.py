"""Runge-Kutta integration of a learned ODE with gradients by the adjoint method.

The adjoint method (Chen et al., 2018, "Neural ordinary differential equations") gets the
gradient of a loss L(x(t1)) by integrating, backwards in time from t1 to t0, the augmented
system

    dx/dt   = f(x, u; theta)
    da/dt   = -a^T df/dx             a(t1) = dL/dx(t1)
    da_p/dt = -a^T df/d(theta, u)    a_p(t1) = 0

so that dL/dx(t0) = a(t0) and dL/d(theta, u) = a_p(t0). Nothing of the forward solve is
stored: memory is constant in the number of steps. The input u is held constant over the
step (zero-order hold, as on the robot). Both directions use classical fourth-order
Runge-Kutta; the backward solve recomputes x(t) from x(t1), which is exact up to the
integration error (O(dt^5) per step).
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import nn

Dynamics = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


def rk4_step(f: Dynamics, x: torch.Tensor, u: torch.Tensor, dt: float) -> torch.Tensor:
    """One classical Runge-Kutta step of dx/dt = f(x, u), u held: x (B, n) -> (B, n)."""
    k1 = f(x, u)
    k2 = f(x + (0.5 * dt) * k1, u)
    k3 = f(x + (0.5 * dt) * k2, u)
    k4 = f(x + dt * k3, u)
    return x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


class _AdjointRk4(torch.autograd.Function):
    """x(t0 + dt) by one RK4 step forward; gradients by one RK4 step of the adjoint system."""

    @staticmethod
    def forward(ctx, x0, u, dt, module, *params):
        with torch.no_grad():
            x1 = rk4_step(module, x0, u, dt)
        ctx.module, ctx.dt = module, dt
        ctx.save_for_backward(x1, u, *params)
        return x1

    @staticmethod
    def backward(ctx, grad_x1):
        x1, u, *params = ctx.saved_tensors
        module, dt = ctx.module, ctx.dt
        n = x1.shape[-1]

        def augmented(state: torch.Tensor) -> tuple[torch.Tensor, ...]:
            # state = [x, a]; returns d/dt of (x, a, a_u, a_theta) (time running forwards).
            x, a = state[..., :n], state[..., n:]
            with torch.enable_grad():
                x = x.detach().requires_grad_(True)
                u_ = u.detach().requires_grad_(True)
                fx = module(x, u_)
                grads = torch.autograd.grad(fx, (x, u_, *params), grad_outputs=a, allow_unused=True)
            grads = [
                torch.zeros_like(p) if g is None else g
                for g, p in zip(grads, (x, u_, *params), strict=True)
            ]
            return (
                torch.cat([fx.detach(), -grads[0]], dim=-1),
                -grads[1],
                *(-g for g in grads[2:]),
            )

        # Integrate from t1 back to t0: a step of -dt on (x, a), accumulating the
        # parameter and input adjoints with the same Runge-Kutta weights.
        h = -dt
        s = torch.cat([x1.detach(), grad_x1], dim=-1)
        k1 = augmented(s)
        k2 = augmented(s + 0.5 * h * k1[0])
        k3 = augmented(s + 0.5 * h * k2[0])
        k4 = augmented(s + h * k3[0])
        stages = (k1, k2, k3, k4)
        weights = (1.0, 2.0, 2.0, 1.0)

        def combine(i: int) -> torch.Tensor:
            return (h / 6.0) * sum(w * k[i] for w, k in zip(weights, stages, strict=True))

        a0 = (s + combine(0))[..., n:]
        # a_p(t0) = a_p(t1) + integral from t1 to t0 of (-a^T df/dp) dt, with a_p(t1) = 0.
        grad_u = combine(1)
        grad_params = [combine(2 + i) for i in range(len(params))]
        return (a0, grad_u, None, None, *grad_params)


def odeint_step(
    module: nn.Module, x: torch.Tensor, u: torch.Tensor, dt: float, adjoint: bool = True
) -> torch.Tensor:
    """x(t + dt) for dx/dt = module(x, u) with u held, by one RK4 step.

    Args:
        module: the dynamics, (B, n), (B, m) -> (B, n).
        x: state (B, n); u: input (B, m); dt: step, s.
        adjoint: gradients by the adjoint method (constant memory); False backpropagates
            through the Runge-Kutta stages directly (discretise-then-differentiate).
    """
    if not adjoint:
        return rk4_step(module, x, u, dt)
    params = tuple(p for p in module.parameters() if p.requires_grad)
    return _AdjointRk4.apply(x, u, dt, module, *params)
