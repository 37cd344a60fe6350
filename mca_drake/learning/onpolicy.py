"""On-policy starts for DPC training: windows flown from the states the policy reaches itself.

DPC rollouts start from the NMPC's states in the dataset and last at most 10.24 s. In a 300 s
flight the policy meets states of its own that no rollout started from, and one that drives
into the joint limits there is never shown the way back: the steep-turn clamp trap of the
policies trained with the T37 (`benchmarks/results/dpc_mixed.md`, sessions 24-26).
`FlightStarts` flies the current policy, without gradients, over each training flight's whole
reference from the flight's first dataset state and keeps the states it reaches; a share of
each training batch then starts its window from the policy's own state at the window's time
rather than the NMPC's. This is DAgger's remedy for a learner's distribution shift (Ross,
Gordon and Bagnell, AISTATS 2011): learn from the states the learner visits.

The dataset's segments carry where they lie in their flight (`locate_flight_runs` adds the
arrays RUN and STEP), so a window cut into rollouts of any length knows its start's run and
step.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import torch

from mca_drake.segments import SOURCE_COLUMNS, SegmentDataset

# Arrays `locate_flight_runs` adds: each sample's run index and step within its run (float32,
# exact below 2**24 steps, as the trainer's tensors are float).
POSITION_ARRAYS = ("RUN", "STEP")

# cell(y (B, 6), x (B, 12), target (B, 6)) -> (u, x_hat, y_next, x_next): one closed-loop step
# (`mca_drake.learning.dpc.rollout_cell`).
Cell = Callable[..., tuple[torch.Tensor, ...]]


@dataclasses.dataclass
class FlightRuns:
    """The contiguous runs of a dataset's flights (a flight with a missing segment is two).

    Attributes:
        targets: (N, S, 6) each run's targets in time, padded past its end with its last sample.
        lengths: (N,) steps of each run.
        x0: (N, 12) the dataset's state at each run's first step [rad, rad/s].
        y0: (N, 6) the dataset's output there (as the windows' y_0).
    """

    targets: np.ndarray
    lengths: np.ndarray
    x0: np.ndarray
    y0: np.ndarray


def locate_flight_runs(data: SegmentDataset, target_name: str) -> tuple[SegmentDataset, FlightRuns]:
    """`data` with the arrays RUN and STEP (J, n_p) added (each sample's run index and step
    within the run), and the runs whose targets are `data.arrays[target_name]`.

    Raises:
        ValueError: if two segments share a flight seed and start step (two flights with one
            seed: their runs could not be told apart).
    """
    seeds = data.source[:, SOURCE_COLUMNS.index("flight_seed")]
    steps = data.source[:, SOURCE_COLUMNS.index("start_step")]
    n_p = data.horizon
    pairs = np.stack([seeds, steps], axis=1)
    if len(np.unique(pairs, axis=0)) != len(pairs):
        raise ValueError(
            "two segments share a flight seed and start step: on-policy starts need one flight "
            "per seed (join datasets flown with different seeds)"
        )
    run_of = np.empty(len(data), dtype=np.int64)
    offset = np.empty(len(data), dtype=np.int64)
    runs: list[list[int]] = []
    for flight in np.unique(seeds):
        rows = np.flatnonzero(seeds == flight)
        previous = None
        for row in rows[np.argsort(steps[rows])]:
            if previous is None or steps[row] != steps[previous] + n_p:
                runs.append([])  # a new flight, or a gap in this one
            run_of[row], offset[row] = len(runs) - 1, len(runs[-1])
            runs[-1].append(int(row))
            previous = row
    targets = data.arrays[target_name]
    lengths = np.array([len(rows) * n_p for rows in runs])
    padded = np.empty((len(runs), lengths.max(), targets.shape[-1]), dtype=np.float32)
    for n, rows in enumerate(runs):
        flown = targets[rows].reshape(-1, targets.shape[-1])
        padded[n, : len(flown)] = flown
        padded[n, len(flown) :] = flown[-1]
    first = [rows[0] for rows in runs]
    located = SegmentDataset(
        {
            **data.arrays,
            "RUN": np.repeat(run_of[:, None], n_p, axis=1).astype(np.float32),
            "STEP": (offset[:, None] * n_p + np.arange(n_p)).astype(np.float32),
        },
        data.source,
        data.metadata,
    )
    x0, y0 = data.arrays["X"][first, 0], data.arrays["Y"][first, 0]
    return located, FlightRuns(padded, lengths, x0, y0)


class FlightStarts:
    """The states a policy reaches when it flies each run of `runs` from the run's start.

    `refresh(cell)` flies them (no gradients; about 30 000 steps of all runs at once for
    300 s flights); `due()` says when the states are `refresh_batches` training batches old
    (or never flown); `starts(run, step)` gives the state and the last output the policy had
    there.
    """

    def __init__(self, runs: FlightRuns, refresh_batches: int):
        if refresh_batches < 1:
            raise ValueError(f"refresh_batches must be at least 1; got {refresh_batches}")
        self.runs = runs
        self.refresh_batches = refresh_batches
        self.batches_since_refresh: int | None = None
        self.x: torch.Tensor | None = None  # (N, S, 12) state before each step
        self.y: torch.Tensor | None = None  # (N, S, 6) the output the policy sees there

    def due(self) -> bool:
        """True when the states were never flown or are `refresh_batches` batches old."""
        return self.batches_since_refresh is None or (
            self.batches_since_refresh >= self.refresh_batches
        )

    def refresh(self, cell: Cell) -> None:
        """Flies every run from its dataset start through `cell` (the current policy behind
        the clamp and the plant) and keeps the states and last outputs at every step."""
        targets = torch.as_tensor(self.runs.targets)
        x = torch.as_tensor(self.runs.x0, dtype=targets.dtype)
        y = torch.as_tensor(self.runs.y0, dtype=targets.dtype)
        xs, ys = [], []
        with torch.no_grad():
            for t in range(targets.shape[1]):
                xs.append(x)
                ys.append(y)
                _, _, y, x = cell(y, x, targets[:, t])
        self.x, self.y = torch.stack(xs, dim=1), torch.stack(ys, dim=1)
        if not (torch.isfinite(self.x).all() and torch.isfinite(self.y).all()):
            raise ValueError("the policy's own flights hold NaN or inf states")
        self.batches_since_refresh = 0

    def count_batch(self) -> None:
        """Records one training batch since the last refresh."""
        self.batches_since_refresh = (self.batches_since_refresh or 0) + 1

    def starts(self, run: torch.Tensor, step: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(x (B, 12), y (B, 6)): the policy's state and last output at step `step` (B,) of run
        `run` (B,) (float or int indices, as the batch's RUN and STEP give them)."""
        if self.x is None or self.y is None:
            raise RuntimeError("FlightStarts.refresh must run before starts")
        run, step = run.long().cpu(), step.long().cpu()
        return self.x[run, step], self.y[run, step]


def start_some_on_policy(
    x0: torch.Tensor,
    y0: torch.Tensor,
    own_x: torch.Tensor,
    own_y: torch.Tensor,
    fraction: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """(x0 (B, 12), y0 (B, 6)) with a random `fraction` of the rows replaced by the policy's
    own state and last output (`own_x`, `own_y`) at the window's start (torch's global
    generator; see `DpcTrainingConfig.onpolicy_fraction`)."""
    chosen = torch.rand(x0.shape[0], 1, device=x0.device) < fraction
    return (
        torch.where(chosen, own_x.to(x0), x0),
        torch.where(chosen, own_y.to(y0), y0),
    )
