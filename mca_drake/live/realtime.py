"""Real-time scheduling for the live layer's hard-deadline processes (the RSI driver and the
loopback robot): Linux's SCHED_FIFO, where the process may have it.

A process that must answer within a few milliseconds loses whole scheduler slices to
ordinary processes on a busy machine (the flight simulator, the MCA loop); under SCHED_FIFO
it runs as soon as its datagram arrives. It needs CAP_SYS_NICE (root, or an rtprio limit in
/etc/security/limits.conf); without it nothing changes and the caller reports so.
"""

from __future__ import annotations

import os


def request_realtime_priority(priority: int) -> bool:
    """Puts this process under SCHED_FIFO at `priority` (1-99); True if granted, False if
    not asked (priority <= 0), not permitted or not Linux."""
    if priority <= 0 or not hasattr(os, "sched_setscheduler"):
        return False
    if priority > 99:
        raise ValueError(f"a SCHED_FIFO priority is 1-99; got {priority}")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError:  # PermissionError included: no CAP_SYS_NICE
        return False
    return True
