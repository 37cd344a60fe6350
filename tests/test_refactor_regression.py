"""The same numbers as before the layering refactor (issue 15).

`tests/data/closed_loop_regression.npz` and `.json` were computed by the code path that the
refactor replaced (commit f31529d, `evaluation.run_closed_loop` and
`station_simulation.run_station_closed_loop`): an 8 s built-in light flight (seed 1000) and
the closed loop of every MCA on both plants (3 s analytical, 2 s multibody; the multibody
DPC run with IMU noise and a 2 ms measurement delay). The refactor moves code and must not
change a single floating-point operation on these paths, so the comparison is exact
(atol = rtol = 0) for the flight, the commands, the states and the outputs, and the PI.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mca_drake.evaluation import run_closed_loop
from mca_drake.references.jsbsim_flight import fly
from mca_drake.references.recording import Recording
from mca_drake.references.reference import reference_from_recording
from mca_drake.station_simulation import run_station_closed_loop
from mca_drake.systems.kr500_station import StationConfig

DATA = Path(__file__).parent / "data"
MCAS = ("dpc", "nmpc-rti", "nmpc-converged", "washout")


@pytest.fixture(scope="module")
def fixture():
    arrays = dict(np.load(DATA / "closed_loop_regression.npz"))
    meta = json.loads((DATA / "closed_loop_regression.json").read_text())
    return arrays, meta


@pytest.fixture(scope="module")
def reference(fixture):
    arrays, _ = fixture
    recording = Recording(
        arrays["recording_t"], arrays["recording_omega"], arrays["recording_f"], {}
    )
    return reference_from_recording(recording, name="fixture")


def test_the_built_in_flight_is_unchanged(fixture):
    arrays, _ = fixture
    recording = fly("light", 8.0, 1000, progress=False)
    np.testing.assert_array_equal(recording.t, arrays["recording_t"])
    np.testing.assert_array_equal(recording.omega, arrays["recording_omega"])
    np.testing.assert_array_equal(recording.f, arrays["recording_f"])


@pytest.mark.parametrize("plant", ["analytical", "multibody"])
@pytest.mark.parametrize("mca", MCAS)
def test_closed_loop_is_unchanged(fixture, reference, plant, mca):
    arrays, meta = fixture
    key = f"{plant}_{mca}"
    expected = meta["runs"][key]
    if plant == "analytical":
        result = run_closed_loop(
            mca=mca, reference=reference, duration_s=expected["duration_s"], progress=False
        )
    else:
        station = (
            StationConfig(
                accelerometer_noise_std=0.05,
                gyroscope_noise_std=0.002,
                measurement_delay_s=0.002,
            )
            if expected["noisy_station"]
            else StationConfig()
        )
        result = run_station_closed_loop(
            mca=mca,
            reference=reference,
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
