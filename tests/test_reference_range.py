"""The guard for the unseen: the range of the references a DPC policy was trained on, and the
share of a run's reference outside it (`mca_drake.cueing.reference_range`), in the summary
and the printed report.

Oracles: quantiles of evenly spaced samples in closed form (linear interpolation: the q
quantile of 0..N-1 is q (N - 1)); shares counted by construction.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from mca_drake.app.cli.report import policy_lines
from mca_drake.conventions import CHANNELS
from mca_drake.cueing.dpc import DpcConfig, load_policy_arrays, shipped_policy_path
from mca_drake.cueing.reference_range import (
    RANGE_QUANTILE,
    ReferenceRange,
    policy_reference_range,
    reference_range,
    run_outside,
    shipped_ranges,
)
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.resources import MOVED_POLICIES
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")


def test_the_range_is_the_quantiles_of_the_training_references():
    n = 10001
    y = np.tile(np.arange(n, dtype=float)[:, None], (1, 6))
    plain = reference_range([y[:5000], y[5000:]], mirrored=False)
    assert plain.low == pytest.approx([RANGE_QUANTILE * (n - 1)] * 6)
    assert plain.high == pytest.approx([(1 - RANGE_QUANTILE) * (n - 1)] * 6)
    # mirrored: roll and yaw rates and the lateral force take both signs, symmetric
    mirrored = reference_range([y], mirrored=True)
    for i, channel in enumerate(CHANNELS):
        if channel in ("w_x", "w_z", "f_y"):
            assert mirrored.low[i] == pytest.approx(-mirrored.high[i])
            assert mirrored.high[i] == pytest.approx((1 - 2 * RANGE_QUANTILE) * (n - 1), rel=1e-3)
        else:
            assert (mirrored.low[i], mirrored.high[i]) == pytest.approx(
                (plain.low[i], plain.high[i])
            )


def test_the_share_outside_counts_the_periods_of_each_policy_against_its_own_range():
    wide = ReferenceRange((-1.0,) * 6, (1.0,) * 6, "wide")
    narrow = ReferenceRange((-0.5,) * 6, (0.5,) * 6, "narrow")
    y = np.zeros((100, 6))
    y[10:20, 4] = 2.0  # outside both
    y[30:40, 0] = 0.8  # outside the narrow range only: the first policy's time
    y[60:70, 0] = 0.8  # ...and the second policy's, from t = 0.5 s
    record = run_outside(y, [(0.0, wide), (0.5, narrow)], 0.01)
    assert record["share"] == pytest.approx(0.2)
    assert record["channels"]["f_y"] == pytest.approx(0.1)
    assert record["channels"]["w_x"] == pytest.approx(0.1)
    assert run_outside(y, [(0.0, wide), (0.5, None)], 0.01) is None


def test_bad_ranges_are_refused():
    with pytest.raises(ValueError, match="lows"):
        ReferenceRange((1.0,) * 6, (0.0,) * 6)
    with pytest.raises(ValueError, match="6 lows"):
        ReferenceRange((0.0,) * 5, (1.0,) * 5)
    with pytest.raises(ValueError, match="'low' and 'high'"):
        ReferenceRange.from_record({"low": [0.0] * 6})
    with pytest.raises(ValueError, match="numbers"):
        ReferenceRange.from_record({"low": ["a"] * 6, "high": [1.0] * 6})


def test_every_shipped_policy_has_its_range_and_a_moved_one_the_kr500s():
    ranges = shipped_ranges()
    assert set(MOVED_POLICIES) <= set(ranges)
    for name in MOVED_POLICIES:
        path = shipped_policy_path(name)
        assert policy_reference_range(path, load_policy_arrays(path)[1]) == ranges[name]
        moved = shipped_policy_path(f"kr500-rail_{name}")
        assert policy_reference_range(moved, {}) == ranges[name]
    # the ground policy learned the cars' lateral forces, the flight policies did not
    f_y = CHANNELS.index("f_y")
    assert ranges["ground_policy"].high[f_y] > ranges["default_policy"].high[f_y]
    own = ReferenceRange((-2.0,) * 6, (2.0,) * 6, "own")
    assert policy_reference_range(path, {"reference_range": own.record()}) == own
    assert policy_reference_range("results/policy/policy.npz", {}) is None


def _cornering(seconds: float) -> Reference:
    """A car holding a bend: a lateral force no flight policy was trained on, a yaw rate."""
    y = np.zeros((round(seconds * 100), 6))
    y[:, 4], y[:, 2] = 3.5, 0.15
    return Reference(y, 0.01, "logger.csv")


def test_a_run_says_how_much_of_its_reference_its_policy_never_saw(tmp_path):
    flight = run_closed_loop(
        mca=DpcConfig(unnamed="default"), reference=_cornering(3.0), robot=KR500, progress=False
    )
    outside = flight.summary["out_of_distribution"]
    assert outside["share"] > 0.9 and outside["channels"]["f_y"] > 0.9
    lines = policy_lines(flight.summary)
    assert any("compare --mca nmpc-rti" in line for line in lines), lines
    json.dumps(flight.summary)  # the record is JSON-ready
    ground = run_closed_loop(
        mca=DpcConfig(profile="ground"), reference=_cornering(3.0), robot=KR500, progress=False
    )
    assert ground.summary["out_of_distribution"]["channels"]["f_y"] == 0.0
