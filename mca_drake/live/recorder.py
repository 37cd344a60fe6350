"""LiveRecorder: the live loop's signals, recorded off the path from a sample to its command.

Drake's `LogVectorOutput` publishes at every control instant t_k, at the end of the step that
reaches t_k: after the telemetry poll (t_k - poll lead) and before the MCA's update at t_k.
Every port it reads (the supervised command, the robot's outputs) was then computed between
the sample's arrival and the command computed from it, which added to the live latency.
The recorder reads the same values at two other moments of each period:

- `before_poll` ports just before the poll (`BEFORE_POLL_S` before it; at t = 0, at
  initialization): everything the MCA will read at t_k, since nothing in the live loop
  updates between then and t_k except the receiver. Row k holds the value at t_k, as a
  `LogVectorOutput` at t_k would (rows 0..N for a run of N periods).
- `after_command` ports just after the command (`AFTER_COMMAND_S` after t_k, once the
  `LatencyProbe` has timed it): the command the robot gets for period k and the reference
  it was computed for. Row k holds period k (rows 0..N-1).

Rows live on the recorder (like `LatencyProbe`'s figures), not in the context: the live loop
runs one simulator once.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import Context, EventStatus, LeafSystem

# The before-poll rows are read this long (s) before the poll.
BEFORE_POLL_S = 1e-5
# The after-command rows are read this long (s) after each control instant: after the
# LatencyProbe (live.loop.PROBE_DELAY_S) and before the analytical plant's update.
AFTER_COMMAND_S = 1.5e-5


class LiveRecorder(LeafSystem):
    """Records vector inputs before each poll and after each command (module docstring).

    Args:
        before_poll: name -> size of the ports read just before each poll (and at t = 0).
        after_command: name -> size of the ports read just after each command.
        period_s: the control period, s.
        poll_lead_s: how long before each control instant the receiver polls, s.
    """

    def __init__(
        self,
        before_poll: dict[str, int],
        after_command: dict[str, int],
        period_s: float,
        poll_lead_s: float,
    ):
        super().__init__()
        if set(before_poll) & set(after_command):
            raise ValueError("LiveRecorder: a port name is in both before_poll and after_command")
        offset = period_s - poll_lead_s - BEFORE_POLL_S
        if not (period_s > 0 and AFTER_COMMAND_S < offset < period_s):
            raise ValueError(
                f"LiveRecorder: poll_lead_s {poll_lead_s} s leaves no room in a {period_s} s "
                "period for the recordings before the poll and after the command"
            )
        self._ports = {
            name: self.DeclareVectorInputPort(name, size)
            for name, size in (before_poll | after_command).items()
        }
        self._before = tuple(before_poll)
        self._after = tuple(after_command)
        self._rows: dict[str, list[np.ndarray]] = {name: [] for name in self._ports}
        self.DeclareInitializationPublishEvent(self._record_before)
        self.DeclarePeriodicPublishEvent(period_s, offset, self._record_before)
        self.DeclarePeriodicPublishEvent(period_s, AFTER_COMMAND_S, self._record_after)

    def rows(self, name: str) -> np.ndarray:
        """The rows recorded from port `name` so far, shape (rows, size)."""
        if name not in self._rows:
            raise KeyError(f"LiveRecorder has no port '{name}'; it has {sorted(self._rows)}")
        size = self._ports[name].size()
        return np.array(self._rows[name]).reshape(-1, size)

    def _record(self, context: Context, names: tuple[str, ...]) -> EventStatus:
        for name in names:
            self._rows[name].append(np.array(self._ports[name].Eval(context)))
        return EventStatus.Succeeded()

    def _record_before(self, context: Context) -> EventStatus:
        return self._record(context, self._before)

    def _record_after(self, context: Context) -> EventStatus:
        return self._record(context, self._after)


__all__ = ["AFTER_COMMAND_S", "BEFORE_POLL_S", "LiveRecorder"]
