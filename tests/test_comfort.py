"""The cabin comfort bound: its closed-form fraction against a search, and in every closed
loop (each MCA, both plants, live) the cabin's force changing no faster than the bound
except where the joint limits needed it, each such period counted."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.comfort import (
    COMFORT_TOLERANCE,
    ComfortConfig,
    comfort_fraction,
    force_changes,
)
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop


def test_the_fraction_is_the_largest_that_keeps_the_bound(rng):
    grid = np.linspace(0.0, 1.0, 20001)
    for _ in range(300):
        a, c = rng.normal(size=3) * rng.uniform(0.1, 3), rng.normal(size=3) * rng.uniform(0, 1)
        limit = rng.uniform(0.05, 2.0)
        alpha = comfort_fraction(a.tolist(), c.tolist(), limit)
        norms = np.linalg.norm(grid[:, None] * a + c, axis=1)
        if np.linalg.norm(c) <= limit:  # alpha = 0 keeps it: the largest alpha that does
            assert np.linalg.norm(alpha * a + c) <= limit + 1e-9
            assert alpha == pytest.approx(grid[norms <= limit + 1e-12].max(), abs=1e-4)
        else:  # the drift alone breaks it: the alpha that changes the force least
            assert np.linalg.norm(alpha * a + c) <= norms.min() + 1e-9
    assert comfort_fraction([0.0, 0.0, 0.0], [5.0, 0.0, 0.0], 1.0) == 1.0  # nothing to scale
    assert comfort_fraction([0.5, 0.0, 0.0], [0.0, 0.0, 0.0], 1.0) == 1.0  # inside it


def test_a_bound_that_cannot_hold_is_refused():
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match=r"ComfortConfig\.max_force_change"):
            ComfortConfig(bad).validate()
    assert not ComfortConfig().enabled and ComfortConfig(0.5).enabled


def surge_steps(seconds=6.0, h=0.01) -> Reference:
    """Sharp steps of surge and sway force, and a roll rate, to make every MCA jolt."""
    t = np.arange(round(seconds / h) + 1) * h
    y = np.zeros((t.size, 6))
    y[(t >= 1.0) & (t < 3.0), 3] = 2.0
    y[(t >= 2.0) & (t < 4.5), 4] = -1.5
    y[(t >= 3.5) & (t < 4.0), 0] = 0.3
    return Reference(y, h, "surge steps")


def checked(result, limit):
    """The run's comfort figures against its own outputs: every period within the bound
    but those counted as over it; zero violations."""
    summary = result.summary
    comfort = summary["comfort"]
    changes = force_changes(result.outputs)
    over = int(np.sum(changes > limit + COMFORT_TOLERANCE))
    assert comfort["exceeded_periods"] == over
    assert comfort["largest_force_change_m_s2"] == pytest.approx(changes.max())
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    return comfort, changes


@pytest.mark.parametrize("mca", ["washout", "dpc", "nmpc-rti"])
def test_every_mca_keeps_the_cabins_force_change_inside_the_bound(mca, robot):
    reference = surge_steps()
    free = run_closed_loop(mca=mca, reference=reference, robot=robot, progress=False)
    limit = 0.5 * force_changes(free.outputs).max()  # half of what it does unbounded
    bounded = run_closed_loop(
        mca=mca, reference=reference, robot=robot, progress=False, comfort=ComfortConfig(limit)
    )
    comfort, changes = checked(bounded, limit)
    assert comfort["bounded_periods"] > 0
    # the joint limits may need a harder change now and then; the bound holds elsewhere
    assert comfort["exceeded_periods"] <= 0.01 * changes.size
    assert changes.max() < force_changes(free.outputs).max()


def test_no_bound_is_the_run_without_one(robot):
    reference = surge_steps(3.0)
    plain = run_closed_loop(mca="washout", reference=reference, robot=robot, progress=False)
    off = run_closed_loop(
        mca="washout", reference=reference, robot=robot, progress=False, comfort=ComfortConfig()
    )
    np.testing.assert_array_equal(plain.outputs, off.outputs)
    assert "comfort" not in off.summary


def test_the_station_keeps_the_bound_too(robot):
    limit = 0.3
    result = run_closed_loop(
        mca="washout",
        reference=surge_steps(3.0),
        robot=robot,
        plant="multibody",
        progress=False,
        comfort=ComfortConfig(limit),
    )
    comfort, changes = checked(result, limit)
    assert comfort["bounded_periods"] > 0
    # the station tracks the bounded command through its controller: what the occupant
    # felt (the IMU) stays near the bound
    assert changes.max() < 2 * limit


def test_a_live_run_keeps_the_bound(robot):
    from test_live_loop import live_with_sender, stream_process

    summary = live_with_sender(
        stream_process, 2.2, "washout", 2.0, comfort=ComfortConfig(0.2), robot=robot
    )
    comfort = summary["comfort"]
    assert comfort["max_force_change_m_s2"] == 0.2 and comfort["bounded_periods"] > 0
    # (a stop in the stream washes out home: the supervisor's command, bounded the same)
    assert comfort["exceeded_periods"] <= 2
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}


def test_the_flag_sets_the_bound_and_the_suite_refuses_it():
    from mca_drake.app.cli import build_parser
    from mca_drake.app.cli.closed_loop_flags import closed_loop_scenario_from_flags
    from mca_drake.app.cli.evaluate import run_suite

    args = build_parser().parse_args(["simulate", "--max-force-change", "0.4"])
    assert closed_loop_scenario_from_flags(args).comfort.max_force_change == 0.4
    args = build_parser().parse_args(["evaluate", "--suite", "--max-force-change", "0.4"])
    with pytest.raises(ValueError, match="the suite cues without the bound"):
        run_suite(args)
