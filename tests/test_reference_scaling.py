"""A scenario's own reference scaling: what the MCA cues changes, the score does not.

Oracles: the scaling formula applied to the vehicle's motion itself (`scaled_reference` of
omega and f), and a run on a reference built at that scaling from the recording."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from mca_drake.app import cli
from mca_drake.app.scenarios import load_scenario
from mca_drake.metrics import performance_index
from mca_drake.platforms.files import load_platform
from mca_drake.references.recording import Recording, save_recording
from mca_drake.references.reference import (
    ReferenceScaling,
    reference_from_recording,
    rescaled_reference,
    rescaled_reference_sample,
    scaled_reference,
)
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.systems.reference_scaling import AddReferenceScaling, ReferenceScaler

REPO = Path(__file__).resolve().parents[1]
G = 9.81
SCALINGS = [
    ReferenceScaling(angular_scale=0.3, force_scale=0.7),
    ReferenceScaling(force_scale=0.3, limits=[0.2, 0.2, 0.2, 1.0, 1.0, 1.0]),
    ReferenceScaling(angular_scale=1.0, limits=[0.4, 0.3, 0.2, 1.0, 2.0, 3.0], limit_mode="tanh"),
    ReferenceScaling(angular_scale=0.0, force_scale=0.0),
]


def vehicle_motion(rng, n=300):
    omega = rng.normal(scale=0.6, size=(n, 3))
    f = rng.normal(scale=5.0, size=(n, 3))
    f[:, 2] += G
    return omega, f


@pytest.mark.parametrize("scaling", SCALINGS)
def test_rescaling_the_default_reference_equals_scaling_the_vehicle_motion(scaling, rng):
    omega, f = vehicle_motion(rng)
    expected = scaled_reference(omega, f, scaling)
    default = scaled_reference(omega, f, ReferenceScaling())
    np.testing.assert_allclose(rescaled_reference(default, scaling), expected, atol=1e-12)
    one = [rescaled_reference_sample(y.tolist(), scaling.factors(), scaling) for y in default]
    np.testing.assert_allclose(one, expected, atol=1e-12)


@pytest.mark.parametrize("scaling", SCALINGS[:3])
def test_the_scaler_system_outputs_the_scaled_reference_and_preview(scaling, rng):
    omega, f = vehicle_motion(rng, n=4)
    default = scaled_reference(omega, f, ReferenceScaling())
    expected = scaled_reference(omega, f, scaling)
    scaler = ReferenceScaler(scaling, preview_samples=4)
    context = scaler.CreateDefaultContext()
    scaler.GetInputPort("reference").FixValue(context, default[0])
    scaler.GetInputPort("reference_preview").FixValue(context, default.reshape(-1))
    got = scaler.GetOutputPort("scaled_reference").Eval(context)
    np.testing.assert_allclose(got, expected[0], atol=1e-12)
    preview = scaler.GetOutputPort("scaled_reference_preview").Eval(context)
    np.testing.assert_allclose(preview.reshape(4, 6), expected, atol=1e-12)


def test_the_default_scaling_adds_nothing_to_the_diagram():
    builder = DiagramBuilder()
    scaler = builder.AddSystem(ReferenceScaler(SCALINGS[0]))
    port = scaler.GetOutputPort("scaled_reference")
    assert AddReferenceScaling(builder, port, ReferenceScaling()) == (port, None)
    assert AddReferenceScaling(builder, port, None) == (port, None)


def surge_and_roll_recording(seconds=6.0, h=0.01) -> Recording:
    t = np.arange(round(seconds / h) + 1) * h
    omega = np.stack([0.2 * np.sin(1.3 * t), 0.05 * np.sin(0.7 * t), 0 * t], axis=1)
    f = np.stack([2.5 * np.sin(0.9 * t), 1.0 * np.cos(0.5 * t), G + 0.8 * np.sin(2 * t)], axis=1)
    return Recording(t, omega, f)


def test_a_scaled_run_cues_the_scaled_reference_and_is_scored_at_the_default():
    """The run with force_scale 0.25 commands what a run on the reference built at 0.25
    from the recording commands; its PI is that of its outputs against the default
    reference, and its summary records the scaling."""
    robot = load_platform("kr500")
    recording = surge_and_roll_recording()
    scaling = ReferenceScaling(force_scale=0.25, limits=[0.3, 0.3, 0.3, 0.5, 0.5, 0.5])
    default = reference_from_recording(recording)
    scaled = run_closed_loop(
        mca="washout", reference=default, robot=robot, scaling=scaling, progress=False
    )
    oracle = run_closed_loop(
        mca="washout",
        reference=reference_from_recording(recording, scaling),
        robot=robot,
        progress=False,
    )
    np.testing.assert_allclose(scaled.commands, oracle.commands, rtol=0, atol=1e-12)
    np.testing.assert_allclose(scaled.reference, default.y[: len(scaled.reference)], atol=1e-15)
    expected_pi = performance_index(default.y[: len(scaled.outputs)], scaled.outputs)
    assert scaled.summary["pi"] == pytest.approx(expected_pi, abs=1e-9)
    assert abs(scaled.summary["pi"] - oracle.summary["pi"]) > 1e-3  # scored differently
    assert scaled.summary["scaling"] == {
        "angular_scale": 0.5,
        "force_scale": 0.25,
        "limits": [0.3, 0.3, 0.3, 0.5, 0.5, 0.5],
        "limit_mode": "clip",
    }
    assert oracle.summary["scaling"]["force_scale"] == 0.5


def test_set_and_the_flag_change_what_the_mca_cues(tmp_path):
    """`run --set '{scaling: {force_scale: 0.3}}'` and `simulate --force-scale 0.3` run the
    same cue, not the default one, and both summaries say so."""
    path = tmp_path / "flight.csv"
    save_recording(path, surge_and_roll_recording(seconds=3.0))
    common = {"plant": "analytical", "mca": "washout", "duration_s": 3.0}
    scenario = json.dumps(common | {"flight": {"recording": str(path)}})
    summaries = {}
    for label, argv in (
        ("default", ["run", str(REPO / "diagrams/closed_loop_dpc.yaml"), "--set", scenario]),
        (
            "set",
            [
                *("run", str(REPO / "diagrams/closed_loop_dpc.yaml"), "--set", scenario),
                *("--set", "{scaling: {force_scale: 0.3}}"),
            ],
        ),
        (
            "flag",
            [
                *("simulate", "--plant", "analytical", "--mca", "washout"),
                *("--reference", str(path), "--force-scale", "0.3", "--plots", ""),
            ],
        ),
    ):
        out = tmp_path / f"{label}.json"
        assert cli.main([*argv, "--json", str(out), "--quiet"]) == 0
        summaries[label] = json.loads(out.read_text())
    assert summaries["set"]["scaling"]["force_scale"] == 0.3
    assert summaries["flag"]["scaling"]["force_scale"] == 0.3
    assert summaries["default"]["scaling"]["force_scale"] == 0.5
    assert summaries["set"]["pi"] == pytest.approx(summaries["flag"]["pi"], abs=1e-12)
    assert abs(summaries["set"]["pi"] - summaries["default"]["pi"]) > 1e-3
    # the same reference is scored: zero motion's PI does not move
    assert summaries["set"]["pi_zero_motion"] == pytest.approx(
        summaries["default"]["pi_zero_motion"], abs=1e-12
    )


@pytest.mark.parametrize(
    ("override", "match"),
    [
        ("{scaling: {force_scale: -1.0}}", "scaling: angular_scale and force_scale"),
        ("{scaling: {limits: [1.0, 2.0]}}", "scaling: limits must be six"),
        ("{scaling: {limit_mode: soft}}", "scaling: unknown limit_mode"),
        ("{scaling: {force_gain: 1.0}}", "force_gain"),
    ],
)
def test_a_bad_scaling_is_refused_naming_the_field(override, match):
    with pytest.raises(ValueError, match=match):
        load_scenario(REPO / "diagrams/closed_loop_dpc.yaml", override).validate()


def test_the_suite_refuses_a_scaling(capsys):
    assert cli.main(["evaluate", "--suite", "--force-scale", "0.3"]) != 0
    assert "the suite cues at the default scaling" in capsys.readouterr().err
