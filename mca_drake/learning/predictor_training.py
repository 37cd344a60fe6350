"""Training the learned reference forecast (`mca_drake.cueing.learned_predictor`) in torch.

The network learns what the linear forecast misses: its targets are the residuals of the
linear forecast on the training references, in units of each channel's residual spread
(each channel counts alike, as in the PI). Its last layer starts at zero, so training
starts from the linear forecast, and the epoch kept is the one that forecasts the
validation references best: a learned forecast is never worse there than the linear one
it corrects (when no epoch helps, the correction stays zero).

Where the references carry controls and vehicle state (`Reference.signals`), the network
also reads those of `LearnedPredictorConfig.signals` with presence flags. It must forecast
as well from what any source sends, from every signal to none: each training pair shows it
a random part of its reference's signals (`signal_keep`), and a share of the pairs none at
all (`signal_dropout`), and the epoch kept is the one with the least validation error
averaged over the pairs with all their signals and with none.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import torch

from mca_drake.cueing.learned_predictor import (
    LEARNED_LAGS,
    PREDICTOR_SIGNALS,
    SIGNAL_LAGS,
    LearnedPredictor,
    default_knots,
    knot_basis,
    signal_features,
)
from mca_drake.cueing.predictor import NUM_CHANNELS, LinearPredictor, lag_features
from mca_drake.references.vehicle_signals import signal_matrix


@dataclasses.dataclass
class LearnedPredictorConfig:
    """How the learned forecast is trained."""

    # the lags the network reads, control periods
    lags: tuple[int, ...] = LEARNED_LAGS
    # hidden units of each of its two layers
    hidden: int = 128
    # passes over the training pairs, at most
    epochs: int = 40
    # stop when the validation error has not improved for this many epochs
    patience: int = 8
    learning_rate: float = 1e-3
    # L2 penalty on the network's weights (AdamW's decoupled decay)
    weight_decay: float = 1e-4
    batch_size: int = 512
    # a training pair at every `stride`-th sample of each reference
    stride: int = 10
    # the forecast steps the loss reads (every `loss_stride`-th, and the last)
    loss_stride: int = 4
    seed: int = 0
    # the controls and state it reads where the references carry them (empty: motion only)
    signals: tuple[str, ...] = PREDICTOR_SIGNALS
    # the lags at which it reads each signal's change, control periods
    signal_lags: tuple[int, ...] = SIGNAL_LAGS
    # share of the training pairs shown none of their signals (a source that sends none)
    signal_dropout: float = 0.3
    # in the others, the chance each signal a reference carries is shown
    signal_keep: float = 0.7


def as_reference(item) -> tuple[np.ndarray, dict]:
    """(y (T, 6), signals {name: (T,)}) of a training or validation item: a `Reference`
    (its `signals`), a (y, signals) pair or an array y (no signals)."""
    if hasattr(item, "y"):
        return np.asarray(item.y, dtype=float), dict(getattr(item, "signals", {}))
    if isinstance(item, tuple):
        return np.asarray(item[0], dtype=float), dict(item[1])
    return np.asarray(item, dtype=float), {}


def forecast_pairs(
    y: np.ndarray,
    linear: LinearPredictor,
    lags,
    stride: int,
    read=None,
    signals: np.ndarray | None = None,
    signal_lags=(),
) -> tuple:
    """(raw features (M, F), residuals (M, S, 6)) of reference y (T, 6): at every
    `stride`-th sample with the longest history either model reads and N samples after it,
    the network's features and what came less the linear forecast, at the forecast steps
    `read` (0-based indices into the N; default all, S = N). Given `signals` (T, K; NaN
    where absent), also their raw values (M, K (L + 1)) and presence (M, K) at those
    samples (`learned_predictor.signal_features` at `signal_lags`)."""
    y = np.asarray(y, dtype=float)
    history = max(max(lags), linear.history - 1)
    steps = linear.steps
    read = np.arange(steps) if read is None else np.asarray(read)
    ends = np.arange(history, y.shape[0] - steps, stride)
    if ends.size == 0:
        width = NUM_CHANNELS * (len(lags) + 1)
        return np.empty((0, width)), np.empty((0, read.size, NUM_CHANNELS))
    windows = y[ends[:, None] + np.arange(-history, 1)[None, :]]
    future = y[ends[:, None] + 1 + read[None, :]]
    residuals = future - linear.forecast(windows)[:, read]
    if signals is None:
        return lag_features(windows, lags), residuals
    back = np.arange(-max(signal_lags), 1)
    values, present = signal_features(signals[ends[:, None] + back[None, :]], signal_lags)
    return lag_features(windows, lags), residuals, values, present


class _Network(torch.nn.Module):
    def __init__(self, inputs: int, hidden: int, outputs: int):
        super().__init__()
        self.hidden = torch.nn.Sequential(
            torch.nn.Linear(inputs, hidden),
            torch.nn.Tanh(),
            torch.nn.Linear(hidden, hidden),
            torch.nn.Tanh(),
        )
        self.out = torch.nn.Linear(hidden, outputs)
        torch.nn.init.zeros_(self.out.weight)  # starts as the linear forecast
        torch.nn.init.zeros_(self.out.bias)

    def forward(self, x):
        return self.out(self.hidden(x))


def train_learned_predictor(
    linear: LinearPredictor,
    training,
    validation,
    config: LearnedPredictorConfig | None = None,
    *,
    metadata: dict | None = None,
    progress=None,
) -> tuple[LearnedPredictor, dict]:
    """The learned forecast that corrects `linear`, trained on `training` references and
    kept at its best epoch on `validation` ones (each a `Reference`, a (y, signals) pair or
    an array y (T, 6), at the linear model's control period). Returns it and a report:
    per-epoch training and validation loss (mean squared residual in units of each
    channel's spread; the linear forecast's is the loss at epoch 0), the best epoch,
    seconds.

    `progress(epoch, train_loss, validation_loss)` is called after every epoch."""
    config = config or LearnedPredictorConfig()
    start = time.perf_counter()
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    knots = default_knots(linear.steps)
    read = np.unique(np.r_[np.arange(0, linear.steps, config.loss_stride), linear.steps - 1])
    names = tuple(config.signals)

    def pairs_of(items):
        found = []
        for item in items:
            y, signals = as_reference(item)
            matrix = signal_matrix(signals, names, y.shape[0]) if names else None
            found.append(
                forecast_pairs(
                    y, linear, config.lags, config.stride, read, matrix, config.signal_lags
                )
            )
        return [np.concatenate(part) for part in zip(*found, strict=True)]

    train_parts, valid_parts = pairs_of(training), pairs_of(validation)
    (x_train, r_train), x_valid = train_parts[:2], valid_parts[0]
    if x_train.shape[0] < 10 * x_train.shape[1] or x_valid.shape[0] == 0:
        raise ValueError(
            f"{x_train.shape[0]} training and {x_valid.shape[0]} validation samples: give "
            "longer or more references"
        )
    mean = x_train.mean(axis=0)
    scale = x_train.std(axis=0)
    scale = np.where(scale > 1e-12, scale, 1.0)
    output_scale = np.sqrt((r_train**2).mean(axis=(0, 1)))
    output_scale = np.where(output_scale > 1e-12, output_scale, 1.0)
    basis = torch.as_tensor(knot_basis(knots, linear.steps)[read], dtype=torch.float32)
    signal_mean, signal_scale = np.zeros(0), np.zeros(0)
    if names:  # each signal feature standardized over the samples that carry it
        values, present = train_parts[2], train_parts[3]
        mask = np.tile(present, len(config.signal_lags) + 1)
        counts = np.maximum(mask.sum(axis=0), 1)
        clean = np.where(mask, np.nan_to_num(values), 0.0)
        signal_mean = clean.sum(axis=0) / counts
        spread = np.sqrt((np.where(mask, clean - signal_mean, 0.0) ** 2).sum(axis=0) / counts)
        signal_scale = np.where(spread > 1e-12, spread, 1.0)

    def tensors(parts):
        x, r = parts[0], parts[1]
        features = torch.as_tensor((x - mean) / scale, dtype=torch.float32)
        targets = torch.as_tensor(r / output_scale, dtype=torch.float32)
        if not names:
            return features, targets, None, None
        standardized = (np.nan_to_num(parts[2]) - signal_mean) / signal_scale
        flags = parts[3]
        standardized = np.where(np.tile(flags, len(config.signal_lags) + 1), standardized, 0.0)
        as_float = lambda a: torch.as_tensor(a, dtype=torch.float32)  # noqa: E731
        return features, targets, as_float(standardized), torch.as_tensor(flags)

    x_t, r_t, s_t, p_t = tensors(train_parts)
    x_v, r_v, s_v, p_v = tensors(valid_parts)
    del train_parts, valid_parts
    repeat = len(config.signal_lags) + 1

    def inputs(x, values, flags, shown):
        """The network's input with the signals `shown` (a bool mask like `flags`)."""
        if values is None:
            return x
        shown = shown & flags
        return torch.cat([x, values * shown.repeat(1, repeat), shown.float()], dim=1)

    width = x_t.shape[1] + (s_t.shape[1] + p_t.shape[1] if names else 0)
    network = _Network(width, config.hidden, NUM_CHANNELS * len(knots))
    optimizer = torch.optim.AdamW(
        network.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay
    )

    def loss_of(features, targets):
        at_knots = network(features).reshape(-1, len(knots), NUM_CHANNELS)
        return ((torch.einsum("nk,bkc->bnc", basis, at_knots) - targets) ** 2).mean()

    def validation_loss() -> float:
        """Averaged over the validation pairs with all their signals and with none."""
        cases = [True, False] if names else [True]
        total = 0.0
        with torch.no_grad():
            for show in cases:
                for batch in torch.arange(x_v.shape[0]).split(4096):
                    flags = None if p_v is None else p_v[batch]
                    shown = None if flags is None else torch.full_like(flags, show)
                    features = inputs(x_v[batch], None if s_v is None else s_v[batch], flags, shown)
                    total += float(loss_of(features, r_v[batch])) * batch.numel()
        return total / (x_v.shape[0] * len(cases))

    def shown_in_training(flags):
        """Which signals a batch's pairs show (class docstring of the config)."""
        keep = torch.rand(flags.shape) < config.signal_keep
        none = torch.rand(flags.shape[0], 1) < config.signal_dropout
        return keep & ~none

    history = {"train": [float((r_t**2).mean())], "validation": [validation_loss()]}
    best = (history["validation"][0], 0, _state(network))
    for epoch in range(1, config.epochs + 1):
        network.train()
        order = torch.as_tensor(rng.permutation(x_t.shape[0]))
        total = 0.0
        for batch in order.split(config.batch_size):
            optimizer.zero_grad()
            if names:
                flags = p_t[batch]
                features = inputs(x_t[batch], s_t[batch], flags, shown_in_training(flags))
            else:
                features = x_t[batch]
            loss = loss_of(features, r_t[batch])
            loss.backward()
            optimizer.step()
            total += float(loss.detach()) * batch.numel()
        network.eval()
        history["train"].append(total / x_t.shape[0])
        history["validation"].append(validation_loss())
        if progress is not None:
            progress(epoch, history["train"][-1], history["validation"][-1])
        if history["validation"][-1] < best[0]:
            best = (history["validation"][-1], epoch, _state(network))
        elif epoch - best[1] >= config.patience:
            break
    predictor = LearnedPredictor(
        linear=linear,
        lags=config.lags,
        mean=mean,
        scale=scale,
        layers=best[2],
        knots=knots,
        output_scale=output_scale,
        metadata={
            **(metadata or {}),
            "config": dataclasses.asdict(config),
            "best_epoch": best[1],
            "training_samples": int(x_t.shape[0]),
        },
        signals=names,
        signal_lags=config.signal_lags if names else (),
        signal_mean=signal_mean,
        signal_scale=signal_scale,
    )
    report = {
        "loss": history,
        "best_epoch": best[1],
        "epochs_run": len(history["train"]) - 1,
        "seconds": time.perf_counter() - start,
        "training_samples": int(x_t.shape[0]),
        "validation_samples": int(x_v.shape[0]),
    }
    return predictor, report


def _state(network: _Network) -> list:
    """The network's layers as numpy (W (in, out), b) pairs."""
    linears = [network.hidden[0], network.hidden[2], network.out]
    return [
        (layer.weight.detach().numpy().T.copy(), layer.bias.detach().numpy().copy())
        for layer in linears
    ]
