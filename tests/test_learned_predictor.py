"""The learned reference forecast: the linear one corrected by a network.

Oracles: linear interpolation worked by hand (the knot basis); the torch network the numpy
forward must equal; the linear forecast, which an untrained correction (last layer zero)
must leave exactly; references whose future a linear forecast cannot know but a nonlinear
one can (triangle waves that turn at their bounds); and the validation loss of the linear
forecast, which the kept epoch may never exceed."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mca_drake.cueing.learned_predictor import (
    LearnedPredictor,
    default_knots,
    knot_basis,
    load_forecast_model,
    load_learned_predictor,
    save_learned_predictor,
)
from mca_drake.cueing.predictor import (
    fit_linear_predictor,
    forecast_errors,
    save_linear_predictor,
)
from mca_drake.learning.predictor_training import (
    LearnedPredictorConfig,
    _Network,
    _state,
    train_learned_predictor,
)
from mca_drake.systems.predictor import MakeReferencePredictor

LAGS = (1, 2, 5, 10)


def triangles(rng, count, length=300):
    """References whose every channel runs between -1 and 1 at a slope of its own and turns
    at the bounds (a triangle wave of random phase): when it turns is a nonlinear function
    of the level and the slope, which a linear forecast cannot follow."""
    out = []
    for _ in range(count):
        y = np.empty((length, 6))
        y[0] = rng.uniform(-1.0, 1.0, size=6)
        slope = rng.uniform(0.01, 0.04, size=6) * rng.choice([-1.0, 1.0], size=6)
        for k in range(1, length):
            y[k] = y[k - 1] + slope
            slope = np.where(np.abs(y[k]) >= 1.0, -np.sign(y[k]) * np.abs(slope), slope)
        out.append(y)
    return out


def test_the_knot_basis_interpolates_linearly_between_knots():
    basis = knot_basis((1, 3, 7), 7)
    values = np.array([2.0, -1.0, 5.0])
    expected = [2.0, 0.5, -1.0, 0.5, 2.0, 3.5, 5.0]  # by hand: steps 1..7
    np.testing.assert_allclose(basis @ values, expected)
    assert default_knots(256)[:3] == (1, 2, 4) and default_knots(256)[-1] == 256
    with pytest.raises(ValueError, match="rise from 1"):
        knot_basis((2, 7), 7)


def _learned(rng, linear, hidden=8, zero_last=False):
    knots = default_knots(linear.steps)
    width = 6 * (len(LAGS) + 1)
    network = _Network(width, hidden, 6 * len(knots))
    if not zero_last:
        torch.nn.init.normal_(network.out.weight, std=0.3)
    return network, LearnedPredictor(
        linear=linear,
        lags=LAGS,
        mean=rng.normal(size=width),
        scale=rng.uniform(0.5, 2.0, size=width),
        layers=_state(network),
        knots=knots,
        output_scale=rng.uniform(0.5, 2.0, size=6),
    )


def test_the_numpy_forecast_is_the_torch_networks(rng):
    linear = fit_linear_predictor(triangles(rng, 4), 20, lags=(1, 3))
    network, model = _learned(rng, linear)
    histories = rng.normal(size=(3, model.history, 6))
    now = histories[:, -1]
    raw = np.concatenate([histories[:, -1 - lag] - now for lag in LAGS] + [now], axis=1)
    x = torch.as_tensor((raw - model.mean) / model.scale, dtype=torch.float32)
    at_knots = network(x).detach().numpy().reshape(3, len(model.knots), 6)
    steps = np.arange(1, linear.steps + 1)
    torch_correction = (
        np.stack(
            [
                np.stack([np.interp(steps, model.knots, at_knots[b, :, c]) for c in range(6)], 1)
                for b in range(3)
            ]
        )
        * model.output_scale
    )
    np.testing.assert_allclose(model.correction(histories), torch_correction, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(
        model.forecast(histories, 7),
        linear.forecast(histories[:, -linear.history :], 7) + torch_correction[:, :7],
        rtol=1e-5,
        atol=1e-6,
    )


def test_an_untrained_correction_leaves_the_linear_forecast(rng):
    linear = fit_linear_predictor(triangles(rng, 4), 20, lags=(1, 3))
    _, model = _learned(rng, linear, zero_last=True)
    history = rng.normal(size=(model.history, 6))
    np.testing.assert_array_equal(model.forecast(history), linear.forecast(history))


def test_a_saved_learned_predictor_loads_as_it_was_and_by_kind(rng, tmp_path):
    linear = fit_linear_predictor(triangles(rng, 4), 20, lags=(1, 3))
    _, model = _learned(rng, linear)
    path = save_learned_predictor(tmp_path / "learned.npz", model)
    again = load_learned_predictor(path)
    history = rng.normal(size=(model.history, 6))
    np.testing.assert_array_equal(again.forecast(history), model.forecast(history))
    assert isinstance(load_forecast_model(str(path)), LearnedPredictor)
    linear_path = save_linear_predictor(tmp_path / "linear.npz", linear)
    assert not isinstance(load_forecast_model(str(linear_path)), LearnedPredictor)
    with pytest.raises(ValueError, match="not a learned predictor file"):
        load_learned_predictor(linear_path)
    # the Drake system runs it: its preview is the current sample, then the forecast
    system = MakeReferencePredictor(str(path), 8)
    context = system.CreateDefaultContext()
    system.get_input_port().FixValue(context, history[-1])
    preview = system.get_output_port().Eval(context).reshape(8, 6)
    np.testing.assert_allclose(preview[0], history[-1])
    held = np.tile(history[-1], (model.history, 1))  # no history yet: the sample held
    np.testing.assert_allclose(preview[1:], model.forecast(held, 7))


def test_training_learns_what_the_linear_forecast_cannot_and_never_loses(rng):
    training, validation = triangles(rng, 60), triangles(rng, 12)
    linear = fit_linear_predictor(training, 40, lags=LAGS, stride=3)
    config = LearnedPredictorConfig(
        lags=LAGS, hidden=32, epochs=15, stride=3, loss_stride=2, batch_size=64
    )
    model, report = train_learned_predictor(linear, training, validation, config)
    losses = report["loss"]["validation"]
    assert min(losses) <= losses[0]  # the kept epoch is never worse than the linear forecast
    assert losses[report["best_epoch"]] == min(losses)
    assert min(losses) < 0.8 * losses[0]  # and the turns are learned
    # measured as any forecast is: RMS error 10 and 40 steps ahead on the validation ones
    learned_rmse = forecast_errors(model.forecast, validation, [10, 40], history=model.history)
    linear_rmse = forecast_errors(linear.forecast, validation, [10, 40], history=model.history)
    assert learned_rmse.mean() < 0.9 * linear_rmse.mean()
    # an epoch-less training keeps the linear forecast exactly
    same, _ = train_learned_predictor(
        linear, training, validation, LearnedPredictorConfig(lags=LAGS, epochs=0, stride=3)
    )
    history = validation[0][: same.history]
    np.testing.assert_array_equal(same.forecast(history), linear.forecast(history))
