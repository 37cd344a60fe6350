"""The predictive MCAs' step time, the forecast included, beside their causal twins.

    python benchmarks/bench_predictive_step.py [--duration 60] [--repeats 3]

On one validation flight that carries the pilot's controls (the A4 flown by the scripted
pilot, seed 700; analytical plant, closed loop), per MCA: the median and p99 of the MCA's
compute time per control step (`closed_loop.step_time_summary`: what the live loop must
fit in its period; a predictive MCA's includes the forecast it reads), each run
`--repeats` times one after the other, reported as the median over the runs with their
spread. The live budget: p99 within 3 ms at 100 Hz. Writes
`benchmarks/results/predictive_step.json` with the machine's calibration.
"""

from __future__ import annotations

import argparse

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.platforms.files import load_platform
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.simulation.closed_loop import run_closed_loop

# (causal twin, predictive MCA)
PAIRS = (("nmpc-rti", "nmpc-rti-predictive"), ("dpc", "dpc-predictive"))
BUDGET_P99_S = 3e-3


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="s of flight per run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", default=default_result_path("predictive_step.json"))
    args = parser.parse_args()
    calibration = print_calibration()
    robot = load_platform("kr500")
    flight = FlightSpec(vehicle="A4", seed=700)
    reference = flight_reference(flight, args.duration)
    found = {}
    for mca in (name for pair in PAIRS for name in pair):
        runs = []
        for _ in range(args.repeats):
            run = run_closed_loop(mca=mca, reference=reference, robot=robot, progress=False)
            runs.append(run.summary["step_time_s"])
        median = [r["median"] for r in runs]
        p99 = [r["p99"] for r in runs]
        found[mca] = {
            "median_s": float(np.median(median)),
            "median_range_s": [min(median), max(median)],
            "p99_s": float(np.median(p99)),
            "p99_range_s": [min(p99), max(p99)],
            "within_budget_runs": sum(p <= BUDGET_P99_S for p in p99),
            "runs": args.repeats,
        }
        print(
            f"{mca}: step median {found[mca]['median_s'] * 1e3:.2f} ms "
            f"({min(median) * 1e3:.2f}-{max(median) * 1e3:.2f}), p99 "
            f"{found[mca]['p99_s'] * 1e3:.2f} ms ({min(p99) * 1e3:.2f}-{max(p99) * 1e3:.2f})",
            flush=True,
        )
    atomic_write_json(
        args.json,
        {
            "provenance": result_header(calibration),
            "flight": {"vehicle": flight.vehicle, "seed": flight.seed, "pilot": flight.pilot},
            "signals": sorted(reference.signals),
            "duration_s": args.duration,
            "budget_p99_s": BUDGET_P99_S,
            "mcas": found,
        },
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
