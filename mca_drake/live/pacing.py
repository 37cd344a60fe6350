"""Real-time pacing of the live loop: the telemetry poll on time, the MCA right after it.

Drake's own pacing (`Simulator.set_target_realtime_rate`) sleeps before every step until the
wall clock reaches the step's time. In the live loop that costs latency twice: the MCA's
update comes `poll_lead_s` after the poll, in a step of its own, and a sleep that short
overshoots (by about 1 ms on the development machine's virtual machine), so every sample
waited that long between the poll and the command computed from it. The pacer instead runs
as the simulator's monitor (called after every step) and waits only before the poll
instants, sleeping until shortly before and spinning the last `spin_s`: the poll comes on
time to a few microseconds, and the MCA, the supervisor and the robot follow at once.

The pacer also carries the loop's phase: `target_phase_s` (> 0: every control instant
earlier on the wall clock by that much) is reached at no more than `max_slew_per_period_s`
per period, so a phase change never shortens or stretches one period by more than that
(the phase lock of `mca_drake.live.phase_lock` sets it).
"""

from __future__ import annotations

import time

from pydrake.systems.framework import Context, EventStatus

# Sleep until this long before a poll instant, then spin: sleeps overshoot, spins do not.
SPIN_S = 4e-4


class RealTimePacer:
    """The simulator's monitor that paces the live loop (see the module docstring).

    Args:
        period_s: the control period, s.
        lead_s: how long before each control instant the poll runs, s
            (`ReceiverConfig.poll_lead_s`).
        realtime_rate: wall seconds per simulated second, inverted (1: real time).
        max_slew_per_period_s: the most the phase moves in one period, s.
    """

    def __init__(
        self,
        period_s: float,
        lead_s: float,
        realtime_rate: float = 1.0,
        max_slew_per_period_s: float = 1e-4,
    ):
        if not (period_s > 0 and 0 < lead_s < period_s and realtime_rate > 0):
            raise ValueError("RealTimePacer needs period_s > 0, 0 < lead_s < period_s, rate > 0")
        self._period, self._lead, self._rate = period_s, lead_s, realtime_rate
        self._max_slew = max_slew_per_period_s
        self.phase_s = 0.0  # the phase now, s (> 0: earlier)
        self.target_phase_s = 0.0  # where the phase goes, s
        self._wall_at_zero: float | None = None
        self.late_polls = 0  # polls that came later than their instant (the loop overran)

    def start(self) -> None:
        """Anchors simulated time 0 to now: call right before `Simulator.AdvanceTo`."""
        self._wall_at_zero = time.perf_counter()

    def __call__(self, context: Context) -> EventStatus:
        """The monitor: waits, before a poll instant, until its wall-clock time."""
        t = context.get_time()
        k = round((t + self._lead) / self._period)
        if self._wall_at_zero is None or abs(t - (k * self._period - self._lead)) > 1e-9:
            return EventStatus.Succeeded()  # not a poll instant: no wait
        error = self.target_phase_s - self.phase_s
        self.phase_s += max(-self._max_slew, min(self._max_slew, error))
        due = self._wall_at_zero + t / self._rate - self.phase_s
        left = due - time.perf_counter()
        if left < 0:
            self.late_polls += 1
            return EventStatus.Succeeded()
        if left > SPIN_S:
            time.sleep(left - SPIN_S)
        while time.perf_counter() < due:
            pass
        return EventStatus.Succeeded()
