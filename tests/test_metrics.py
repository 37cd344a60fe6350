"""Metrics on hand-computable cases."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from mca_drake import metrics
from mca_drake.platforms import usage

T = np.linspace(0.0, 10.0, 1001)


def six(signal):
    return np.tile(np.asarray(signal)[:, None], (1, 6))


def test_identical_signals_give_minus_six():
    y = six(np.sin(T))
    assert metrics.performance_index(y, y) == pytest.approx(-6.0, abs=1e-12)


def test_identical_signals_with_a_still_channel_give_minus_six():
    y = six(np.sin(T))
    y[:, 2] = 0.0  # e.g. no yaw at all, rendered as no yaw at all
    assert metrics.performance_index(y, y) == pytest.approx(-6.0, abs=1e-12)


def test_a_still_channel_rendered_within_round_off_counts_as_rendered():
    """A solver's 1e-8 rad/s of noise on a still channel is still (CC 1); a 1e-3 wobble,
    which is motion, is not (CC 0: nothing to correlate with a still target)."""
    target = six(np.sin(T))
    target[:, 0] = 0.0
    noisy = target.copy()
    noisy[:, 0] = 1e-8 * np.sin(7 * T)
    assert metrics.pearson_cc(target, noisy)[0] == 1.0
    noisy[:, 0] = 1e-3 * np.sin(7 * T)
    assert metrics.pearson_cc(target, noisy)[0] == 0.0


def test_constant_offset_has_rmse_offset_and_cc_one():
    y = six(np.sin(T))
    score = metrics.tracking_score(y, y + 0.5)
    np.testing.assert_allclose(score.rmse, 0.5, atol=1e-12)
    np.testing.assert_allclose(score.cc, 1.0, atol=1e-12)
    assert score.pi == pytest.approx(6 * 0.5 - 6, abs=1e-10)


def test_known_rmse_and_correlation():
    """sin vs -sin: CC = -1, RMSE = 2 * rms(sin) = 2 / sqrt(2) over whole periods."""
    t = np.arange(0, 2 * np.pi * 10, 2 * np.pi * 10 / 100000)
    target = six(np.sin(t))
    score = metrics.tracking_score(target, -target)
    np.testing.assert_allclose(score.cc, -1.0, atol=1e-12)
    np.testing.assert_allclose(score.rmse, np.sqrt(2.0), rtol=1e-9)


def test_quadrature_signals_are_uncorrelated():
    t = np.arange(0, 2 * np.pi * 5, 2 * np.pi * 5 / 20000)
    np.testing.assert_allclose(metrics.pearson_cc(six(np.sin(t)), six(np.cos(t))), 0.0, atol=1e-9)


def test_cc_matches_scipy_on_random_signals(rng):
    a, b = rng.normal(size=(2, 500, 6))
    b = 0.4 * a + b
    expected = [scipy.stats.pearsonr(a[:, k], b[:, k]).statistic for k in range(6)]
    np.testing.assert_allclose(metrics.pearson_cc(a, b), expected, atol=1e-12)


def test_zero_motion_against_a_moving_target():
    """Doing nothing: RMSE = rms(target), CC defined as 0 (not NaN)."""
    target = six(2.0 * np.sin(T))
    score = metrics.tracking_score(target, np.zeros_like(target))
    assert np.all(np.isfinite(score.cc))
    np.testing.assert_allclose(score.cc, 0.0)
    np.testing.assert_allclose(score.rmse, np.sqrt(np.mean((2 * np.sin(T)) ** 2)), rtol=1e-12)


def test_wilcoxon_rank_sum_matches_scipy_and_detects_shift(rng):
    a = rng.normal(-2.0, 0.2, size=10)
    b = rng.normal(-1.0, 0.2, size=10)
    result = metrics.wilcoxon_rank_sum(a, b)
    z, p = scipy.stats.ranksums(a, b)
    assert (result.z, result.p) == pytest.approx((z, p))
    assert result.significant()
    # complete separation of 10 vs 10: U = 0, z = -(100/2) / sqrt(10*10*21/12)
    assert result.z == pytest.approx(-50 / np.sqrt(175.0))
    same = metrics.wilcoxon_rank_sum(a, a)
    assert same.p == pytest.approx(1.0) and not same.significant()


def test_normalized_usage_keeps_neutral_and_maps_limits(robot):
    q = np.array([robot.q_max, robot.q_min, np.zeros(6), robot.q_max / 2])
    normalised = usage.normalized_joint_usage(q, robot.q_min, robot.q_max)
    np.testing.assert_allclose(normalised, [np.ones(6), -np.ones(6), np.zeros(6), np.full(6, 0.5)])


def test_violation_counts_per_limit_type(robot):
    n = 10
    q, qd, qdd = np.zeros((n, 6)), np.zeros((n, 6)), np.zeros((n, 6))
    q[3, 1] = robot.q_max[1] + 0.01  # one sample over on joint 2
    q[4, 2] = robot.q_min[2] - 0.01  # one under on joint 3
    qd[7, :] = robot.qd_max * 1.5  # one sample, all joints: still one sample
    qdd[2, 5] = robot.qdd_max[5]  # exactly at the limit: not a violation
    assert usage.limit_violations(q, qd, qdd, robot) == {"q": 2, "qd": 1, "qdd": 0}
    peak = usage.joint_usage(q, qd, qdd, robot).peak()
    np.testing.assert_allclose(peak["qd"], 1.5)


@pytest.mark.parametrize(
    ("target", "achieved", "match"),
    [
        (np.zeros((10, 6)), np.zeros((10, 5)), "shapes must match"),
        (np.zeros((10, 5)), np.zeros((10, 5)), "must have 6 channels"),
        (np.zeros((1, 6)), np.zeros((1, 6)), "T >= 2"),
        (np.full((10, 6), np.nan), np.zeros((10, 6)), "target has non-finite"),
    ],
)
def test_bad_signals_are_reported(target, achieved, match):
    with pytest.raises(ValueError, match=match):
        metrics.tracking_score(target, achieved)


def test_bad_rank_sum_input():
    with pytest.raises(ValueError, match="at least 2"):
        metrics.wilcoxon_rank_sum([1.0], [1.0, 2.0])


def test_wilcoxon_signed_rank_exact_closed_form():
    # five pairs, all in favour of a: the exact two-sided p is 2 / 2^5 (one extreme sign
    # pattern at each end of the 2^5 equally likely ones)
    a = np.array([-1.0, -2.0, -0.5, -1.5, -0.7])
    b = a + np.array([0.3, 0.1, 0.5, 0.2, 0.4])
    result = metrics.wilcoxon_signed_rank(a, b)
    assert result.n == 5 and result.a_better == 5
    assert result.p == pytest.approx(2 / 32)
    assert result.median_difference == pytest.approx(-0.3)
    # mirrored pairs: same p, no wins; identical samples carry no evidence
    assert metrics.wilcoxon_signed_rank(b, a).p == pytest.approx(2 / 32)
    assert metrics.wilcoxon_signed_rank(b, a).a_better == 0
    assert metrics.wilcoxon_signed_rank(a, a).p == 1.0
    with pytest.raises(ValueError, match="paired"):
        metrics.wilcoxon_signed_rank(a, b[:4])


def test_joint_range_used_is_the_swept_share_of_each_range(robot):
    q = np.zeros((3, 6))
    q[0, 0], q[2, 0] = robot.q_min[0] / 2, robot.q_max[0] / 2  # half of joint 1's range
    q[1, 4] = robot.q_max[4]  # from 0 to the upper limit of joint 5
    used = usage.joint_range_used(q, robot)
    np.testing.assert_allclose(used[0], 0.5, atol=1e-12)
    expected = robot.q_max[4] / (robot.q_max[4] - robot.q_min[4])
    np.testing.assert_allclose(used[4], expected, atol=1e-12)
    assert used[1] == used[2] == used[3] == used[5] == 0.0


def test_false_rotation_on_hand_computable_cases():
    """Closed-form cases: a faithful, a scaled-down and a missing rotation are not false; a
    rotation the wrong way is false at its whole rate, more than the vehicle's at the excess."""
    target = np.zeros((1000, 6))
    target[:, 0] = np.radians(10.0)  # 10 deg/s of roll throughout
    assert metrics.false_rotation(target, target).rms_deg_s == pytest.approx(0.0)
    assert metrics.false_rotation(target, 0.5 * target).share_felt == 0.0
    assert metrics.false_rotation(target, np.zeros_like(target)).rms_deg_s == 0.0
    wrong_way = -target
    result = metrics.false_rotation(target, wrong_way)
    assert result.rms_deg_s == pytest.approx(10.0)
    assert result.share_felt == 1.0
    # 2 deg/s more than the vehicle's: below the 3 deg/s roll threshold, never felt
    excess = target.copy()
    excess[:, 0] += np.radians(2.0)
    result = metrics.false_rotation(target, excess)
    assert result.rms_deg_s == pytest.approx(2.0)
    assert result.share_felt == 0.0
    # a yaw of 4 deg/s half the time where the vehicle has none: over the 2.6 deg/s threshold
    spurious = target.copy()
    spurious[::2, 2] = np.radians(4.0)
    result = metrics.false_rotation(target, spurious)
    assert result.rms_deg_s == pytest.approx(np.sqrt(0.5 * 16.0))
    assert result.share_felt == pytest.approx(0.5)
    # the thresholds combine: 2.4 deg/s of roll and 2.9 of pitch, each below its own
    both = np.zeros((10, 6))
    both[:, 0], both[:, 1] = np.radians(2.4), np.radians(2.9)
    assert metrics.false_rotation(np.zeros((10, 6)), both).share_felt == 1.0
    with pytest.raises(ValueError, match="channels"):
        metrics.false_rotation(np.zeros((10, 3)), np.zeros((10, 3)))


def test_jolts_are_the_largest_changes_between_two_samples():
    """Closed form: a surge ramp of 2 m/s^3 and one lateral step of 0.3 m/s^2 at 100 Hz; a
    roll rate ramp of 0.5 rad/s^2."""
    from mca_drake.metrics import jolts

    h = 0.01
    t = np.arange(200) * h
    y = np.zeros((200, 6))
    y[:, 3] = 2.0 * t
    y[120:, 4] = 0.3
    y[:, 0] = 0.5 * t
    found = jolts(y, h)
    step = np.hypot(0.3, 2.0 * h)  # the lateral step, in the period the ramp also moves
    assert found.peak_force_change_m_s2 == pytest.approx(step)
    assert found.peak_jerk_m_s3 == pytest.approx(step / h)
    assert found.peak_angular_acceleration_rad_s2 == pytest.approx(0.5)
    assert jolts(y[:1], h).peak_jerk_m_s3 == 0.0
    with pytest.raises(ValueError, match="time_step"):
        jolts(y, 0.0)
