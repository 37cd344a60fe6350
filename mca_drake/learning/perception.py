"""The vestibular model in torch: differentiable perceived signals for training.

The same discrete filter as `mca_drake.perception.filters.vestibular_filter` (built from it,
so the two cannot drift apart), applied to a batch at once: the filter is linear and time-
invariant, so over T samples its output is the input convolved with its impulse response
(D, C B, C A B, ...) plus the free response C A^t x_0 of the initial state. Both are formed
as (T, T) and (T, n) matrices per length T (cached), which makes a whole rollout's perceived
signals one batched product instead of T sequential steps (up to MAX_CONVOLUTION_LENGTH
samples; longer ones are filtered step by step, which costs T n^2 instead of T^2).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.perception.filters import DiscreteFilter, vestibular_filter
from mca_drake.perception.models import PerceptionConfig

# Longer signals go through the step-by-step recursion: the convolution's operator takes
# T^2 values per channel (50 MB at 1024 samples) and T^2 products per batch row.
MAX_CONVOLUTION_LENGTH = 512


class TorchVestibularFilter(nn.Module):
    """Perceived signals of batches of y-like signals, differentiable.

    Args:
        config: the vestibular model (default PerceptionConfig()).
        time_step: the sample period, s.
        discrete: the discrete filter to use instead (any `DiscreteFilter`).
    """

    def __init__(
        self,
        config: PerceptionConfig | None = None,
        time_step: float = CONTROL_PERIOD_S,
        discrete: DiscreteFilter | None = None,
    ):
        super().__init__()
        self.discrete = discrete or vestibular_filter(config, time_step)
        self._operators: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._tensor_cache: dict[tuple, tuple[torch.Tensor, torch.Tensor]] = {}
        # a stack of single-axis filters (the vestibular model): each input drives its own
        # output only, so the convolution is per channel (p times fewer products)
        f = self.discrete
        self._channelwise = f.C.shape[0] == f.B.shape[1] and all(
            np.count_nonzero(M - np.diag(np.diag(M))) == 0 for M in (f.D, f.C @ _pattern(f.A) @ f.B)
        )

    @property
    def num_states(self) -> int:
        """Dimension n of the filter's state."""
        return self.discrete.num_states

    def _operator(self, length: int) -> tuple[np.ndarray, np.ndarray]:
        """(G, F (T, p, n)) for T = `length`: outputs[t] = sum_j G[t, j] u[j] + F[t] x_0, G
        lower block-triangular (G[t, j] = D for j = t, C A^(t-j-1) B before), of shape
        (T, T, p, m), or (T, T, m) holding the diagonals where the filter is channelwise."""
        if length not in self._operators:
            f = self.discrete
            p, m = f.C.shape[0], f.B.shape[1]
            markov = np.empty((length, p, m))  # h[i]: the response i samples after an impulse
            free = np.empty((length, p, f.num_states))
            power = np.eye(f.num_states)
            markov[0] = f.D
            for i in range(length):
                free[i] = f.C @ power
                if i + 1 < length:
                    markov[i + 1] = f.C @ power @ f.B
                power = f.A @ power
            lag = np.arange(length)[:, None] - np.arange(length)[None, :]
            if self._channelwise:  # p = m and channel i drives output i only: (T, T, m)
                markov = np.diagonal(markov, axis1=1, axis2=2)
                G = np.where((lag >= 0)[:, :, None], markov[np.clip(lag, 0, None)], 0.0)
            else:
                G = np.where((lag >= 0)[:, :, None, None], markov[np.clip(lag, 0, None)], 0.0)
            self._operators[length] = (G, free)
        return self._operators[length]

    def _tensors(self, length: int, dtype, device) -> tuple[torch.Tensor, torch.Tensor]:
        """`_operator(length)` as tensors of `dtype` on `device` (kept: a training step
        would otherwise copy megabytes each call)."""
        key = (length, dtype, str(device))
        if key not in self._tensor_cache:
            G, F = self._operator(length)
            self._tensor_cache[key] = tuple(
                torch.as_tensor(M, dtype=dtype, device=device) for M in (G, F)
            )
        return self._tensor_cache[key]

    def forward(self, signals: torch.Tensor, state: torch.Tensor | None = None) -> torch.Tensor:
        """Perceived signals (B, T, p) of `signals` (B, T, m) from states `state` (B, n)
        (default zeros: at rest)."""
        if signals.ndim != 3 or signals.shape[-1] != self.discrete.B.shape[1]:
            raise ValueError(
                f"signals must have shape (B, T, {self.discrete.B.shape[1]}); "
                f"got {tuple(signals.shape)}"
            )
        if signals.shape[1] > MAX_CONVOLUTION_LENGTH:
            return self._recursion(signals, state)
        G, F = self._tensors(signals.shape[1], signals.dtype, signals.device)
        pattern = "tjm,bjm->btm" if self._channelwise else "tjpm,bjm->btp"
        out = torch.einsum(pattern, G, signals)
        if state is not None:
            out = out + torch.einsum("tpn,bn->btp", F, state)
        return out

    def _recursion(self, signals: torch.Tensor, state: torch.Tensor | None) -> torch.Tensor:
        """The filter step by step, x_(t+1) = A x_t + B u_t, y_t = C x_t + D u_t: for long
        signals, where the convolution's (T, T) operator would cost T^2 per channel."""
        f = self.discrete
        A, B, C, D = (
            torch.as_tensor(M, dtype=signals.dtype, device=signals.device)
            for M in (f.A, f.B, f.C, f.D)
        )
        x = signals.new_zeros(signals.shape[0], f.num_states) if state is None else state
        drive = signals @ B.T
        states = []
        for t in range(signals.shape[1]):
            states.append(x)
            x = x @ A.T + drive[:, t]
        return torch.stack(states, dim=1) @ C.T + signals @ D.T


def _pattern(A: np.ndarray) -> np.ndarray:
    """1 where some power of A can be non-zero (the reachability of A's sparsity graph)."""
    reach = (np.abs(A) > 0).astype(float) + np.eye(A.shape[0])
    for _ in range(A.shape[0]):
        reach = np.minimum(reach @ reach, 1.0)
    return reach
