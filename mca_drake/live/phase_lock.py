"""Phase lock of the live loop to a periodic sender: polls that come just after its packets.

A flight simulator that streams at the loop's rate (JSBSim and FlightGear at 100 Hz) sends
at a phase of its own. A sample then waits in the socket from its arrival until the next
poll, up to a whole control period, and that wait, not the MCA, dominated the latency from
arrival to command (3.4 ms median on real-time JSBSim telemetry, where the MCA took
0.1 ms). The lock measures the waits (time the poll was due - arrival time) over a window of the run
and moves the loop's control instants so that the poll comes `margin_s` after the latest
usual arrival (the `quantile` of the waits): the pacer (`mca_drake.live.pacing`) slews its
phase there within the next window (at most `max_slew_s` per window), so the loop's time
never jumps and a period changes by at most max_slew_s / window_s of itself (1 % by default).

With the pacer's wake window (`wake_window_s`), a sample that arrives in the window before
its poll instant brings the poll forward and waits only for the wake-up; the lock then
measures each sample against the time its poll was due, not the time it ran, and keeps the
samples in the window (the latest usual one `margin_s` before the instant, but the median
one no more than `wake_window_s - margin_s` before it: on a loaded machine a few samples
arrive several ms late, and following them alone moved every other sample out of the
window, so that it waited for the window to open: 4.3 ms median on a CI machine).

Waits are read on the circle of one period: a sample that arrived just after its poll waits
almost a whole period, which is the same phase as a negative wait. A stream without a
steady phase (another rate, a bursty sender: the central 80 % of the waits spread over more
than half a period) leaves the loop's timing alone.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mca_drake.input_checks import check_config_numbers


@dataclasses.dataclass
class PhaseLockConfig:
    """How the live loop follows the sender's phase (see the module docstring)."""

    # Follow the sender's phase at all (False: the loop keeps the phase it started with).
    enabled: bool = True
    # The poll comes this long (s) after the latest usual arrival: room for the sender's
    # jitter, so that its samples rarely miss their poll.
    margin_s: float = 1e-3
    # From this long (s) before each poll instant, a datagram brings the poll forward
    # (`mca_drake.live.pacing`): the samples the lock places in this window wait for their
    # poll only as long as the wake-up takes (0: polls only at their instants).
    wake_window_s: float = 4e-3
    # The latest usual arrival: this quantile of the waits (the shortest ones).
    quantile: float = 0.01
    # The loop's time (s) over which the waits are measured and a correction is run.
    window_s: float = 0.5
    # At most this much shift (s) per window.
    max_slew_s: float = 0.005
    # Shifts smaller than this (s) are not made.
    deadband_s: float = 1e-4
    # Fewer samples than this in a window: no correction.
    min_samples: int = 20

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        if not self.window_s > 0 or self.margin_s < 0 or self.deadband_s < 0:
            raise ValueError("PhaseLockConfig: window_s must be > 0, margin_s, deadband_s >= 0")
        if self.wake_window_s < 0:
            raise ValueError("PhaseLockConfig.wake_window_s must be >= 0")
        if not 0 <= self.max_slew_s < 0.5 * self.window_s:
            raise ValueError("PhaseLockConfig.max_slew_s must be in [0, window_s / 2)")
        if not 0 < self.quantile < 0.5:
            raise ValueError("PhaseLockConfig.quantile must be in (0, 0.5)")


# The central quantiles (and 1 - it) whose spread tells a steady phase from none: robust to
# the few samples a loaded machine delays, which the latest-arrival quantile sees.
CORE_QUANTILE = 0.1


def phase_correction(waits_s: np.ndarray, period_s: float, config: PhaseLockConfig) -> float:
    """The shift (s) of the loop's control instants that brings the polls `margin_s` after
    the latest usual arrival: > 0 moves them earlier, < 0 later, 0 for none. Of the two
    ways round the period it takes the shorter (waits of 8 ms in a 10 ms period: 2.3 ms
    later, not 7.7 ms earlier).

    Args:
        waits_s: the time each sample's poll was due (its control instant's poll on the
            loop's grid, whether or not the sample brought it forward) - its arrival time,
            for the samples of one window, s.
        period_s: the control period, s.
    """
    waits = np.asarray(waits_s, dtype=float)
    waits = waits[np.isfinite(waits)]
    if not config.enabled or waits.size < config.min_samples:
        return 0.0
    # unwrap on the circle of one period around the waits' circular mean
    angle = 2 * np.pi * waits / period_s
    centre = period_s * np.angle(np.mean(np.exp(1j * angle))) / (2 * np.pi)
    unwrapped = centre + np.mod(waits - centre + period_s / 2, period_s) - period_s / 2
    low, core_low, median, core_high = np.quantile(
        unwrapped, [config.quantile, CORE_QUANTILE, 0.5, 1 - CORE_QUANTILE]
    )
    if core_high - core_low > period_s / 2:
        return 0.0  # no steady phase to follow
    # the median sample's wait after the shift: room for the latest usual arrival and the
    # margin, but no more than keeps it inside the wake window: a few samples the machine
    # held up (on a loaded machine, several ms late) must not push every other sample out
    # of the window, where it would wait for the window to open
    lead = median - low + config.margin_s
    if config.wake_window_s > 2 * config.margin_s:
        lead = min(lead, config.wake_window_s - config.margin_s)
    # the shorter way round: waits near half a period may unwrap on either side
    shift = float(np.mod(median - lead + period_s / 2, period_s) - period_s / 2)
    if abs(shift) < config.deadband_s:
        return 0.0
    return float(np.clip(shift, -config.max_slew_s, config.max_slew_s))
