"""Reference forecasts and the predictive NMPC.

Oracles: ramps, which a linear forecast must continue exactly; the recorded future, with
which the predictive NMPC must equal the preview NMPC; the causal NMPC, which the constant
forecast must equal; and the reference itself, changed after a time that no earlier command
may notice."""

from __future__ import annotations

import numpy as np
import pytest
from forecast_helpers import perfect_predictor
from forecast_helpers import smooth_flight as flight
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

import mca_drake.systems.predictor as predictor_systems
from mca_drake.app.scenarios import LiveScenario
from mca_drake.cueing import NmpcConfig, mca_config_from_name, mca_name
from mca_drake.cueing.predictor import (
    LinearPredictor,
    constant_forecast,
    fit_linear_predictor,
    load_linear_predictor,
    save_linear_predictor,
)
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.systems import ReferenceSource
from mca_drake.systems.predictor import ReferencePredictor

H = 0.01
KR500 = load_platform("kr500")


def ramps(rng, count=40, length=400):
    """References whose every channel is a ramp of its own slope and offset."""
    t = np.arange(length)[:, None]
    return [rng.normal(size=6) + rng.normal(scale=0.01, size=6) * t for _ in range(count)]


def test_a_fitted_linear_forecast_continues_a_ramp_exactly(rng):
    model = fit_linear_predictor(ramps(rng), 30, ridge=1e-12, stride=7)
    (y,) = ramps(rng, count=1)
    k = 200
    forecast = model.forecast(y[k - model.history + 1 : k + 1])
    np.testing.assert_allclose(forecast, y[k + 1 : k + 31], atol=1e-8)
    # histories of a batch at once, and fewer steps
    batch = np.stack([y[k - model.history + 1 : k + 1], y[k - model.history : k]])
    np.testing.assert_allclose(model.forecast(batch, 5)[1], y[k : k + 5], atol=1e-8)


def test_the_constant_forecast_holds_the_current_sample(rng):
    history = rng.normal(size=(7, 6))
    np.testing.assert_array_equal(constant_forecast(history, 4), np.tile(history[-1], (4, 1)))


def test_a_saved_predictor_loads_as_it_was(rng, tmp_path):
    model = fit_linear_predictor(ramps(rng), 12, metadata={"source": "ramps"})
    path = save_linear_predictor(tmp_path / "p.npz", model)
    again = load_linear_predictor(path)
    assert again.lags == model.lags and again.steps == 12
    assert again.metadata["source"] == "ramps"
    np.testing.assert_array_equal(again.weights, model.weights)
    (y,) = ramps(rng, count=1)
    np.testing.assert_array_equal(again.forecast(y[-60:]), model.forecast(y[-60:]))


def test_bad_predictors_are_refused(rng, tmp_path):
    np.savez(tmp_path / "other.npz", weights=np.zeros(3), metadata_json=np.array("{}"))
    with pytest.raises(ValueError, match="not a linear predictor"):
        load_linear_predictor(tmp_path / "other.npz")
    with pytest.raises(FileNotFoundError):
        load_linear_predictor(tmp_path / "missing.npz")
    with pytest.raises(ValueError, match=r"weights must have shape"):
        LinearPredictor(lags=(1, 2), steps=3, scale=np.ones(18), weights=np.zeros((18, 2, 6)))
    with pytest.raises(ValueError, match="unknown predictor"):
        NmpcConfig(preview_steps=10, predictor="oracle").validate()
    with pytest.raises(ValueError, match="set preview_steps"):
        NmpcConfig(predictor="constant").validate()
    with pytest.raises(ValueError, match="training samples"):
        fit_linear_predictor([np.zeros((40, 6))], 30)


def test_the_predictor_system_forecasts_from_what_it_has_read(rng):
    """Its preview at each control instant is the current sample and the model's forecast
    of the history read so far (the first sample held before it)."""
    model = fit_linear_predictor(ramps(rng), 20, stride=3)
    y = np.cumsum(rng.normal(scale=0.05, size=(120, 6)), axis=0)
    builder = DiagramBuilder()
    source = builder.AddSystem(ReferenceSource(Reference(y, H)))
    system = builder.AddSystem(
        ReferencePredictor(lambda h: model.forecast(h, 20), model.history, 21, H)
    )
    builder.Connect(source.GetOutputPort("reference"), system.GetInputPort("reference"))
    log = LogVectorOutput(system.GetOutputPort("reference_preview"), builder, H)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(110 * H + 1e-9)
    previews = log.FindLog(simulator.get_context()).data().T.reshape(-1, 21, 6)
    padded = np.vstack([np.tile(y[0], (model.history - 1, 1)), y])
    for k in (0, 3, 50, 110):
        history = padded[k : k + model.history]
        expected = np.vstack([y[k], model.forecast(history, 20)])
        np.testing.assert_allclose(previews[k], expected, atol=1e-12)


def test_the_predictive_nmpc_with_the_recorded_future_is_the_preview_nmpc(monkeypatch):
    reference = flight()
    steps = NmpcConfig().horizon_steps
    monkeypatch.setattr(predictor_systems, "MakeReferencePredictor", perfect_predictor(reference))
    predictive = run_closed_loop(
        mca=NmpcConfig(preview_steps=steps, predictor="constant"),
        reference=reference,
        robot=KR500,
        progress=False,
    )
    preview = run_closed_loop(
        mca=NmpcConfig(preview_steps=steps), reference=reference, robot=KR500, progress=False
    )
    np.testing.assert_allclose(predictive.commands, preview.commands, rtol=0, atol=1e-9)
    assert abs(predictive.summary["pi"] - preview.summary["pi"]) < 1e-9


def test_the_constant_forecast_is_the_causal_nmpc():
    reference = flight()
    constant = run_closed_loop(
        mca=NmpcConfig(preview_steps=NmpcConfig().horizon_steps, predictor="constant"),
        reference=reference,
        robot=KR500,
        progress=False,
    )
    causal = run_closed_loop(mca="nmpc-rti", reference=reference, robot=KR500, progress=False)
    np.testing.assert_allclose(constant.commands, causal.commands, rtol=0, atol=1e-9)


def test_a_predictor_never_sees_the_future():
    """Changing the reference from 4 s on leaves every command before 4 s as it was; the
    predictive NMPC holds every limit."""
    reference = flight()
    changed = reference.y.copy()
    k = round(4.0 / H)
    changed[k:] += np.array([0.2, -0.1, 0.3, 2.0, -1.5, 1.0])
    runs = [
        run_closed_loop(
            mca="nmpc-rti-predictive", reference=Reference(y, H), robot=KR500, progress=False
        )
        for y in (reference.y, changed)
    ]
    np.testing.assert_array_equal(runs[0].commands[:k], runs[1].commands[:k])
    assert np.max(np.abs(runs[0].commands[k:] - runs[1].commands[k:])) > 1e-3
    for run in runs:
        assert run.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}


def test_predictive_names_and_live_use():
    config = mca_config_from_name("nmpc-rti-predictive")
    assert (config.mode, config.predictor, config.preview_steps) == ("rti", "learned", 256)
    assert mca_name(config) == "nmpc-rti-predictive"
    linear = NmpcConfig(mode="rti", preview_steps=256, predictor="linear")
    assert mca_name(linear) == "nmpc-rti-predictive-linear"
    assert mca_name(mca_config_from_name("nmpc-converged-predictive")) == (
        "nmpc-converged-predictive"
    )
    LiveScenario(mca="nmpc-rti-predictive", port=0).validate()
    with pytest.raises(ValueError, match="no future"):
        LiveScenario(mca=NmpcConfig(preview_steps=10), port=0).validate()
