"""State-transition candidates (paper Section III-A): x_(t+1) from (x_t, u_t).

Every model maps an initial state and an input sequence to the state trajectory:

    forward(x0 (B, 12), U (B, T, 6)) -> X (B, T + 1, 12), X[:, 0] = x0

with x = [q, qd] (rad, rad/s), u = qdd (rad/s^2) and a control period dt (default 0.01 s).

    nssm    eq. (2): x_(t+1) = f1(x_t) + f2(u_t)                       learned
    node1   eq. (3): dx/dt = f1(x, u), one RK4 step per period,        learned
            gradients by the adjoint method (`mca_drake.learning.ode_adjoint`)
    node2   eq. (4): dx/dt = [qd, u], forward Euler, no parameters     exact ODE, Euler error
    exact   the exact zero-order-hold discretisation of the plant:     no error
            q+ = q + dt qd + dt^2/2 u, qd+ = qd + dt u

NODE 2 integrates the true ODE with forward Euler, as the paper did, so it drifts from the
exact discretisation by dt^2/2 u per step (about 0.004 rad RMS over 2.56 s of typical
motion: the paper's Table II figure). The exact model removes that error for free.
"""

from __future__ import annotations

import torch
from torch import nn

from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.learning.blocks import Mlp
from mca_drake.learning.ode_adjoint import odeint_step
from mca_drake.learning.torch_plant import integrate_double_integrator
from mca_drake.platforms.serial import NUM_JOINTS

STATE_SIZE, INPUT_SIZE = 2 * NUM_JOINTS, NUM_JOINTS


def _check(x0: torch.Tensor, U: torch.Tensor) -> None:
    if x0.ndim != 2 or x0.shape[-1] != STATE_SIZE:
        raise ValueError(f"x0 must have shape (B, {STATE_SIZE}); got {tuple(x0.shape)}")
    if U.ndim != 3 or U.shape[-1] != INPUT_SIZE or U.shape[0] != x0.shape[0]:
        raise ValueError(
            f"U must have shape (B, T, {INPUT_SIZE}) with B = {x0.shape[0]}; got {tuple(U.shape)}"
        )


class StateModel(nn.Module):
    """Base: a recurrent state-transition model (see the module docstring for shapes)."""

    learnable = True

    def __init__(self, dt: float = CONTROL_PERIOD_S):
        super().__init__()
        if not dt > 0:
            raise ValueError(f"dt must be positive; got {dt}")
        self.dt = float(dt)

    def step(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """x (B, 12), u (B, 6) -> x_next (B, 12)."""
        raise NotImplementedError

    def forward(self, x0: torch.Tensor, U: torch.Tensor) -> torch.Tensor:
        _check(x0, U)
        states = [x0]
        for t in range(U.shape[1]):
            states.append(self.step(states[-1], U[:, t]))
        return torch.stack(states, dim=1)


class NssmState(StateModel):
    """Equation (2): x_(t+1) = f1(x_t) + f2(u_t), f1 and f2 two-layer GELU networks."""

    def __init__(self, dt: float = CONTROL_PERIOD_S, hidden: int = 64):
        super().__init__(dt)
        self.f1 = Mlp(STATE_SIZE, STATE_SIZE, hidden)
        self.f2 = Mlp(INPUT_SIZE, STATE_SIZE, hidden)

    def step(self, x, u):
        return self.f1(x) + self.f2(u)


class _Derivative(nn.Module):
    def __init__(self, hidden: int):
        super().__init__()
        self.f1 = Mlp(STATE_SIZE + INPUT_SIZE, STATE_SIZE, hidden)

    def forward(self, x, u):
        return self.f1(torch.cat([x, u], dim=-1))


class Node1State(StateModel):
    """Equation (3): dx/dt = f1(x, u), integrated by RK4 over each period, u held.

    Args:
        adjoint: gradients by the adjoint method (the paper's choice, constant memory);
            False backpropagates through the solver (faster on small problems).
    """

    def __init__(self, dt: float = CONTROL_PERIOD_S, hidden: int = 64, adjoint: bool = True):
        super().__init__(dt)
        self.derivative = _Derivative(hidden)
        self.adjoint = adjoint

    def step(self, x, u):
        return odeint_step(self.derivative, x, u, self.dt, adjoint=self.adjoint)


class Node2State(StateModel):
    """Equation (4): dx/dt = I(x, u) = [qd, u], forward Euler; no parameters.

    Closed form (no loop): qd_t = qd_0 + dt sum_(k<t) u_k, q_t = q_0 + dt sum_(k<t) qd_k.
    """

    learnable = False

    def step(self, x, u):
        q, qd = x[..., :NUM_JOINTS], x[..., NUM_JOINTS:]
        return torch.cat([q + self.dt * qd, qd + self.dt * u], dim=-1)

    def forward(self, x0, U):
        _check(x0, U)
        return integrate_double_integrator(x0, U, self.dt, exact=False)


class ExactState(StateModel):
    """The exact zero-order-hold discretisation of the double integrator (no error)."""

    learnable = False

    def step(self, x, u):
        q, qd = x[..., :NUM_JOINTS], x[..., NUM_JOINTS:]
        dt = self.dt
        return torch.cat([q + dt * qd + (0.5 * dt * dt) * u, qd + dt * u], dim=-1)

    def forward(self, x0, U):
        _check(x0, U)
        return integrate_double_integrator(x0, U, self.dt, exact=True)


STATE_MODELS: dict[str, type[StateModel]] = {
    "nssm": NssmState,
    "node1": Node1State,
    "node2": Node2State,
    "exact": ExactState,
}
