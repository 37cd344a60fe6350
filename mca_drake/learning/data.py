"""Segment datasets as torch tensors, re-cut to the curriculum's horizons.

A `SegmentDataset` (`mca_drake.segments`) holds J segments of n_p steps. Training on a
shorter horizon n cuts every segment into n_p // n non-overlapping pieces, so each
curriculum step sees all the data (the paper segments its long simulations per n_p; cutting
the n_p = 256 segments gives the same pieces up to where the cuts fall).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from mca_drake.segments import SegmentDataset

TRAINING_ARRAYS = ("U", "X", "Y", "dF", "ddF")


@dataclasses.dataclass
class SegmentTensors:
    """Tensors of one dataset at one horizon: name -> (J, n, ...) (see `TRAINING_ARRAYS`)."""

    arrays: dict[str, torch.Tensor]

    def __len__(self) -> int:
        return self.arrays["U"].shape[0]

    @property
    def horizon(self) -> int:
        """Steps per segment (the rollout length n_c)."""
        return self.arrays["U"].shape[1]

    def batch(self, index: torch.Tensor) -> dict[str, torch.Tensor]:
        """The segments at `index` (a 1-D integer tensor)."""
        return {k: v[index] for k, v in self.arrays.items()}

    def batches(self, batch_size: int, generator: torch.Generator | None = None, shuffle=True):
        """Yields dicts of at most `batch_size` segments, shuffled with `generator`."""
        n = len(self)
        order = torch.randperm(n, generator=generator) if shuffle else torch.arange(n)
        for start in range(0, n, batch_size):
            yield self.batch(order[start : start + batch_size])


def to_tensors(
    dataset: SegmentDataset,
    horizon: int | None = None,
    dtype: torch.dtype = torch.float32,
    device: str | torch.device = "cpu",
    names: tuple[str, ...] = TRAINING_ARRAYS,
) -> SegmentTensors:
    """The arrays `names` of `dataset`, cut into `horizon`-long pieces (default: as is).

    Raises:
        ValueError: if the horizon does not divide into the dataset's, or data are not finite.
    """
    n_p = dataset.horizon
    horizon = n_p if horizon is None else int(horizon)
    if not 2 <= horizon <= n_p:
        raise ValueError(f"horizon must be in [2, {n_p}] for this dataset; got {horizon}")
    pieces = n_p // horizon
    arrays = {}
    for name in names:
        if name not in dataset.arrays:
            raise ValueError(f"dataset lacks array {name} (it has {', '.join(dataset.arrays)})")
        a = np.asarray(dataset.arrays[name])
        if not np.all(np.isfinite(a)):
            raise ValueError(f"dataset array {name} holds NaN or inf values")
        a = a[:, : pieces * horizon].reshape(len(dataset) * pieces, horizon, *a.shape[2:])
        arrays[name] = torch.as_tensor(a, dtype=dtype, device=device)
    return SegmentTensors(arrays)
