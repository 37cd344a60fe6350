"""A machine-stall probe for the live benchmarks: when was a CPU unavailable?

    python benchmarks/machine_stalls.py --cpu 0 --duration 600 --out stalls_cpu0.json
        [--period-ms 5] [--threshold-ms 1] [--priority 40]

Pinned to one CPU under SCHED_FIFO (below the RSI driver's 50 and the loopback robot's 60,
above every ordinary process), it sleeps to every period's instant and notes each wake-up
later than the threshold: a time when nothing below those two could run on that CPU, which
on a virtual machine means the hypervisor or the kernel took it (the process under test
needs far less than the threshold per wake). The way `cyclictest` measures a machine, in
Python and at a 5 ms period (under 1 % of a core). Also the CPU's steal time over the run
(/proc/stat: time the hypervisor gave to others). Writes JSON: the stalls as [start, late]
on the time.perf_counter() clock (s), which the other processes' records share.
"""

from __future__ import annotations

import argparse
import math
import os
import time

from mca_drake.atomic_io import atomic_write_json
from mca_drake.live.realtime import request_realtime_priority


def steal_s(cpu: int) -> float:
    """The CPU's steal time so far (s), NaN where /proc/stat does not say."""
    try:
        with open("/proc/stat") as stat:
            for line in stat:
                fields = line.split()
                if fields[0] == f"cpu{cpu}" and len(fields) > 8:
                    return int(fields[8]) / os.sysconf("SC_CLK_TCK")
    except OSError:
        pass
    return math.nan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cpu", type=int, required=True)
    parser.add_argument("--duration", type=float, required=True, help="s")
    parser.add_argument("--out", required=True, help="JSON file")
    parser.add_argument("--period-ms", type=float, default=5.0)
    parser.add_argument("--threshold-ms", type=float, default=1.0)
    parser.add_argument("--priority", type=int, default=40, help="SCHED_FIFO (0: none)")
    args = parser.parse_args()
    os.sched_setaffinity(0, {args.cpu})
    realtime = request_realtime_priority(args.priority)
    period, threshold = args.period_ms * 1e-3, args.threshold_ms * 1e-3
    stalls: list[list[float]] = []
    steal_before = steal_s(args.cpu)
    start = time.perf_counter()
    n = 0
    while (due := start + n * period) < start + args.duration:
        # a plain sleep, no spin: the probe must not take the CPU it watches
        time.sleep(max(0.0, due - time.perf_counter()))
        late = time.perf_counter() - due
        if late > threshold:
            stalls.append([due, late])
        n += 1 + math.floor(late / period)
    atomic_write_json(
        args.out,
        {
            "cpu": args.cpu,
            "period_s": period,
            "threshold_s": threshold,
            "realtime_priority": args.priority if realtime else 0,
            "wakeups": n,
            "steal_s": steal_s(args.cpu) - steal_before,
            "stalls": stalls,
        },
    )


if __name__ == "__main__":
    main()
