"""The predictive DPC: a preview policy reading a forecast of the reference.

Oracles: the ReferencePredictor system beside a closed loop, whose forecasts the training
array must equal sample for sample; a causal policy, which its widened preview twin must
equal exactly; the recorded future, with which a forecast-reading DPC must equal the same
policy reading the recorded preview; and the reference itself, changed after a time that
no earlier command may notice."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from dataset_helpers import segments_of
from forecast_helpers import perfect_predictor, smooth_flight
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

import mca_drake.systems.predictor as predictor_systems
from mca_drake.app.scenarios import LiveScenario
from mca_drake.cueing import DpcConfig, mca_config_from_name, mca_name
from mca_drake.cueing.dpc import PREVIEW_POINTS, default_policy_path, preview_offsets
from mca_drake.cueing.learned_predictor import load_forecast_model
from mca_drake.learning.dpc_training import (
    DpcTrainingConfig,
    mirror_some_windows,
    train_policy,
)
from mca_drake.learning.forecast_previews import (
    FORECAST_PREVIEW_ARRAY,
    flight_forecast_previews,
    forecast_preview_array,
)
from mca_drake.learning.policy_network import (
    PolicyNetwork,
    load_policy_network,
    save_policy,
    with_preview,
)
from mca_drake.learning.trainer import TrainConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.systems import ReferenceSource
from mca_drake.systems.dpc import DpcPolicy
from mca_drake.systems.predictor import MakeReferencePredictor

H = 0.01
KR500 = load_platform("kr500")
PREVIEW = 256


@pytest.fixture(scope="module")
def widened(tmp_path_factory):
    """The default policy widened to a preview of PREVIEW periods: once as it is (zero
    preview weights), once with the preview read (small random preview weights)."""
    causal = load_policy_network(default_policy_path(), KR500)
    folder = tmp_path_factory.mktemp("policies")
    same = with_preview(causal, KR500, PREVIEW)
    save_policy(folder / "same.npz", same, {"platform": KR500.summary()})
    reading = with_preview(causal, KR500, PREVIEW)
    torch.manual_seed(0)
    with torch.no_grad():
        first = reading.f_pi.net[0].weight
        first[:, -6 * PREVIEW_POINTS :] = 0.05 * torch.randn(first.shape[0], 6 * PREVIEW_POINTS)
    save_policy(folder / "reading.npz", reading, {"platform": KR500.summary()})
    return causal, folder / "same.npz", folder / "reading.npz"


def test_the_training_forecast_is_what_the_predictor_system_outputs():
    """Sample for sample, the forecast previews of a dataset's run of segments equal the
    ReferencePredictor's output at the preview offsets, run on the same flight."""
    y = smooth_flight(4.0).y
    model = load_forecast_model("learned")
    offsets = preview_offsets(PREVIEW)
    builder = DiagramBuilder()
    source = builder.AddSystem(ReferenceSource(Reference(y, H)))
    system = builder.AddSystem(MakeReferencePredictor("learned", PREVIEW + 1, H))
    builder.Connect(source.GetOutputPort("reference"), system.GetInputPort("reference"))
    log = LogVectorOutput(system.GetOutputPort("reference_preview"), builder, H)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(300 * H + 1e-9)
    logged = log.FindLog(simulator.get_context()).data().T.reshape(-1, PREVIEW + 1, 6)
    # the same flight as a dataset: three consecutive segments of 100 samples, shuffled
    n_p = 100
    rows = [(5, 2 * n_p), (5, 0), (5, n_p)]
    source_rows = np.array([(seed, step, 0) for seed, step in rows])
    segments = np.stack([y[step : step + n_p] for _, step in rows])
    data = segments_of({"R": segments}, source_rows)
    array = forecast_preview_array(data, "R", "learned", PREVIEW)
    by_time = array[[1, 2, 0]].reshape(3 * n_p, PREVIEW_POINTS, 6)
    for k in (0, 1, 7, 150, 299):
        np.testing.assert_allclose(by_time[k], logged[k][offsets], rtol=0, atol=1e-5)
    direct = flight_forecast_previews(y[:300], model, offsets)
    np.testing.assert_allclose(direct.reshape(300, PREVIEW_POINTS, 6), by_time, atol=1e-5)


def test_a_widened_policy_acts_as_the_causal_one(widened):
    causal, same, _ = widened
    wide = load_policy_network(same, KR500)
    rng = np.random.default_rng(1)
    y, target = (torch.tensor(rng.normal(size=(5, 6)), dtype=torch.float32) for _ in range(2))
    x = torch.tensor(rng.normal(scale=0.2, size=(5, 12)), dtype=torch.float32)
    preview = torch.tensor(rng.normal(size=(5, 6 * PREVIEW_POINTS)), dtype=torch.float32)
    for a, b in zip(causal(y, x, target), wide(y, x, target, preview), strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=0)
    with pytest.raises(ValueError, match="already"):
        with_preview(wide, KR500, PREVIEW)


def test_a_predictive_dpc_equals_its_policy_on_the_recorded_future(widened, monkeypatch):
    """With a forecast that is the recorded future the predictive DPC commands what the
    same policy commands reading the recorded preview; with zero preview weights, what the
    causal policy commands."""
    _, same, reading = widened
    reference = smooth_flight(6.0)

    recorded = run_closed_loop(
        mca=DpcConfig(policy=str(reading)), reference=reference, robot=KR500, progress=False
    )
    monkeypatch.setattr(predictor_systems, "MakeReferencePredictor", perfect_predictor(reference))
    forecast = run_closed_loop(
        mca=DpcConfig(policy=str(reading), predictor="constant"),
        reference=reference,
        robot=KR500,
        progress=False,
    )
    np.testing.assert_allclose(forecast.commands, recorded.commands, rtol=0, atol=1e-9)
    monkeypatch.undo()
    zero = run_closed_loop(
        mca=DpcConfig(policy=str(same), predictor="learned"),
        reference=reference,
        robot=KR500,
        progress=False,
    )
    causal = run_closed_loop(
        mca=DpcConfig(policy=str(default_policy_path())),
        reference=reference,
        robot=KR500,
        progress=False,
    )
    np.testing.assert_allclose(zero.commands, causal.commands, rtol=0, atol=1e-9)


def test_a_predictive_dpc_never_sees_the_future(widened):
    """Changing the reference from 3 s on leaves every command before 3 s as it was."""
    _, _, reading = widened
    reference = smooth_flight(6.0)
    changed = reference.y.copy()
    k = round(3.0 / H)
    changed[k:] += np.array([0.2, -0.1, 0.3, 2.0, -1.5, 1.0])
    runs = [
        run_closed_loop(
            mca=DpcConfig(policy=str(reading), predictor="learned"),
            reference=Reference(y, H),
            robot=KR500,
            progress=False,
        )
        for y in (reference.y, changed)
    ]
    np.testing.assert_array_equal(runs[0].commands[:k], runs[1].commands[:k])
    assert np.max(np.abs(runs[0].commands[k:] - runs[1].commands[k:])) > 1e-3
    for run in runs:
        assert run.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}


def test_names_and_refusals(widened):
    _, same, _ = widened
    config = mca_config_from_name("dpc-predictive")
    assert config == DpcConfig(predictor="learned") and mca_name(config) == "dpc-predictive"
    assert mca_name(DpcConfig(policy=str(same), predictor="linear")) == "dpc-predictive-linear"
    assert not config.recognizes()
    ground = mca_config_from_name("dpc-predictive-ground")
    assert ground == DpcConfig(predictor="learned", profile="ground")
    assert mca_name(ground) == "dpc-predictive-ground"
    # the ground's predictive policy for a car, named or from the ground profile
    car = dataclasses.replace(config, vehicle="bmw-320i")
    for ground_config in (ground, car):
        assert ground_config.cues_ground() and not config.cues_ground()
    # each causal policy the DPC picks by vehicle has its predictive twin
    for vehicle, twin in (("", "predictive"), ("light", "light_predictive")):
        named = dataclasses.replace(config, vehicle=vehicle)
        assert named.policy_path("kr500").name == f"{twin}_policy.npz"
        assert (
            DpcConfig(vehicle=vehicle).policy_path("kr500").name
            == (twin.replace("predictive", "").rstrip("_") or "default") + "_policy.npz"
        )
    assert dataclasses.replace(config, vehicle="B747").policy_path("kr500").name == (
        "transport_predictive_policy.npz"
    )
    with pytest.raises(ValueError, match="unknown predictor"):
        DpcConfig(predictor="oracle").validate()
    with pytest.raises(ValueError, match="reads none"):
        DpcPolicy(str(default_policy_path()), KR500, predictor="learned")
    with pytest.raises(FileNotFoundError, match="no predictive policy"):
        config.policy_path("fanuc-m900ib700")
    LiveScenario(mca=DpcConfig(policy=str(same), predictor="learned"), port=0).validate()
    with pytest.raises(ValueError, match="no future"):
        LiveScenario(mca=DpcConfig(policy=str(same)), port=0).validate()


def test_mirrored_windows_mirror_their_forecast():
    torch.manual_seed(3)
    x0, y0 = torch.zeros(64, 12), torch.ones(64, 6)
    targets = torch.ones(64, 5, 6)
    previews = torch.arange(6 * PREVIEW_POINTS, dtype=torch.float32).repeat(64, 5, 1) + 1
    _, y, r, p = mirror_some_windows(x0, y0, targets, 0.5, KR500, previews)
    flipped = (y < 0).any(dim=1)
    assert 0 < flipped.sum() < 64
    signs = p / previews
    # each preview point carries its window's channel signs, those of its targets
    np.testing.assert_array_equal(signs.numpy(), r.repeat(1, 1, PREVIEW_POINTS).numpy())


def test_training_on_the_forecast_runs_from_a_causal_policy(tmp_path):
    rng = np.random.default_rng(4)
    n, n_p = 12, 300
    split = (np.arange(n) >= 8).astype(np.int64)
    source = np.stack([np.arange(n) // 4, n_p * (np.arange(n) % 4), split], 1)
    data = segments_of({"R": 0.3 * rng.normal(size=(n, n_p, 6))}, source)
    path = data.save(tmp_path / "data.npz")
    causal = tmp_path / "causal.npz"
    save_policy(causal, PolicyNetwork(KR500), {"platform": KR500.summary()})
    config = DpcTrainingConfig(
        compile=False,
        preview_steps=PREVIEW,
        preview_predictor="linear",
        time_stretch_fraction=0.0,
        initial_policy=str(causal),
        own_start_fraction=0.5,
        train=TrainConfig(batch_size=4, max_epochs=1, horizons=(100,), device="cpu"),
    )
    policy, policy_path = train_policy(config, path, tmp_path / "run", progress=False)
    assert policy.preview_steps == PREVIEW
    run = run_closed_loop(
        mca=DpcConfig(policy=str(policy_path), predictor="linear"),
        reference=smooth_flight(2.0),
        robot=KR500,
        progress=False,
    )
    assert run.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert FORECAST_PREVIEW_ARRAY not in ("F", "dF", "ddF", "S", "E")


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"preview_predictor": "learned"}, "preview_steps > 0"),
        ({"preview_predictor": "learned", "preview_steps": 8}, "time_stretch_fraction 0"),
        ({"preview_predictor": "oracle", "preview_steps": 8}, "unknown predictor"),
    ],
)
def test_bad_forecast_training_settings_are_refused(fields, message):
    with pytest.raises(ValueError, match=message):
        DpcTrainingConfig(**fields).validate()


def test_a_policy_file_keeps_the_predictive_dpcs_forecast(widened):
    from argparse import Namespace

    from mca_drake.app.cli.closed_loop_flags import mca_from_flags

    _, same, _ = widened
    config = mca_from_flags(Namespace(mca="dpc-predictive", policy=str(same)), DpcConfig())
    assert config == DpcConfig(policy=str(same), predictor="learned")


def test_every_policy_dpc_picks_by_vehicle_has_a_predictive_twin():
    from mca_drake.cueing.dpc import ENVELOPE_POLICIES, PREDICTIVE_TWINS, shipped_policy_path

    for causal in ("default_policy", "ground_policy", *ENVELOPE_POLICIES.values()):
        assert shipped_policy_path(PREDICTIVE_TWINS[causal]).is_file()
