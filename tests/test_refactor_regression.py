"""The same numbers as before the layering refactor (issue 15).

`tests/data/closed_loop_regression.npz` and `.json` were computed by the code path that the
refactor replaced (commit f31529d, `evaluation.run_closed_loop` and
`station_simulation.run_station_closed_loop`, now both
`simulation.closed_loop.run_closed_loop`): an 8 s built-in light flight (seed 1000) and
the closed loop of every MCA on both plants (3 s analytical, 2 s multibody; the multibody
DPC run with IMU noise and a 2 ms measurement delay). The refactor moves code and must not
change a single floating-point operation on these paths, so the comparison is exact
(atol = rtol = 0) for the flight, the commands, the states and the outputs, and the PI.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mca_drake.references.jsbsim import fly
from mca_drake.references.recording import Recording
from mca_drake.references.reference import reference_from_recording
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.systems.kr500_station import StationConfig

DATA = Path(__file__).parent / "data"
MCAS = ("dpc", "nmpc-rti", "nmpc-converged", "washout")


@pytest.fixture(scope="module")
def fixture():
    arrays = dict(np.load(DATA / "closed_loop_regression.npz"))
    meta = json.loads((DATA / "closed_loop_regression.json").read_text())
    return arrays, meta


def test_the_built_in_flight_is_unchanged(fixture):
    arrays, _ = fixture
    recording = fly("light", 8.0, 1000, progress=False)
    np.testing.assert_array_equal(recording.t, arrays["recording_t"])
    np.testing.assert_array_equal(recording.omega, arrays["recording_omega"])
    np.testing.assert_array_equal(recording.f, arrays["recording_f"])


def _fresh_process_run(plant: str, mca: str) -> None:
    """Runs the comparison in a new Python process.

    The noisy multibody run draws its IMU noise from Drake's RandomSource with its default
    seed, which Drake takes from a process-wide counter: the fixture was made in a fresh
    process whose first RandomSource it was, so only a fresh process reproduces it.
    """
    code = (
        "import sys; sys.path.insert(0, 'tests'); import test_refactor_regression as t; "
        f"t.compare({plant!r}, {mca!r})"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=DATA.parents[1]
    )
    assert result.returncode == 0, result.stderr[-3000:]


@pytest.mark.parametrize("plant", ["analytical", "multibody"])
@pytest.mark.parametrize("mca", MCAS)
def test_closed_loop_is_unchanged(plant, mca):
    if plant == "multibody" and mca == "dpc":
        _fresh_process_run(plant, mca)
    else:
        compare(plant, mca)


def compare(plant: str, mca: str) -> None:
    """Runs one closed loop of the fixture and compares it exactly."""
    arrays = dict(np.load(DATA / "closed_loop_regression.npz"))
    meta = json.loads((DATA / "closed_loop_regression.json").read_text())
    recording = Recording(
        arrays["recording_t"], arrays["recording_omega"], arrays["recording_f"], {}
    )
    reference = reference_from_recording(recording, name="fixture")
    key = f"{plant}_{mca}"
    expected = meta["runs"][key]
    station = None
    if plant == "multibody":
        noisy = expected["noisy_station"]
        station = StationConfig(
            accelerometer_noise_std=0.05 if noisy else 0.0,
            gyroscope_noise_std=0.002 if noisy else 0.0,
            measurement_delay_s=0.002 if noisy else 0.0,
        )
    result = run_closed_loop(
        mca=mca,
        reference=reference,
        plant=plant,
        duration_s=expected["duration_s"],
        station=station,
        progress=False,
    )
    np.testing.assert_array_equal(result.commands, arrays[f"{key}_commands"])
    np.testing.assert_array_equal(result.states, arrays[f"{key}_states"])
    np.testing.assert_array_equal(result.outputs, arrays[f"{key}_outputs"])
    assert result.summary["pi"] == expected["pi"]
    assert result.summary["violations"] == expected["violations"]
    assert result.summary["solver_failures"] == expected["solver_failures"]
