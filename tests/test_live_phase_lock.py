"""The phase lock's correction on synthetic waits with a known answer."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.live.phase_lock import PhaseLockConfig, phase_correction

H = 0.01


def waits(centre_s, spread_s, n=200, seed=0):
    """Waits (poll - arrival) of a periodic sender whose samples arrive with a uniform
    jitter of `spread_s` behind a fixed phase, wrapped onto one period as a receiver sees
    them (a sample arriving after its poll waits for the next one)."""
    rng = np.random.default_rng(seed)
    return np.mod(centre_s - rng.uniform(0, spread_s, n), H)


def test_the_polls_move_earlier_by_the_wait_beyond_the_margin():
    config = PhaseLockConfig(margin_s=3e-4, quantile=0.02, max_slew_s=0.005)
    # waits 3.0 to 3.2 ms: the shortest (2 % quantile) is about 3.004 ms, so the polls can
    # come 3.004 - 0.3 = 2.704 ms earlier
    shift = phase_correction(waits(3.2e-3, 2e-4), H, config)
    assert shift == pytest.approx(3.2e-3 - 2e-4 * 0.98 - 3e-4, abs=2e-5)


def test_a_large_shift_is_slewed_the_shorter_way_over_several_windows():
    config = PhaseLockConfig(max_slew_s=0.002)
    # waits of 4 ms: 3.7 ms earlier (not 6.3 ms later), at most 2 ms per window
    assert phase_correction(waits(4.1e-3, 1e-4), H, config) == pytest.approx(0.002)
    # waits of 8 ms: 2.3 ms later is the shorter way round than 7.7 ms earlier
    assert phase_correction(waits(8.1e-3, 1e-4), H, config) == pytest.approx(-0.002)


def test_samples_missing_their_poll_move_the_polls_later():
    """Arrivals just after the poll wait almost a whole period: on the circle that is a
    negative wait, and the polls must come later, not earlier by 9 ms."""
    config = PhaseLockConfig(margin_s=3e-4, quantile=0.02)
    w = waits(1e-4, 4e-4)  # some arrive up to 0.3 ms after their poll
    assert np.any(w > 0.009)
    shift = phase_correction(w, H, config)
    # the latest usual arrival is 1e-4 - 0.98 * 4e-4 = -0.292 ms: 0.592 ms later
    assert shift == pytest.approx(1e-4 - 4e-4 * 0.98 - 3e-4, abs=2e-5)
    assert shift < 0


def test_no_correction_without_a_steady_phase_or_samples():
    config = PhaseLockConfig()
    rng = np.random.default_rng(1)
    assert phase_correction(rng.uniform(0, H, 300), H, config) == 0.0  # any phase
    assert phase_correction(waits(5e-3, 1e-4, n=5), H, config) == 0.0  # too few
    # within the deadband of the margin
    assert phase_correction(waits(config.margin_s + 1e-4, 1e-4), H, config) == 0.0
    off = PhaseLockConfig(enabled=False)
    assert phase_correction(waits(5e-3, 1e-4), H, off) == 0.0


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="quantile"):
        PhaseLockConfig(quantile=0.7).validate()
    with pytest.raises(ValueError, match="max_slew_s"):
        PhaseLockConfig(window_s=0.01, max_slew_s=0.005).validate()


def test_windows_end_between_control_instants():
    """The lock's windows end half a period after a control instant, never on one: the
    Python between windows must not fall between a sample's poll and its MCA update."""
    from mca_drake.live.loop import _window_end

    h, t, ends = 0.01, 0.0, []
    for _ in range(40):
        t = _window_end(t, 0.5, h)
        ends.append(t)
    phase = np.array(ends) / h % 1.0
    np.testing.assert_allclose(phase, 0.5, atol=1e-6)
    np.testing.assert_allclose(np.diff(ends), 0.5, atol=1e-9)  # about window_s apart
    assert ends[0] == pytest.approx(0.505)


def test_a_few_late_samples_never_push_the_rest_out_of_the_wake_window():
    """On a loaded machine a few samples arrive several ms late (here 3 % of them, 4.5 ms
    behind a steady phase whose samples wait 5 ms). Following the latest arrival alone would
    move the polls 0.5 ms later, and every other sample would wait 5.5 ms, outside the 4 ms
    wake window; the lock keeps the median sample `wake_window_s - margin_s` before its poll."""
    config = PhaseLockConfig(margin_s=1e-3, wake_window_s=4e-3, quantile=0.01)
    rng = np.random.default_rng(3)
    steady = waits(5.05e-3, 1e-4, n=194, seed=4)
    late = steady[:6] - 4.5e-3
    shift = phase_correction(rng.permutation(np.concatenate([steady, late])), H, config)
    assert np.median(steady) - shift == pytest.approx(3e-3, abs=1e-5)
    # without the wake window the latest arrivals decide, as before
    plain = PhaseLockConfig(margin_s=1e-3, wake_window_s=0.0, quantile=0.01)
    shift = phase_correction(np.concatenate([steady, late]), H, plain)
    latest = np.quantile(np.concatenate([steady, late]), 0.01)
    assert shift == pytest.approx(latest - 1e-3, abs=2e-5)
    assert shift < 0


def test_waits_of_half_a_period_shift_the_shorter_way_whichever_side_they_unwrap_on():
    """Waits of 5.0 to 5.1 ms in a 10 ms period sit where the circle's unwrapping may read them as
    -4.95 ms: the shift must still be the short one (4 ms earlier), not 6 ms later."""
    config = PhaseLockConfig(margin_s=1e-3, wake_window_s=0.0, max_slew_s=0.005)
    for seed in range(5):
        shift = phase_correction(waits(5.1e-3, 1e-4, seed=seed), H, config)
        assert shift == pytest.approx(0.0051 - 1e-4 * 0.99 - 1e-3, abs=3e-5)
