"""Closed loops against stored runs: `tests/data/closed_loop_regression.npz` and `.json` hold
an 8 s built-in light flight (seed 1000) and the 3 s closed loop of every MCA on it on the
analytical plant (commands, states, outputs, PI, violations, solver failures).

Each path is compared as tightly as its arithmetic allows, so that any change of what the
code computes shows here:
- the flight exactly (atol = rtol = 0), and the washout's commands and states to
  `WASHOUT_TOLERANCE`: its filters are small matrix products, which numpy hands to BLAS,
  whose kernels (and so the last bits of a sum) depend on the CPU's vector instructions;
- the outputs and the PI to the round-off of the kinematics (`OUTPUT_TOLERANCE`), and so the
  DPC's commands and states too (the policy reads the plant's output);
- the NMPC runs to within `NMPC_TOLERANCE`: the stored runs and these reach the same QP
  and KKT solutions only to the solvers' tolerances (they differ by up to 7e-7 rad/s^2 in
  the commands and 4e-8 in the PI).

The multibody station is not in the fixture: `test_kr500_station.py` and
`test_station_limits.py` check it against independent oracles.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mca_drake.cueing import DpcConfig, NmpcConfig, WashoutConfig
from mca_drake.cueing.dpc import shipped_policy_path
from mca_drake.platforms.files import load_platform
from mca_drake.references.jsbsim import fly
from mca_drake.references.recording import Recording
from mca_drake.references.reference import reference_from_recording
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")

DATA = Path(__file__).parent / "data"
# Absolute tolerance of the NMPC runs (rad/s^2, rad, rad/s, output units and PI).
NMPC_TOLERANCE = 1e-6
# Absolute tolerance of the outputs and the PI: round-off of the kinematics (m/s^2, rad/s).
OUTPUT_TOLERANCE = 1e-12
# Absolute tolerance of the washout's commands and states (rad/s^2, rad, rad/s): round-off
# of its filters' matrix products on another CPU (1.1e-12 seen between two machines).
WASHOUT_TOLERANCE = 1e-11
# The MCAs as the fixture ran them, named explicitly so that tuned defaults do not change
# them: the paper reproduction's policy, the paper's NMPC weights, the classic washout.
MCAS = {
    "dpc": DpcConfig(policy=str(shipped_policy_path("policy_v6"))),
    "nmpc-rti": NmpcConfig.paper("rti"),
    "nmpc-converged": NmpcConfig.paper("converged"),
    "washout": WashoutConfig.classic(),
}


@pytest.fixture(scope="module")
def fixture():
    arrays = dict(np.load(DATA / "closed_loop_regression.npz"))
    meta = json.loads((DATA / "closed_loop_regression.json").read_text())
    return arrays, meta


def test_the_built_in_flight_matches_the_stored_one(fixture):
    arrays, _ = fixture
    recording = fly("light", 8.0, 1000, progress=False)
    np.testing.assert_array_equal(recording.t, arrays["recording_t"])
    np.testing.assert_array_equal(recording.omega, arrays["recording_omega"])
    np.testing.assert_array_equal(recording.f, arrays["recording_f"])


@pytest.mark.parametrize("mca", MCAS)
def test_each_mcas_closed_loop_matches_its_stored_run(mca):
    compare("analytical", mca)


def compare(plant: str, mca: str) -> None:
    """Runs one closed loop of the fixture and compares it with the stored run, to the
    tolerance of its MCA (see the module docstring)."""
    arrays = dict(np.load(DATA / "closed_loop_regression.npz"))
    meta = json.loads((DATA / "closed_loop_regression.json").read_text())
    recording = Recording(
        arrays["recording_t"], arrays["recording_omega"], arrays["recording_f"], {}
    )
    reference = reference_from_recording(recording, name="fixture")
    key = f"{plant}_{mca}"
    expected = meta["runs"][key]
    result = run_closed_loop(
        mca=MCAS[mca],
        reference=reference,
        plant=plant,
        duration_s=expected["duration_s"],
        progress=False,
        robot=KR500,
    )
    tolerances = {"nmpc": NMPC_TOLERANCE, "dpc": OUTPUT_TOLERANCE, "washout": WASHOUT_TOLERANCE}
    atol = tolerances.get(mca.split("-")[0], 0.0)
    for name in ("commands", "states", "outputs"):
        tolerance = max(atol, OUTPUT_TOLERANCE) if name == "outputs" else atol
        np.testing.assert_allclose(
            getattr(result, name), arrays[f"{key}_{name}"], rtol=0, atol=tolerance, err_msg=name
        )
    assert abs(result.summary["pi"] - expected["pi"]) <= max(atol, OUTPUT_TOLERANCE)
    assert result.summary["violations"] == expected["violations"]
    assert result.summary["solver_failures"] == expected["solver_failures"]
