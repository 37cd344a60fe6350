"""Forecasts that read the controls and vehicle state a source carries.

Oracles: references whose future is set by a control given beforehand (a channel follows a
stick 40 samples late), which a forecast reading the stick knows and one reading the motion
cannot; the model's own forecast of histories padded by hand, which the Drake system beside
a closed loop must output; and the signals themselves, changed after a time that no earlier
command may notice."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from mca_drake.cueing import NmpcConfig
from mca_drake.cueing.learned_predictor import (
    LearnedPredictor,
    default_knots,
    load_learned_predictor,
    save_learned_predictor,
    signal_features,
)
from mca_drake.cueing.predictor import fit_linear_predictor
from mca_drake.learning.predictor_training import (
    LearnedPredictorConfig,
    _Network,
    _state,
    train_learned_predictor,
)
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.systems import ReferenceSource
from mca_drake.systems.predictor import MakeReferencePredictor

H = 0.01
DELAY = 40
LAGS = (1, 2, 5, 10)


def stick_flights(rng, count, length=400):
    """(y, {"aileron": u}) pairs: u a stick held at random levels for random spells; the
    roll rate y[:, 0] follows it DELAY samples late, the other channels drift slowly."""
    out = []
    for _ in range(count):
        u = np.empty(length)
        k = 0
        while k < length:
            spell = int(rng.integers(20, 80))
            u[k : k + spell] = rng.uniform(-1.0, 1.0)
            k += spell
        y = 0.05 * np.cumsum(rng.normal(scale=0.02, size=(length, 6)), axis=0)
        y[:, 0] = 0.3 * np.r_[np.zeros(DELAY), u[:-DELAY]]
        out.append((y, {"aileron": u}))
    return out


def errors(model, flights, ahead, show):
    """RMS error of the roll-rate forecast `ahead` samples on, every 5th sample, with the
    stick shown or not."""
    squared = []
    for y, signals in flights:
        for k in range(max(model.history, model.signal_history), y.shape[0] - ahead, 5):
            history = y[k - model.history + 1 : k + 1]
            stick = signals["aileron"][k - model.signal_history + 1 : k + 1, None]
            seen = stick if show else np.full_like(stick, np.nan)
            forecast = model.forecast(history, ahead, seen)
            squared.append((forecast[-1, 0] - y[k + ahead, 0]) ** 2)
    return float(np.sqrt(np.mean(squared)))


def test_a_forecast_reading_the_stick_knows_what_the_motion_cannot(rng):
    training, validation = stick_flights(rng, 40), stick_flights(rng, 8)
    linear = fit_linear_predictor([y for y, _ in training], 40, lags=LAGS, stride=3)
    config = LearnedPredictorConfig(
        lags=LAGS,
        hidden=32,
        epochs=20,
        stride=3,
        loss_stride=2,
        batch_size=64,
        signals=("aileron",),
        signal_lags=(10, 20, 30),  # the stick that sets the roll rate 30 to 10 samples on
    )
    model, report = train_learned_predictor(linear, training, validation, config)
    assert model.signals == ("aileron",) and report["best_epoch"] > 0
    shown, hidden = errors(model, validation, 30, True), errors(model, validation, 30, False)
    assert shown < 0.4 * hidden, (shown, hidden)


def _signal_model(rng, linear):
    """A learned forecast reading the aileron and the speed, with random weights."""
    signals, signal_lags = ("aileron", "speed"), (1, 3)
    knots = default_knots(linear.steps)
    width = 6 * (len(LAGS) + 1) + len(signals) * (len(signal_lags) + 2)
    network = _Network(width, 8, 6 * len(knots))
    torch.nn.init.normal_(network.out.weight, std=0.3)
    features = len(signals) * (len(signal_lags) + 1)
    return LearnedPredictor(
        linear=linear,
        lags=LAGS,
        mean=rng.normal(size=6 * (len(LAGS) + 1)),
        scale=rng.uniform(0.5, 2.0, size=6 * (len(LAGS) + 1)),
        layers=_state(network),
        knots=knots,
        output_scale=rng.uniform(0.1, 0.3, size=6),
        signals=signals,
        signal_lags=signal_lags,
        signal_mean=rng.normal(size=features),
        signal_scale=rng.uniform(0.5, 2.0, size=features),
    )


def test_absent_signals_are_read_as_absent_and_files_keep_them(rng, tmp_path):
    linear = fit_linear_predictor([y for y, _ in stick_flights(rng, 4)], 20, lags=(1, 3))
    model = _signal_model(rng, linear)
    history = rng.normal(size=(model.history, 6))
    nothing = np.full((model.signal_history, 2), np.nan)
    np.testing.assert_array_equal(model.forecast(history), model.forecast(history, None, nothing))
    seen = rng.normal(size=(model.signal_history, 2))
    assert np.abs(model.forecast(history, None, seen) - model.forecast(history)).max() > 1e-6
    values, present = signal_features(np.c_[seen[:, 0], np.full(4, np.nan)], (1, 3))
    assert present.tolist() == [True, False] and values[0] == seen[-1, 0]
    again = load_learned_predictor(save_learned_predictor(tmp_path / "s.npz", model))
    assert again.signals == model.signals and again.signal_lags == model.signal_lags
    np.testing.assert_array_equal(
        again.forecast(history, 7, seen), model.forecast(history, 7, seen)
    )
    with pytest.raises(ValueError, match="signals must be distinct names"):
        dataclasses.replace(model, signals=("stick", "speed"))


@pytest.fixture
def signal_model_file(rng, tmp_path):
    t = np.arange(2000)[:, None]
    ramps = [rng.normal(size=6) + rng.normal(scale=0.01, size=6) * t for _ in range(4)]
    linear = fit_linear_predictor(ramps, 256, lags=(1, 3))
    model = _signal_model(rng, linear)
    return model, save_learned_predictor(tmp_path / "signals.npz", model)


def _flight(rng, seconds=6.0):
    t = np.arange(round(seconds / H) + 1) * H
    y = np.stack([0.3 * np.sin(0.5 * t + p) for p in range(6)], axis=1)
    signals = {"aileron": np.sin(0.9 * t), "speed": 60.0 + t, "throttle": np.full_like(t, 0.5)}
    return Reference(y, H, "stick", signals=signals)


def test_the_system_forecasts_from_the_signals_it_has_read(rng, signal_model_file):
    """Beside a ReferenceSource the system's forecast at each instant is the model's of
    the reference and signal histories read so far, the first sample held before them."""
    model, path = signal_model_file
    reference = _flight(rng)
    builder = DiagramBuilder()
    source = builder.AddSystem(ReferenceSource(reference))
    system = builder.AddSystem(MakeReferencePredictor(str(path), 9, H))
    builder.Connect(source.GetOutputPort("reference"), system.GetInputPort("reference"))
    builder.Connect(source.GetOutputPort("signals"), system.GetInputPort("signals"))
    log = LogVectorOutput(system.GetOutputPort("reference_preview"), builder, H)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(120 * H + 1e-9)
    previews = log.FindLog(simulator.get_context()).data().T.reshape(-1, 9, 6)
    y = reference.y
    stick = np.c_[reference.signals["aileron"], reference.signals["speed"]]
    padded_y = np.vstack([np.tile(y[0], (model.history - 1, 1)), y])
    padded_s = np.vstack([np.tile(stick[0], (model.signal_history - 1, 1)), stick])
    for k in (0, 2, 60, 120):
        expected = model.forecast(
            padded_y[k : k + model.history], 8, padded_s[k : k + model.signal_history]
        )
        np.testing.assert_allclose(previews[k, 1:], expected, atol=1e-9)


def test_a_predictor_never_sees_future_signals(rng, signal_model_file):
    """Changing the aileron from 3 s on leaves every command before 3 s as it was and
    changes later ones: the predictive NMPC reads the signals, and only the past ones."""
    _, path = signal_model_file
    reference = _flight(rng)
    changed = dict(reference.signals)
    k = round(3.0 / H)
    changed["aileron"] = np.r_[changed["aileron"][:k], -changed["aileron"][k:]]
    config = NmpcConfig(preview_steps=256, predictor=str(path))
    runs = [
        run_closed_loop(
            mca=config,
            reference=Reference(reference.y, H, signals=signals),
            robot=load_platform("kr500"),
            progress=False,
        )
        for signals in (reference.signals, changed)
    ]
    np.testing.assert_array_equal(runs[0].commands[:k], runs[1].commands[:k])
    assert np.max(np.abs(runs[0].commands[k:] - runs[1].commands[k:])) > 1e-6
    for run in runs:
        assert run.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}


def test_references_carry_a_recordings_signals_to_the_source(rng):
    """A recording's signals ride on its reference, cut with it, and leave the source at
    each sample in `SIGNALS` order, NaN for those it lacks; a signal of another length is
    refused."""
    from mca_drake.references.recording import Recording
    from mca_drake.references.reference import reference_from_recording
    from mca_drake.references.vehicle_signals import SIGNALS

    t = np.arange(300) * H
    omega, f = rng.normal(scale=0.1, size=(300, 3)), np.tile([0.0, 0.0, 9.81], (300, 1))
    recording = Recording(t, omega, f, {}, {"throttle": np.linspace(0, 1, 300)})
    reference = reference_from_recording(recording).truncated(1.0)
    assert reference.signals["throttle"].shape == (101,)
    source = ReferenceSource(reference)
    context = source.CreateDefaultContext()
    context.SetTime(0.5 + 1e-9)
    out = source.GetOutputPort("signals").Eval(context)
    names = list(SIGNALS)
    assert out[names.index("throttle")] == pytest.approx(50 / 299)
    assert np.isnan(np.delete(out, names.index("throttle"))).all()
    with pytest.raises(ValueError, match="must have 101 samples"):
        Reference(reference.y, H, signals={"speed": np.zeros(3)})
