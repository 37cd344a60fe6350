"""Real-time pacing of the live loop: the telemetry poll and the MCA on time.

Drake's own pacing (`Simulator.set_target_realtime_rate`) sleeps before every step until the
wall clock reaches the step's time, and a short sleep overshoots (by about 1 ms on the
development machine's virtual machine). The pacer instead runs as the simulator's monitor
(called after every step) and waits only before the control instants, where the telemetry
poll and the MCA run in one step (`mca_drake.systems.mca_update`), sleeping until shortly
before and spinning the last `SPIN_S`: the poll comes on time to a few microseconds, and the
MCA, the supervisor and the robot follow at once; the steps between control instants run
unpaced.

A poll may also come early, when the sender's packet does: from `wake_window_s` before a poll
instant the pacer watches the receiver's socket (a blocking `select`, then a spin that checks
it) and lets the poll run as soon as a datagram arrives, so that a sample waits for its poll
only as long as the wake-up takes. The control instant itself keeps its place on the
nominal grid (the next one is due at its usual time), so an early poll never makes the loop
run ahead.

The pacer also carries the loop's phase: `target_phase_s` (> 0: every control instant
earlier on the wall clock by that much) is reached at no more than `max_slew_per_period_s`
per period, so a phase change never shortens or stretches one period by more than that
(the phase lock of `mca_drake.live.phase_lock` sets it). And its rate: `rate_trim` (> 0:
the loop's clock runs slower by that fraction, its instants drifting later) lets the loop
follow another clock, a robot controller's (`mca_drake.live.rsi.link.RobotClockServo`);
the drift accumulates period by period, so the time between instants changes by the trim
alone, never by a jump.
"""

from __future__ import annotations

import select
import time
from collections import deque

from pydrake.systems.framework import Context, EventStatus

# Sleep until this long before a control instant, then spin: sleeps overshoot, spins do not.
SPIN_S = 4e-4


class RealTimePacer:
    """The simulator's monitor that paces the live loop (see the module docstring).

    Args:
        period_s: the control period, s.
        realtime_rate: wall seconds per simulated second, inverted (1: real time).
        max_slew_per_period_s: the most the phase moves in one period, s.
        wake_socket: the receiver's socket (anything with `fileno()`), watched from
            `wake_window_s` before each control instant; None: polls only at their instants.
        wake_window_s: how early a datagram may bring a poll forward, s (< period_s).
    """

    def __init__(
        self,
        period_s: float,
        realtime_rate: float = 1.0,
        max_slew_per_period_s: float = 1e-4,
        wake_socket=None,
        wake_window_s: float = 0.0,
    ):
        if not (period_s > 0 and realtime_rate > 0):
            raise ValueError("RealTimePacer needs period_s > 0 and realtime_rate > 0")
        if not 0 <= wake_window_s < period_s:
            raise ValueError("RealTimePacer needs 0 <= wake_window_s < period_s")
        self._wake_socket = wake_socket if wake_window_s > 0 else None
        self._wake_window = wake_window_s
        self._period, self._rate = period_s, realtime_rate
        self._max_slew = max_slew_per_period_s
        self.phase_s = 0.0  # the phase now, s (> 0: earlier)
        self.target_phase_s = 0.0  # where the phase goes, s
        self.rate_trim = 0.0  # > 0: the loop's clock runs slower by this fraction
        self.drift_s = 0.0  # what the trim has added up to, s (> 0: later)
        self._wall_at_zero: float | None = None
        self.late_polls = 0  # polls that came later than their instant (the loop overran)
        self.early_polls = 0  # polls a datagram brought forward
        # (control instant k, wall time its poll was due): what the phase lock measures
        # arrivals against, since an early poll's own time says nothing of the phase
        self.dues: deque[tuple[int, float]] = deque(maxlen=4096)

    def start(self) -> None:
        """Anchors simulated time 0 to now: call right before `Simulator.AdvanceTo`."""
        self._wall_at_zero = time.perf_counter()

    def __call__(self, context: Context) -> EventStatus:
        """The monitor: waits, before a control instant, until its wall-clock time."""
        t = context.get_time()
        k = round(t / self._period)
        if self._wall_at_zero is None or abs(t - k * self._period) > 1e-9:
            return EventStatus.Succeeded()  # not a control instant: no wait
        error = self.target_phase_s - self.phase_s
        self.phase_s += max(-self._max_slew, min(self._max_slew, error))
        self.drift_s += self.rate_trim * self._period / self._rate
        due = self._wall_at_zero + t / self._rate + self.drift_s - self.phase_s
        self.dues.append((k, due))
        if due < time.perf_counter():
            self.late_polls += 1
            return EventStatus.Succeeded()
        if self._wake_socket is None:
            wait_until(due)
            return EventStatus.Succeeded()
        wait_until(due - self._wake_window)
        if self._datagram_by(due):
            self.early_polls += 1
        return EventStatus.Succeeded()

    def _datagram_by(self, due: float) -> bool:
        """Waits until a datagram arrives (True) or `due` (False): blocked in `select` until
        SPIN_S before it, then spinning on a zero-timeout `select`. A datagram already there
        when the window opens arrived before it, while the poll was not yet due: the poll
        waits for its instant (taking it and any newer one), as without the window; else the
        loop would poll at every window's opening for the datagram that came after the
        previous early poll, one sample behind for good."""
        sock = self._wake_socket
        try:
            if select.select([sock], [], [], 0)[0]:
                wait_until(due)
                return False
            left = due - SPIN_S - time.perf_counter()
            if left > 0 and select.select([sock], [], [], left)[0]:
                return True
            while time.perf_counter() < due:
                if select.select([sock], [], [], 0)[0]:
                    return True
        except (OSError, ValueError):  # the socket closed: just keep the time
            wait_until(due)
        return False


def wait_until(wall_s: float) -> None:
    """Sleeps until SPIN_S before `wall_s` (time.perf_counter()), then spins to it."""
    left = wall_s - time.perf_counter()
    if left > SPIN_S:
        time.sleep(left - SPIN_S)
    while time.perf_counter() < wall_s:
        pass
