"""The learned reference forecast: the linear one, corrected by a small network.

`LearnedPredictor` forecasts as its `LinearPredictor` does and adds what a network reads
from a longer history: the changes of every channel from the current sample at `lags`
(back to 2 s, where a turn's or a braking's shape shows) and the current levels,
standardized, through two tanh layers to the correction at a few knots of the horizon,
interpolated linearly between them (the forecast is smooth in time, and the network's last
layer stays small). Trained in torch (`mca_drake.learning.predictor_training`), it runs here
in numpy: a forecast is three small products, what a live control step can afford.

The file is an npz of plain arrays (`save_learned_predictor`; nothing that executes): the
network's, and the linear predictor's under a `linear_` prefix.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_npz, load_npz_with_metadata
from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.cueing.predictor import (
    NUM_CHANNELS,
    PREDICTOR_FORMAT,
    LinearPredictor,
    history_samples,
    lag_features,
    load_linear_predictor,
    predictor_file,
)
from mca_drake.references.vehicle_signals import SIGNALS

LEARNED_FORMAT = "mca-drake-learned-predictor-1"
# The lags the network reads: the linear model's and more, back to 2 s.
LEARNED_LAGS = (1, 2, 3, 5, 8, 12, 20, 30, 50, 75, 100, 150, 200)
# The controls and vehicle state a learned forecast may read where its source carries them
# (`references.vehicle_signals`): what the pilot or driver commands comes before the motion
# it causes; the speed and attitude say what motion is possible.
PREDICTOR_SIGNALS = (
    "aileron",
    "elevator",
    "rudder",
    "throttle",
    "brake",
    "steering",
    "speed",
    "roll",
    "pitch",
)
# The lags (control periods) at which it reads each signal's change from its current value.
SIGNAL_LAGS = (5, 20, 50)


def signal_features(signals: np.ndarray, lags) -> tuple[np.ndarray, np.ndarray]:
    """(values (..., S (len(lags) + 1)), present (..., S)) of signal histories (..., H, S),
    the current sample last, NaN where absent: each signal's current value, then its
    changes from it at each of `lags`; a signal is present where all of those are finite."""
    now = signals[..., -1, :]
    changes = [signals[..., -1 - lag, :] - now for lag in lags]
    values = np.concatenate([now, *changes], axis=-1)
    width = signals.shape[-1]
    finite = np.isfinite(values).reshape(*values.shape[:-1], len(lags) + 1, width)
    return values, finite.all(axis=-2)


def network_inputs(
    motion: np.ndarray, mean, scale, values=None, present=None, signal_mean=None, signal_scale=None
) -> np.ndarray:
    """The network's input: the standardized motion features (..., F), then, for a forecast
    that reads signals, their standardized `values` (..., S (L + 1)) with an absent
    signal's at zero (its mean) and the presence flags (..., S) (`signal_features`)."""
    x = (motion - mean) / scale
    if values is None:
        return x
    repeat = values.shape[-1] // present.shape[-1]
    mask = np.tile(present, repeat)
    standardized = np.where(mask, (np.nan_to_num(values) - signal_mean) / signal_scale, 0.0)
    return np.concatenate([x, standardized, present.astype(float)], axis=-1)


def knot_basis(knots, steps: int) -> np.ndarray:
    """(steps, K): row k - 1 interpolates linearly the values at the `knots` (forecast steps
    1 <= knot <= steps, increasing, the first 1 and the last `steps`) at step k."""
    knots = np.asarray(knots, dtype=float)
    if knots[0] != 1 or knots[-1] != steps or np.any(np.diff(knots) <= 0):
        raise ValueError(f"knots must rise from 1 to {steps}; got {knots.tolist()}")
    basis = np.zeros((steps, knots.size))
    for column in range(knots.size):
        unit = np.zeros(knots.size)
        unit[column] = 1.0
        basis[:, column] = np.interp(np.arange(1, steps + 1), knots, unit)
    return basis


def default_knots(steps: int) -> tuple[int, ...]:
    """Knots dense near now, where the forecast changes fastest: 1, 2, 4, ... doubling, then
    every 32 steps, and `steps`."""
    knots = [k for k in (1, 2, 4, 8, 16, 32) if k < steps]
    knots += list(range(64, steps, 32))
    return (*knots, steps)


@dataclasses.dataclass
class LearnedPredictor:
    """A linear forecast plus a network's correction (module docstring).

    Attributes:
        linear: the forecast it corrects; its `steps` is this predictor's.
        lags: control periods before the current sample whose change from it the network
            reads.
        mean, scale: the network's feature standardization, shapes (F,), F = 6 (len(lags) + 1).
        layers: [(W (F, h), b (h,)), (W (h, h), b (h,)), (W (h, 6 K), b (6 K,))]: tanh after
            the first two.
        knots: the K forecast steps the network's output sits at (`knot_basis`).
        output_scale: (6,): the output's unit per channel (a correction of 1 is that much).
        metadata: where it came from (training references, epochs, date), JSON-ready.
        signals: the controls and state it reads where given (`PREDICTOR_SIGNALS` names;
            empty: the motion alone), each at `signal_lags`.
        signal_lags: control periods before the current sample at which it reads each
            signal's change.
        signal_mean, signal_scale: the signal features' standardization,
            (S (len(signal_lags) + 1),) each (`signal_features`).
    """

    linear: LinearPredictor
    lags: tuple[int, ...]
    mean: np.ndarray
    scale: np.ndarray
    layers: list
    knots: tuple[int, ...]
    output_scale: np.ndarray
    metadata: dict = dataclasses.field(default_factory=dict)
    signals: tuple[str, ...] = ()
    signal_lags: tuple[int, ...] = ()
    signal_mean: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    signal_scale: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        self.lags = tuple(int(v) for v in self.lags)
        self.knots = tuple(int(v) for v in self.knots)
        self.mean = np.asarray(self.mean, dtype=float)
        self.scale = np.asarray(self.scale, dtype=float)
        self.output_scale = np.asarray(self.output_scale, dtype=float)
        self.layers = [(np.asarray(w, float), np.asarray(b, float)) for w, b in self.layers]
        self.signals = tuple(str(v) for v in self.signals)
        self.signal_lags = tuple(int(v) for v in self.signal_lags)
        self.signal_mean = np.asarray(self.signal_mean, dtype=float)
        self.signal_scale = np.asarray(self.signal_scale, dtype=float)
        features = NUM_CHANNELS * (len(self.lags) + 1)
        if not self.lags or min(self.lags) < 1:
            raise ValueError(f"lags must be positive control periods; got {self.lags}")
        if self.mean.shape != (features,) or self.scale.shape != (features,):
            raise ValueError(f"mean and scale must be {features} numbers each")
        if not np.all(self.scale > 0) or self.output_scale.shape != (NUM_CHANNELS,):
            raise ValueError("scale must be positive and output_scale 6 numbers")
        unknown = [name for name in self.signals if name not in SIGNALS]
        if unknown or len(set(self.signals)) != len(self.signals):
            raise ValueError(f"signals must be distinct names of {', '.join(SIGNALS)}")
        if self.signals and (not self.signal_lags or min(self.signal_lags) < 1):
            raise ValueError(
                f"signal_lags must be positive control periods; got {self.signal_lags}"
            )
        signal_width = len(self.signals) * (len(self.signal_lags) + 1)
        if self.signal_mean.shape != (signal_width,) or self.signal_scale.shape != (signal_width,):
            raise ValueError(f"signal_mean and signal_scale must be {signal_width} numbers each")
        if not np.all(self.signal_scale > 0):
            raise ValueError("signal_scale must be positive")
        features += signal_width + len(self.signals)  # the values and the presence flags
        widths = [features] + [b.size for _, b in self.layers]
        if len(self.layers) != 3 or any(
            w.shape != (a, c)
            for (w, _), a, c in zip(self.layers, widths[:-1], widths[1:], strict=True)
        ):
            raise ValueError(f"layers must be three (W, b) pairs chained from {features} inputs")
        if widths[-1] != NUM_CHANNELS * len(self.knots):
            raise ValueError(f"the last layer must give 6 x {len(self.knots)} knot values")
        arrays = [self.mean, self.scale, self.output_scale, *(a for p in self.layers for a in p)]
        arrays += [self.signal_mean, self.signal_scale]
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise ValueError("a learned predictor's arrays must be finite")
        self._basis = knot_basis(self.knots, self.steps)

    @property
    def steps(self) -> int:
        """N, the samples it forecasts."""
        return self.linear.steps

    @property
    def time_step(self) -> float:
        """The control period it was trained at, s."""
        return self.linear.time_step

    @property
    def history(self) -> int:
        """Samples of history it reads, the current one included."""
        return max(history_samples(self.lags), self.linear.history)

    @property
    def signal_history(self) -> int:
        """Samples of signal history it reads, the current one included (0: none)."""
        return history_samples(self.signal_lags) if self.signals else 0

    def correction(self, history: np.ndarray, signals: np.ndarray | None = None) -> np.ndarray:
        """The network's correction to the linear forecast of histories (..., H, 6), and,
        for a forecast that reads signals, of their histories `signals` (..., H_s, S) in
        the order of `self.signals`, NaN where absent (None: all absent): (..., N, 6)."""
        motion = lag_features(history, self.lags)
        if self.signals:
            if signals is None:
                shape = (*history.shape[:-2], self.signal_history, len(self.signals))
                signals = np.full(shape, np.nan)
            values, present = signal_features(np.asarray(signals, float), self.signal_lags)
            x = network_inputs(
                motion, self.mean, self.scale, values, present, self.signal_mean, self.signal_scale
            )
        else:
            x = network_inputs(motion, self.mean, self.scale)
        (w1, b1), (w2, b2), (w3, b3) = self.layers
        out = np.tanh(np.tanh(x @ w1 + b1) @ w2 + b2) @ w3 + b3
        at_knots = out.reshape(*out.shape[:-1], len(self.knots), NUM_CHANNELS)
        return np.einsum("nk,...kc->...nc", self._basis, at_knots) * self.output_scale

    def forecast(
        self, history: np.ndarray, steps: int | None = None, signals: np.ndarray | None = None
    ) -> np.ndarray:
        """The next `steps` samples (default and at most N) after histories (..., H, 6),
        reading the signal histories `signals` (`correction`) where given: (..., steps, 6)."""
        steps = self.steps if steps is None else steps
        history = np.asarray(history, dtype=float)
        linear = self.linear.forecast(history, steps)
        return linear + self.correction(history, signals)[..., :steps, :]


def save_learned_predictor(path: str | Path, predictor: LearnedPredictor) -> Path:
    """Writes `predictor` as an npz of plain arrays with its metadata, atomically."""
    linear = predictor.linear
    metadata = {
        **predictor.metadata,
        "format": LEARNED_FORMAT,
        "linear_metadata": linear.metadata,
    }
    arrays = {
        "lags": np.asarray(predictor.lags),
        "mean": predictor.mean,
        "scale": predictor.scale,
        "knots": np.asarray(predictor.knots),
        "output_scale": predictor.output_scale,
        "linear_lags": np.asarray(linear.lags),
        "linear_steps": np.asarray(linear.steps),
        "linear_scale": linear.scale,
        "linear_weights": linear.weights,
        "linear_time_step": np.asarray(linear.time_step),
        "metadata_json": np.array(json.dumps(metadata)),
    }
    if predictor.signals:  # the signal part (a motion-only file has none)
        arrays |= {
            "signals": np.array(predictor.signals),
            "signal_lags": np.asarray(predictor.signal_lags),
            "signal_mean": predictor.signal_mean,
            "signal_scale": predictor.signal_scale,
        }
    for i, (w, b) in enumerate(predictor.layers):
        arrays[f"w{i}"], arrays[f"b{i}"] = w, b
    return atomic_write_npz(path, arrays)


def load_learned_predictor(path: str | Path) -> LearnedPredictor:
    """A predictor written by `save_learned_predictor` (no pickle: plain arrays only).

    Raises:
        FileNotFoundError: no such file. ValueError: not a learned predictor's file, or
            arrays that do not fit together.
    """
    names = ("lags", "mean", "scale", "knots", "output_scale", "w0", "b0", "w1", "b1", "w2")
    names += ("b2", "linear_lags", "linear_steps", "linear_scale", "linear_weights")
    optional = ("linear_time_step", "signals", "signal_lags", "signal_mean", "signal_scale")
    arrays, metadata = load_npz_with_metadata(
        path, "learned predictor", names=frozenset((*names, *optional))
    )
    if metadata.get("format") != LEARNED_FORMAT:
        raise ValueError(
            f"{path} is not a learned predictor file: format {metadata.get('format')!r}"
        )
    try:
        linear = LinearPredictor(
            lags=tuple(int(v) for v in arrays["linear_lags"]),
            steps=int(arrays["linear_steps"]),
            scale=arrays["linear_scale"],
            weights=arrays["linear_weights"],
            time_step=float(arrays.get("linear_time_step", CONTROL_PERIOD_S)),
            metadata=metadata.pop("linear_metadata", {}),
        )
        return LearnedPredictor(
            linear=linear,
            lags=tuple(int(v) for v in arrays["lags"]),
            mean=arrays["mean"],
            scale=arrays["scale"],
            layers=[(arrays[f"w{i}"], arrays[f"b{i}"]) for i in range(3)],
            knots=tuple(int(v) for v in arrays["knots"]),
            output_scale=arrays["output_scale"],
            metadata=metadata,
            signals=tuple(str(v) for v in arrays.get("signals", ())),
            signal_lags=tuple(int(v) for v in arrays.get("signal_lags", ())),
            signal_mean=arrays.get("signal_mean", np.zeros(0)),
            signal_scale=arrays.get("signal_scale", np.zeros(0)),
        )
    except KeyError as missing:
        raise ValueError(f"{path} is not a learned predictor file: no {missing}") from None


def load_forecast_model(kind: str) -> LinearPredictor | LearnedPredictor:
    """The model of a predictor setting other than "constant": "linear", "learned" (the
    packaged ones) or an .npz file of either kind, told apart by its format.

    Raises:
        FileNotFoundError: no such file. ValueError: a file of neither format.
    """
    path = predictor_file(kind)
    _, metadata = load_npz_with_metadata(path, "predictor")
    if metadata.get("format") == PREDICTOR_FORMAT:
        return load_linear_predictor(path)
    return load_learned_predictor(path)
