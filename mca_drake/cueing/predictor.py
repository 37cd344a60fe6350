"""Reference forecasts: the motion to come, from the motion so far.

A predictive MCA reads a forecast of the reference over its horizon where a preview MCA
reads the recorded future. A predictor maps the reference's recent history, sampled at the
control period up to and including the current sample, to the next N samples:

- "constant": the current sample held over the horizon, what a causal NMPC assumes;
- "linear": a linear model fitted on training flights and drives (`fit_linear_predictor`).
  Per forecast step and channel, the change from the current sample is a linear function of
  the history's changes from it at a few lags and of the current levels of every channel
  (forces return to level flight, turns end): ridge least squares on standardized
  features, stored as an npz of arrays (`save_linear_predictor`; nothing that executes);
- "learned": the linear forecast corrected by a small network trained in torch on the same
  references (`mca_drake.cueing.learned_predictor`).

A forecast never reads past the current sample: the history is all it has.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_npz, load_npz_with_metadata
from mca_drake.conventions import CHANNELS, CONTROL_PERIOD_S
from mca_drake.references.vehicle_signals import signal_matrix
from mca_drake.resources import data_dir

PREDICTOR_KINDS = ("constant", "linear", "learned")
# The packaged models (`benchmarks/bench_predictor.py` fits, trains and measures them).
PACKAGED_LINEAR_PREDICTOR = "linear_predictor.npz"
PACKAGED_LEARNED_PREDICTOR = "learned_predictor.npz"
NUM_CHANNELS = len(CHANNELS)
# The lags (control periods before the current sample) the linear model reads: dense near
# now, where the trend is, sparser back to 0.5 s.
DEFAULT_LAGS = (1, 2, 3, 5, 8, 12, 20, 30, 50)
PREDICTOR_FORMAT = "mca-drake-linear-predictor-1"


def predictor_file(kind: str) -> Path:
    """The model file of a predictor setting: the packaged one for "linear" or "learned",
    else `kind` as a path to an .npz (`save_linear_predictor`, `save_learned_predictor`)."""
    if kind == "linear":
        return data_dir() / PACKAGED_LINEAR_PREDICTOR
    if kind == "learned":
        return data_dir() / PACKAGED_LEARNED_PREDICTOR
    return Path(kind)


def check_predictor(kind: str) -> None:
    """Raises ValueError unless `kind` is "", a kind of PREDICTOR_KINDS or an .npz file."""
    if kind in ("", *PREDICTOR_KINDS):
        return
    if not kind.endswith(".npz"):
        raise ValueError(
            f"unknown predictor '{kind}'; valid: {', '.join(PREDICTOR_KINDS)} or a model "
            "file (.npz)"
        )
    if not Path(kind).is_file():
        raise ValueError(f"predictor model file {kind!r} not found")


def history_samples(lags=DEFAULT_LAGS) -> int:
    """Samples of history a predictor with these lags reads, the current one included."""
    return int(max(lags)) + 1


def lag_features(history: np.ndarray, lags) -> np.ndarray:
    """The features a forecast reads from histories (..., H, 6), the current sample last:
    every channel's change from it at each of `lags` (control periods back), then its
    levels: (..., 6 (len(lags) + 1))."""
    now = history[..., -1, :]
    changes = [history[..., -1 - lag, :] - now for lag in lags]
    return np.concatenate([*changes, now], axis=-1)


@dataclasses.dataclass
class LinearPredictor:
    """A fitted linear forecast (module docstring).

    Attributes:
        lags: control periods before the current sample whose change from it is a feature.
        steps: forecast length N, control periods.
        scale: each feature's training standard deviation, shape (F,), F = 6 (len(lags) + 1).
        weights: shape (F, N, 6): the forecast's change from the current sample at step
            k + 1 in channel c is features / scale @ weights[:, k, c].
        time_step: the control period it was fitted at, s.
        metadata: where it came from (flights, ridge, date), JSON-ready.
    """

    lags: tuple[int, ...]
    steps: int
    scale: np.ndarray
    weights: np.ndarray
    time_step: float = CONTROL_PERIOD_S
    metadata: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        self.lags = tuple(int(v) for v in self.lags)
        self.scale = np.asarray(self.scale, dtype=float)
        self.weights = np.asarray(self.weights, dtype=float)
        features = NUM_CHANNELS * (len(self.lags) + 1)
        if min(self.lags, default=0) < 1 or not self.lags:
            raise ValueError(f"lags must be positive control periods; got {self.lags}")
        if self.scale.shape != (features,) or not np.all(self.scale > 0):
            raise ValueError(f"scale must be {features} positive numbers")
        if self.weights.shape != (features, self.steps, NUM_CHANNELS):
            raise ValueError(
                f"weights must have shape ({features}, {self.steps}, 6); got {self.weights.shape}"
            )
        if not (np.all(np.isfinite(self.weights)) and np.all(np.isfinite(self.scale))):
            raise ValueError("a linear predictor's arrays must be finite")
        # folded once: the per-step forecast is one product
        self._matrix = (self.weights / self.scale[:, None, None]).reshape(features, -1)

    @property
    def history(self) -> int:
        """Samples of history it reads, the current one included."""
        return history_samples(self.lags)

    def features(self, history: np.ndarray) -> np.ndarray:
        """The features of histories (..., H, 6), oldest first, the current sample last
        (H >= `history`): (..., F)."""
        return lag_features(history, self.lags)

    def forecast(self, history: np.ndarray, steps: int | None = None) -> np.ndarray:
        """The next `steps` samples (default and at most `self.steps`) after histories
        (..., H, 6): (..., steps, 6)."""
        steps = self.steps if steps is None else steps
        if not 0 < steps <= self.steps:
            raise ValueError(f"this predictor forecasts 1 to {self.steps} steps; asked {steps}")
        history = np.asarray(history, dtype=float)
        change = (self.features(history) @ self._matrix).reshape(
            *history.shape[:-2], self.steps, NUM_CHANNELS
        )
        return history[..., -1:, :] + change[..., :steps, :]


def constant_forecast(history: np.ndarray, steps: int) -> np.ndarray:
    """The current sample (the last of `history`, (..., H, 6)) held for `steps` samples."""
    history = np.asarray(history, dtype=float)
    return np.repeat(history[..., -1:, :], steps, axis=-2)


def training_pairs(y: np.ndarray, lags, steps: int, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """(features (M, F), targets (M, steps, 6)) of one reference y (T, 6): at every
    `stride`-th sample with a full history and `steps` samples after it, the history's
    features and the changes of the next samples from the current one."""
    y = np.asarray(y, dtype=float)
    first = max(lags)
    ends = np.arange(first, y.shape[0] - steps, stride)
    if ends.size == 0:
        return np.empty((0, NUM_CHANNELS * (len(lags) + 1))), np.empty((0, steps, NUM_CHANNELS))
    now = y[ends]
    changes = [y[ends - lag] - now for lag in lags]
    features = np.concatenate([*changes, now], axis=1)
    future = y[ends[:, None] + np.arange(1, steps + 1)[None, :]]
    return features, future - now[:, None, :]


def fit_linear_predictor(
    references,
    steps: int,
    *,
    lags=DEFAULT_LAGS,
    ridge: float = 1e-2,
    stride: int = 5,
    time_step: float = CONTROL_PERIOD_S,
    metadata: dict | None = None,
) -> LinearPredictor:
    """The ridge least-squares linear predictor of `references` (arrays (T, 6) at
    `time_step`): one forecast of `steps` samples from every `stride`-th sample; `ridge`
    is the penalty on the standardized features' weights, relative to the sample count.
    The normal equations are summed reference by reference, so memory stays that of one."""
    references = [np.asarray(y, dtype=float) for y in references]
    features_of = [training_pairs(y, lags, 1, stride)[0] for y in references]
    count = sum(f.shape[0] for f in features_of)
    width = NUM_CHANNELS * (len(lags) + 1)
    if count < width:
        raise ValueError(
            f"{count} training samples for {width} features: give longer or more references"
        )
    stacked = np.concatenate(features_of)
    scale = stacked.std(axis=0)
    scale = np.where(scale > 1e-12, scale, 1.0)
    gram = np.zeros((width, width))
    moment = np.zeros((width, steps * NUM_CHANNELS))
    samples = 0
    for y in references:
        features, targets = training_pairs(y, lags, steps, stride)
        x = features / scale
        gram += x.T @ x
        moment += x.T @ targets.reshape(x.shape[0], -1)
        samples += x.shape[0]
    weights = np.linalg.solve(gram + ridge * samples * np.eye(width), moment)
    return LinearPredictor(
        lags=tuple(lags),
        steps=steps,
        scale=scale,
        weights=weights.reshape(width, steps, NUM_CHANNELS),
        time_step=time_step,
        metadata={**(metadata or {}), "samples": int(samples), "ridge": ridge},
    )


def forecast_errors(
    predict,
    references,
    horizons,
    *,
    stride: int = 10,
    history: int = 1,
    signals: tuple[str, ...] = (),
    signal_history: int = 1,
) -> np.ndarray:
    """RMS forecast error per horizon and channel, shape (len(horizons), 6): `predict`
    maps histories (M, H, 6) to forecasts (M, max(horizons), 6), scored at every
    `stride`-th sample of `references` (arrays y (T, 6), or references with `y` and
    `signals`) with `history` samples before it and the horizons after it against what
    came. With `signals` named, `predict` also reads their histories (M, signal_history,
    len(signals)), NaN for those a reference does not carry."""
    horizons = np.asarray(horizons, dtype=int)
    squared, count = np.zeros((horizons.size, NUM_CHANNELS)), 0
    first = max(history, signal_history if signals else 1) - 1
    lags = np.arange(history - 1, -1, -1)
    signal_lags = np.arange(signal_history - 1, -1, -1)
    for reference in references:
        y = np.asarray(getattr(reference, "y", reference), dtype=float)
        ends = np.arange(first, y.shape[0] - horizons.max(), stride)
        if ends.size == 0:
            continue
        if signals:
            matrix = signal_matrix(getattr(reference, "signals", {}), signals, y.shape[0])
            forecast = predict(
                y[ends[:, None] - lags[None, :]], matrix[ends[:, None] - signal_lags[None, :]]
            )
        else:
            forecast = predict(y[ends[:, None] - lags[None, :]])
        truth = y[ends[:, None] + horizons[None, :]]
        squared += ((forecast[:, horizons - 1] - truth) ** 2).sum(axis=0)
        count += ends.size
    return np.sqrt(squared / max(count, 1))


def save_linear_predictor(path: str | Path, predictor: LinearPredictor) -> Path:
    """Writes `predictor` as an npz of plain arrays with its metadata, atomically."""
    metadata = {**predictor.metadata, "format": PREDICTOR_FORMAT}
    return atomic_write_npz(
        path,
        {
            "lags": np.asarray(predictor.lags),
            "steps": np.asarray(predictor.steps),
            "scale": predictor.scale,
            "weights": predictor.weights,
            "time_step": np.asarray(predictor.time_step),
            "metadata_json": np.array(json.dumps(metadata)),
        },
    )


def load_linear_predictor(path: str | Path) -> LinearPredictor:
    """A predictor written by `save_linear_predictor` (no pickle: plain arrays only).

    Raises:
        FileNotFoundError: no such file. ValueError: not a linear predictor's file, or arrays
            that do not fit together.
    """
    arrays, metadata = load_npz_with_metadata(
        path,
        "linear predictor",
        names=frozenset(("lags", "steps", "scale", "weights", "time_step")),
    )
    if metadata.get("format") != PREDICTOR_FORMAT:
        raise ValueError(
            f"{path} is not a linear predictor file: format {metadata.get('format')!r}"
        )
    try:
        return LinearPredictor(
            lags=tuple(int(v) for v in arrays["lags"]),
            steps=int(arrays["steps"]),
            scale=arrays["scale"],
            weights=arrays["weights"],
            time_step=float(arrays["time_step"]),
            metadata=metadata,
        )
    except KeyError as missing:
        raise ValueError(f"{path} is not a linear predictor file: no {missing}") from None
