"""Closed-loop speed of the three figures the layering must not slow down: DPC and NMPC-rti
step times on the analytical plant and the KR500 station's real-time factor with DPC.

    python benchmarks/bench_closed_loop.py [--seconds 60] [--repeats 3] [--seed 1000]

Prints, per repeat and as median with min and max over repeats: the DPC step median (us),
the NMPC-rti step median and p99 (ms) on the analytical plant, and the real-time factor of
the multibody station (1 kHz MultibodyPlant, DPC). A short calibration workload (numpy and
pure Python, fixed size) is timed first so that figures from different machines can be
compared. `--json` writes the figures with their provenance (date, command, calibration,
machine).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics

import numpy as np
from common import calibration_s, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.platforms.files import load_platform
from mca_drake.references.jsbsim import fly
from mca_drake.references.reference import reference_from_recording
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")


def measure(reference, seconds: float) -> dict[str, float]:
    """One repeat of the three figures."""
    dpc = run_closed_loop(
        mca="dpc", reference=reference, duration_s=seconds, progress=False, robot=KR500
    )
    rti = run_closed_loop(
        mca="nmpc-rti", reference=reference, duration_s=seconds, progress=False, robot=KR500
    )
    station = run_closed_loop(
        mca="dpc",
        reference=reference,
        plant="multibody",
        duration_s=seconds,
        progress=False,
        robot=KR500,
    )
    return {
        "dpc_step_median_us": float(np.median(dpc.step_times_s) * 1e6),
        "rti_step_median_ms": float(np.median(rti.step_times_s) * 1e3),
        "rti_step_p99_ms": float(np.percentile(rti.step_times_s, 99) * 1e3),
        "station_realtime_factor": station.summary["realtime_factor"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--json", help="also write the figures to this JSON file")
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores")
    calibration = calibration_s()
    print(
        f"calibration: numpy {calibration['numpy_s'] * 1e3:.1f} ms, "
        f"pure Python {calibration['python_s'] * 1e3:.1f} ms"
    )
    reference = reference_from_recording(
        fly("light", args.seconds, args.seed), name=f"light {args.seed}"
    )
    repeats = []
    for k in range(args.repeats):
        repeats.append(measure(reference, args.seconds))
        print(f"repeat {k + 1}: " + ", ".join(f"{n} {v:.3f}" for n, v in repeats[-1].items()))
    summary = {}
    for name in repeats[0]:
        values = [r[name] for r in repeats]
        summary[name] = {
            "median": statistics.median(values),
            "min": min(values),
            "max": max(values),
        }
        print(
            f"{name}: median {summary[name]['median']:.3f} "
            f"(min {summary[name]['min']:.3f}, max {summary[name]['max']:.3f}, n {len(values)})"
        )
    if args.json:
        atomic_write_json(args.json, {"provenance": result_header(calibration), "figures": summary})


if __name__ == "__main__":
    main()
