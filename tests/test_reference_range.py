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

from mca_drake.app.cli.report import OUT_OF_RANGE_NOTICE, policy_lines, suggests_nmpc
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


def test_the_report_suggests_the_nmpc_above_the_notice_share_only():
    """At the notice share the report keeps quiet, just above it says to compare the NMPC;
    a policy without a range (None) never does; the report's line and `suggests_nmpc`
    agree."""
    for share, expected in ((OUT_OF_RANGE_NOTICE, False), (OUT_OF_RANGE_NOTICE + 1e-9, True)):
        outside = {"share": share, "channels": dict.fromkeys(CHANNELS, share)}
        assert suggests_nmpc(outside) is expected
        summary = {"policy_file": "p.npz", "policy_reason": "r", "out_of_distribution": outside}
        said = any("compare --mca nmpc-rti" in line for line in policy_lines(summary))
        assert said is expected
    assert not suggests_nmpc(None)


def _policy_file(tmp_path, ranges: ReferenceRange):
    """A random policy saved with `ranges` in its metadata, and the torch network itself."""
    torch = pytest.importorskip("torch")
    from mca_drake.learning.policy_network import PolicyNetwork, save_policy

    torch.manual_seed(3)
    policy = PolicyNetwork(KR500)
    path = tmp_path / "ranged.npz"
    save_policy(path, policy, {"reference_range": ranges.record()})
    return path, policy


def test_a_clipping_dpc_reads_the_reference_at_the_edge_of_its_range(tmp_path, rng):
    """Oracle: the torch network evaluated on the reference clipped by hand, then the
    viability clamp; and the same DPC without clipping reads the reference as it is."""
    import torch
    from pydrake.systems.analysis import Simulator

    from mca_drake.safety import ViabilityClamp
    from mca_drake.systems.dpc import DpcPolicy

    ranges = ReferenceRange((-0.1, -0.1, -0.1, -1.0, -0.5, -2.0), (0.1, 0.1, 0.1, 2.0, 0.5, 3.0))
    path, policy = _policy_file(tmp_path, ranges)
    clamp = ViabilityClamp.for_robot(KR500, 0.01)

    def command(system, x, y, r):
        context = system.CreateDefaultContext()
        for port, value in (("state", x), ("inertial_output", y), ("reference", r)):
            system.GetInputPort(port).FixValue(context, value)
        Simulator(system, context).AdvanceTo(0.005)  # the update at t = 0
        return system.GetOutputPort("joint_acceleration").Eval(context)

    def torch_command(x, y, r):
        with torch.no_grad():
            u = policy(*(torch.tensor(v, dtype=torch.float32)[None] for v in (y, x, r)))[0]
        return clamp(x, u[0].double().numpy())[0]

    clipping, plain = DpcPolicy(path, KR500, range_clip=True), DpcPolicy(path, KR500)
    differences = []
    for _ in range(5):
        x = np.r_[rng.uniform(KR500.q_min, KR500.q_max) * 0.5, np.zeros(6)]
        y = rng.normal(size=6) * 0.1
        r = rng.normal(size=6) * 3.0  # mostly beyond the range
        clipped = np.clip(r, ranges.low, ranges.high)
        expected = torch_command(x, y, clipped)
        np.testing.assert_allclose(command(clipping, x, y, r), expected, atol=1e-5)
        np.testing.assert_allclose(command(plain, x, y, r), torch_command(x, y, r), atol=1e-5)
        differences.append(np.abs(command(clipping, x, y, r) - command(plain, x, y, r)).max())
    assert max(differences) > 1e-3  # the clip changed what the network read


def test_the_clip_leaves_a_reference_inside_the_range_and_a_non_finite_one_refused(tmp_path):
    ranges = ReferenceRange((-1.0,) * 6, (1.0,) * 6)
    path, _ = _policy_file(tmp_path, ranges)
    arrays, _ = load_policy_arrays(path)
    from mca_drake.cueing.dpc import PolicyInference

    clipping, plain = PolicyInference(arrays, ranges), PolicyInference(arrays)
    x, y, r = np.zeros(12), np.full(6, 0.2), np.linspace(-0.9, 0.9, 6)
    assert clipping.command(y, x, r) == plain.command(y, x, r)
    assert clipping.command(y, x, 5 * r) == plain.command(y, x, np.clip(5 * r, -1.0, 1.0))
    assert all(np.isnan(clipping.command(y, x, np.r_[np.nan, r[1:]])))


def test_the_reference_is_clipped_where_the_policy_is_recognized_unless_told_otherwise():
    assert DpcConfig().clips_reference()
    assert not DpcConfig(vehicle="light").clips_reference()
    assert not DpcConfig(unnamed="default").clips_reference()
    assert DpcConfig(vehicle="light", range_clip="always").clips_reference()
    assert not DpcConfig(range_clip="never").clips_reference()
    with pytest.raises(ValueError, match="range_clip"):
        DpcConfig(range_clip="sometimes").validate()
