"""The `mca-drake` command end to end on short runs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mca_drake import cli
from mca_drake.demo_motion import demo_joint_motion
from mca_drake.diagrams import PlantDemoScenario, load_scenario
from mca_drake.jobs import run_plant_demo
from mca_drake.kinematics import plant_output

REPO = Path(__file__).resolve().parent.parent


def test_plant_demo_follows_the_demo_motion(robot):
    """The discrete plant under the sampled demo accelerations tracks the analytic demo
    trajectory, stays in limits, and its logged outputs are y of its logged states.

    Sampling qdd at the start of each step (left Riemann sum) bounds the velocity error by
    h * max|qdd| (about 0.014 rad/s here) and the position error by t times that."""
    duration, h = 4.0, 0.01
    result = run_plant_demo(scenario=PlantDemoScenario(duration_s=duration), progress=False)
    q, qd, _ = demo_joint_motion(result.times, robot)
    qd_bound = h * robot.qdd_max.max()
    np.testing.assert_allclose(result.states[:, 6:], qd, atol=qd_bound)
    np.testing.assert_allclose(result.states[:, :6], q, atol=duration * qd_bound)
    np.testing.assert_allclose(
        result.outputs,
        plant_output(result.states[:, :6], result.states[:, 6:], result.accelerations, robot),
        atol=1e-12,
    )
    assert result.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert result.times[-1] == pytest.approx(4.0)


def test_simulate_command_writes_json_and_plot(tmp_path, capsys):
    out_json, out_png = tmp_path / "out.json", tmp_path / "out.png"
    code = cli.main(
        ["simulate", "--duration", "1", "--json", str(out_json), "--plot", str(out_png), "--quiet"]
    )
    assert code == 0
    summary = json.loads(out_json.read_text())
    assert summary["plant"] == "analytical" and summary["duration_s"] == 1.0
    assert out_png.stat().st_size > 10_000
    assert "f_x" in capsys.readouterr().out


def test_every_scenario_file_loads_and_runs():
    files = sorted((REPO / "diagrams").glob("*.yaml"))
    assert files, "diagrams/ has no scenario files"
    for path in files:
        scenario = load_scenario(path, "{scenario: {duration_s: 0.2}}")
        assert scenario.duration_s == 0.2
        run_plant_demo(scenario=scenario, progress=False)


@pytest.mark.parametrize(
    ("override", "match"),
    [
        ("{scenario: {durration_s: 2}}", "unknown to the schema"),
        ("{scenario: {duration_s: abc}}", "could not convert"),
        ("{scenario: {duration_s: -1}}", "duration_s must be positive"),
    ],
)
def test_bad_scenario_values_fail_clearly(override, match):
    with pytest.raises(ValueError, match=match):
        load_scenario(REPO / "diagrams" / "plant_demo.yaml", override)


def test_console_script_reports_errors_without_traceback():
    result = subprocess.run(
        [sys.executable, "-m", "mca_drake.cli", "run", "no/such/file.yaml"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 2
    assert "scenario file not found" in result.stderr
    assert "Traceback" not in result.stderr
