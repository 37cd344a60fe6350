"""Vestibular models as discrete linear filters at the control period, and `perceive`.

A transfer function is realised in state space (controllable canonical form) and
discretised exactly for an input held over each period (zero-order hold, the matrix
exponential of the augmented system): the discrete filter's output at t_n equals the
continuous model's response to the piecewise-constant input, to round-off, at any period
(the canal's 5 ms pole included). The six channels of y = [w_x, w_y, w_z, f_x, f_y, a_z] are
stacked block-diagonally: canals on the rates, otoliths on the specific forces and on the
vertical channel (a_z, the deviation of the vertical specific force from 1 g: the otolith
is linear, so the 1 g it carries at rest only adds a constant to both the vehicle's and the
simulator's perceived signal, which no tracking figure sees).

Conventions of `DiscreteFilter.run`: state x_n, input u_n, output y_n = C x_n + D u_n,
x_(n+1) = A x_n + B u_n; x_0 = 0 (the occupant at rest, adapted to 1 g) unless given.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg
import scipy.signal

from mca_drake.conventions import CHANNELS, CONTROL_PERIOD_S
from mca_drake.input_checks import as_float_array
from mca_drake.perception.models import PerceptionConfig, TransferFunction


@dataclasses.dataclass(frozen=True)
class DiscreteFilter:
    """x_(n+1) = A x_n + B u_n, y_n = C x_n + D u_n at a fixed period.

    Attributes:
        A: (n, n).
        B: (n, m).
        C: (p, n).
        D: (p, m).
        time_step: the period, s.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    time_step: float

    @property
    def num_states(self) -> int:
        """Dimension n of the state."""
        return self.A.shape[0]

    def run(self, inputs, state=None) -> tuple[np.ndarray, np.ndarray]:
        """The filter's outputs for inputs u_0..u_(T-1): (outputs (T, p), state x_T (n,)).

        Args:
            inputs: shape (T, m).
            state: x_0, shape (n,); default zeros.
        """
        u, states = self.trajectory(inputs, state)
        return states[:-1] @ self.C.T + u @ self.D.T, states[-1]

    def trajectory(self, inputs, state=None) -> tuple[np.ndarray, np.ndarray]:
        """(inputs as a float array (T, m), the states x_0..x_T (T + 1, n)) for inputs
        u_0..u_(T-1) from x_0 = `state` (default zeros)."""
        u = as_float_array("inputs", inputs, last_dim=self.B.shape[1])
        if u.ndim != 2:
            raise ValueError(f"inputs must have shape (T, {self.B.shape[1]}); got {u.shape}")
        x = np.zeros(self.num_states) if state is None else as_float_array("state", state)
        if x.shape != (self.num_states,):
            raise ValueError(f"state must have shape ({self.num_states},); got {x.shape}")
        states = np.empty((u.shape[0] + 1, self.num_states))
        A = self.A
        # u enters the state through B only: B u for all samples at once, then the recursion
        drive = u @ self.B.T
        states[0] = x
        for n in range(u.shape[0]):
            states[n + 1] = A @ states[n] + drive[n]
        return u, states

    def steps(self, durations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The filter over intervals of `durations` whole periods each (ints, shape (N,)):
        (Phi (N, n, n), Gamma (N, n, m)) with x_(k+1) = Phi_k x_k + Gamma_k u_k for u_k
        held over interval k (the NMPC's non-uniform grid)."""
        n, m = self.num_states, self.B.shape[1]
        Phi, Gamma = np.empty((len(durations), n, n)), np.empty((len(durations), n, m))
        for k, steps in enumerate(np.asarray(durations, dtype=int)):
            if steps < 1:
                raise ValueError(f"interval lengths must be whole periods >= 1; got {steps}")
            Ak = np.linalg.matrix_power(self.A, int(steps))
            # sum_{i < steps} A^i B: the held input's effect over the interval
            Gk, power = np.zeros((n, m)), np.eye(n)
            for _ in range(int(steps)):
                Gk += power @ self.B
                power = power @ self.A
            Phi[k], Gamma[k] = Ak, Gk
        return Phi, Gamma


def discretize(tf: TransferFunction, time_step: float) -> DiscreteFilter:
    """The exact zero-order-hold discretisation of a single-axis transfer function.

    Args:
        tf: the continuous model.
        time_step: the period, s (> 0).
    """
    if not time_step > 0:
        raise ValueError(f"time_step must be positive; got {time_step}")
    A, B, C, D = scipy.signal.tf2ss(tf.numerator, tf.denominator)
    n = A.shape[0]
    # exp([[A, B], [0, 0]] h) = [[Ad, Bd], [0, I]]: the state's and the held input's effect
    augmented = np.zeros((n + 1, n + 1))
    augmented[:n, :n], augmented[:n, n:] = A, B
    exponential = scipy.linalg.expm(augmented * time_step)
    return DiscreteFilter(exponential[:n, :n], exponential[:n, n:], C, D, float(time_step))


def stack(filters: list[DiscreteFilter]) -> DiscreteFilter:
    """Single-axis filters side by side: channel i of the input drives filter i only."""
    periods = {f.time_step for f in filters}
    if len(periods) != 1:
        raise ValueError(f"filters must share one period; got {sorted(periods)}")
    return DiscreteFilter(
        scipy.linalg.block_diag(*(f.A for f in filters)),
        scipy.linalg.block_diag(*(f.B for f in filters)),
        scipy.linalg.block_diag(*(f.C for f in filters)),
        scipy.linalg.block_diag(*(f.D for f in filters)),
        periods.pop(),
    )


def vestibular_filter(
    config: PerceptionConfig | None = None, time_step: float = CONTROL_PERIOD_S
) -> DiscreteFilter:
    """The vestibular model of `config` on the six channels of y (canals on w_x, w_y, w_z;
    otoliths on f_x, f_y, a_z): 6 inputs, 6 outputs, in the units of y.

    Args:
        config: the model (default PerceptionConfig(): Telban & Cardullo).
        time_step: the control period, s.
    """
    parameters = (config or PerceptionConfig()).parameters
    canal = discretize(parameters.canal, time_step)
    otolith = discretize(parameters.otolith, time_step)
    return stack([canal] * 3 + [otolith] * 3)


def perceive(
    signals, config: PerceptionConfig | None = None, time_step: float = CONTROL_PERIOD_S
) -> np.ndarray:
    """What the occupant perceives of y-like signals (T, 6) sampled at `time_step`, starting
    at rest: the vestibular model's outputs, shape (T, 6), in the units of y."""
    signals = as_float_array("signals", signals, last_dim=len(CHANNELS))
    return vestibular_filter(config, time_step).run(signals)[0]
