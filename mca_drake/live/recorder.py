"""LiveRecorder: the live loop's signals, recorded off the path from a sample to its command.

The live loop records its signals at two moments of each period, neither between a sample's
poll and the command computed from it (the poll and the MCA run in one simulator step at t_k,
`mca_drake.systems.mca_update`), and each row at the moment its meaning asks for:

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
    """

    def __init__(
        self,
        before_poll: dict[str, int],
        after_command: dict[str, int],
        period_s: float,
    ):
        super().__init__()
        if set(before_poll) & set(after_command):
            raise ValueError("LiveRecorder: a port name is in both before_poll and after_command")
        offset = period_s - BEFORE_POLL_S
        if not AFTER_COMMAND_S < offset < period_s:
            raise ValueError(
                f"LiveRecorder: a {period_s} s period leaves no room for the recordings "
                f"before the poll and after the command ({BEFORE_POLL_S} s, {AFTER_COMMAND_S} s)"
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
