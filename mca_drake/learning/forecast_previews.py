"""The forecast a predictive DPC policy reads, computed once per training dataset.

A policy trained to read a forecast as its preview (`DpcTrainingConfig.preview_predictor`)
must see in training what it will see live: at each control period the forecast of the
reference at its `preview_offsets`, made by the predictor from the history of that flight
as the `ReferencePredictor` system makes it beside the MCA (at a flight's start, or after
a gap in its segments, the history is the first sample held, as at rest). The forecast
depends on the reference alone, never on the policy, so it is computed once for every
segment of a dataset (`forecast_preview_array`) and cut into windows with the other arrays.
"""

from __future__ import annotations

import numpy as np

from mca_drake.cueing.dpc import preview_offsets
from mca_drake.cueing.learned_predictor import load_forecast_model
from mca_drake.segments import SegmentDataset, consecutive_runs

# The dataset array that holds the forecast previews (`forecast_preview_array`).
FORECAST_PREVIEW_ARRAY = "P"
# Samples forecast per batch: bounds the memory of the histories (H samples each).
_CHUNK = 2048


def flight_forecast_previews(y: np.ndarray, model, offsets) -> np.ndarray:
    """What a policy reading `model`'s forecast at `offsets` (samples ahead, each at most
    the model's `steps`) sees at every sample of one run of a reference y (T, 6): shape
    (T, 6 len(offsets)), the forecast at each offset, offset after offset, from the
    history up to and including that sample (the first sample held before it)."""
    y = np.asarray(y, dtype=float)
    offsets = np.asarray(offsets, dtype=int)
    if offsets.max() > model.steps or offsets.min() < 1:
        raise ValueError(f"offsets must lie in 1..{model.steps}; got {offsets.tolist()}")
    history = model.history
    padded = np.concatenate([np.repeat(y[:1], history - 1, axis=0), y])
    out = np.empty((y.shape[0], offsets.size * y.shape[1]))
    back = np.arange(history)
    for start in range(0, y.shape[0], _CHUNK):
        rows = np.arange(start, min(start + _CHUNK, y.shape[0]))
        histories = padded[rows[:, None] + back[None, :]]  # (M, H, 6), current sample last
        forecast = model.forecast(histories, int(offsets.max()))
        out[rows] = forecast[:, offsets - 1].reshape(rows.size, -1)
    return out


def forecast_preview_array(
    data: SegmentDataset, key: str, predictor: str, preview_steps: int
) -> np.ndarray:
    """The forecast previews of every segment of `data` (N, n_p, 6 PREVIEW_POINTS),
    aligned with its arrays: each run of consecutive segments of a flight
    (`segments.consecutive_runs`) forecast from its targets `key` ("R" or "Y") by the
    predictor `predictor` ("linear", "learned" or a model file) at the preview offsets of
    `preview_steps`, float32."""
    model = load_forecast_model(predictor)
    offsets = preview_offsets(preview_steps)
    targets = data.arrays[key]
    n_p = data.horizon
    out = np.empty((*targets.shape[:2], 6 * offsets.size), dtype=np.float32)
    for run in consecutive_runs(data):
        joined = targets[run].reshape(-1, targets.shape[-1])
        previews = flight_forecast_previews(joined, model, offsets)
        out[run] = previews.reshape(len(run), n_p, -1)
    return out
