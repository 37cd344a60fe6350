"""The same numbers as before the layering refactor (issue 15).

`tests/data/closed_loop_regression.npz` and `.json` were computed by the code path that the
refactor replaced (commit f31529d, `evaluation.run_closed_loop`, now
`simulation.closed_loop.run_closed_loop`): an 8 s built-in light flight (seed 1000) and the
3 s closed loop of every MCA on the analytical plant. The refactor moved code and must not
change a single floating-point operation on these paths, so the comparison is exact
(atol = rtol = 0) for the flight, the commands, the states and the outputs, and the PI.

The fixture's multibody runs were compared the same way until issue 16 changed the station
on purpose (a command limiter and the plant's own integration step for the desired
trajectory); `test_kr500_station.py` and `test_station_limits.py` cover it now.

Issue 18 changed how the NMPC solves its QPs, on purpose: a verified active-set solve
replaces OSQP's approximate solution (rti) and a quasi-Newton term and a KKT stop shorten the
Gauss-Newton iterations (converged). The NMPC runs are therefore compared to within
`NMPC_TOLERANCE` (the largest difference measured at that change: 3e-7 rad/s^2 in the
commands, 2e-8 in the PI), everything else still exactly.

Issue 18 later replaced the quasi-Newton term by Newton models from learnt output Hessians
(`mca_drake.cueing.output_curvature`): the same KKT points to the same tolerance, here
within 7e-7 rad/s^2 of the fixture's commands and 4e-8 of its PI.

Issue 18 also replaced the kinematics' method (twists and closed-form Jacobians instead of
forward-mode jets, `mca_drake.kinematics`): the same outputs in another order of floating-
point operations, so the outputs and the PI are compared to round-off (`OUTPUT_TOLERANCE`),
and so are the DPC's commands and states (the policy reads the plant's output); the
washout's commands and states still exactly.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mca_drake.cueing import DpcConfig, NmpcConfig, WashoutConfig
from mca_drake.cueing.dpc import shipped_policy_path
from mca_drake.references.jsbsim import fly
from mca_drake.references.recording import Recording
from mca_drake.references.reference import reference_from_recording
from mca_drake.simulation.closed_loop import run_closed_loop

DATA = Path(__file__).parent / "data"
# Absolute tolerance of the NMPC runs (rad/s^2, rad, rad/s, output units and PI).
NMPC_TOLERANCE = 1e-6
# Absolute tolerance of the outputs and the PI: round-off of the kinematics (m/s^2, rad/s).
OUTPUT_TOLERANCE = 1e-12
# The MCAs as the fixture ran them: the defaults of f31529d, named explicitly so that
# tuned defaults do not change them.
MCAS = {
    "dpc": DpcConfig(policy=str(shipped_policy_path("policy_v6"))),  # shipped at f31529d
    "nmpc-rti": NmpcConfig.paper("rti"),
    "nmpc-converged": NmpcConfig.paper("converged"),
    "washout": WashoutConfig.classic(),
}


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


@pytest.mark.parametrize("mca", MCAS)
def test_closed_loop_is_unchanged(mca):
    compare("analytical", mca)


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
    result = run_closed_loop(
        mca=MCAS[mca],
        reference=reference,
        plant=plant,
        duration_s=expected["duration_s"],
        progress=False,
    )
    atol = {"nmpc": NMPC_TOLERANCE, "dpc": OUTPUT_TOLERANCE}.get(mca.split("-")[0], 0.0)
    for name in ("commands", "states", "outputs"):
        tolerance = max(atol, OUTPUT_TOLERANCE) if name == "outputs" else atol
        np.testing.assert_allclose(
            getattr(result, name), arrays[f"{key}_{name}"], rtol=0, atol=tolerance, err_msg=name
        )
    assert abs(result.summary["pi"] - expected["pi"]) <= max(atol, OUTPUT_TOLERANCE)
    assert result.summary["violations"] == expected["violations"]
    assert result.summary["solver_failures"] == expected["solver_failures"]
