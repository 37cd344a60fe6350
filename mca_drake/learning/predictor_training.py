"""Training the learned reference forecast (`mca_drake.cueing.learned_predictor`) in torch.

The network learns what the linear forecast misses: its targets are the residuals of the
linear forecast on the training references, in units of each channel's residual spread
(each channel counts alike, as in the PI). Its last layer starts at zero, so training
starts from the linear forecast, and the epoch kept is the one that forecasts the
validation references best: a learned forecast is never worse there than the linear one
it corrects (when no epoch helps, the correction stays zero).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import torch

from mca_drake.cueing.learned_predictor import (
    LEARNED_LAGS,
    LearnedPredictor,
    default_knots,
    knot_basis,
)
from mca_drake.cueing.predictor import NUM_CHANNELS, LinearPredictor, lag_features


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


def forecast_pairs(
    y: np.ndarray, linear: LinearPredictor, lags, stride: int, read=None
) -> tuple[np.ndarray, np.ndarray]:
    """(raw features (M, F), residuals (M, S, 6)) of reference y (T, 6): at every
    `stride`-th sample with the longest history either model reads and N samples after it,
    the network's features and what came less the linear forecast, at the forecast steps
    `read` (0-based indices into the N; default all, S = N)."""
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
    return lag_features(windows, lags), residuals


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
    kept at its best epoch on `validation` ones (arrays (T, 6) at the linear model's
    control period). Returns it and a report: per-epoch training and validation loss
    (mean squared residual in units of each channel's spread; the linear forecast's is the
    loss at epoch 0), the best epoch, seconds.

    `progress(epoch, train_loss, validation_loss)` is called after every epoch."""
    config = config or LearnedPredictorConfig()
    start = time.perf_counter()
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    knots = default_knots(linear.steps)
    read = np.unique(np.r_[np.arange(0, linear.steps, config.loss_stride), linear.steps - 1])
    pairs = [forecast_pairs(y, linear, config.lags, config.stride, read) for y in training]
    held = [forecast_pairs(y, linear, config.lags, config.stride, read) for y in validation]
    x_train = np.concatenate([p[0] for p in pairs])
    r_train = np.concatenate([p[1] for p in pairs])
    x_valid = np.concatenate([p[0] for p in held])
    r_valid = np.concatenate([p[1] for p in held])
    del pairs, held
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

    def tensors(x, r):
        features = torch.as_tensor((x - mean) / scale, dtype=torch.float32)
        targets = torch.as_tensor(r / output_scale, dtype=torch.float32)
        return features, targets

    x_t, r_t = tensors(x_train, r_train)
    x_v, r_v = tensors(x_valid, r_valid)
    network = _Network(x_t.shape[1], config.hidden, NUM_CHANNELS * len(knots))
    optimizer = torch.optim.AdamW(
        network.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay
    )

    def loss_of(features, targets):
        at_knots = network(features).reshape(-1, len(knots), NUM_CHANNELS)
        return ((torch.einsum("nk,bkc->bnc", basis, at_knots) - targets) ** 2).mean()

    def validation_loss() -> float:
        with torch.no_grad():
            batches = zip(x_v.split(4096), r_v.split(4096), strict=True)
            return float(sum(loss_of(f, t) * f.shape[0] for f, t in batches) / x_v.shape[0])

    history = {"train": [float((r_t**2).mean())], "validation": [validation_loss()]}
    best = (history["validation"][0], 0, _state(network))
    for epoch in range(1, config.epochs + 1):
        network.train()
        order = torch.as_tensor(rng.permutation(x_t.shape[0]))
        total = 0.0
        for batch in order.split(config.batch_size):
            optimizer.zero_grad()
            loss = loss_of(x_t[batch], r_t[batch])
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
    layers = best[2]
    predictor = LearnedPredictor(
        linear=linear,
        lags=config.lags,
        mean=mean,
        scale=scale,
        layers=layers,
        knots=knots,
        output_scale=output_scale,
        metadata={
            **(metadata or {}),
            "config": dataclasses.asdict(config),
            "best_epoch": best[1],
            "training_samples": int(x_t.shape[0]),
        },
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
