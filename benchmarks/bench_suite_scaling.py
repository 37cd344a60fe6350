"""Scaling of the evaluation suite on Ray: wall time with 1 worker (in this process) and
with N workers (a local Ray), efficiency = speed-up / workers.

    python benchmarks/bench_suite_scaling.py [--workers 2] [--flights 3] [--duration 60]

The suite: cases A and B with `--flights` flights each, DPC, washout and NMPC-rti, on the
analytical plant. The flights are flown once beforehand and copied into every run's
folder, so that both runs time the same closed loops. Prints the calibration of this
machine (`common.calibration_s`) beside the figures.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

from common import calibration_s

from mca_drake.studies.evaluation import EvaluationCase, EvaluationConfig, run_evaluation


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--flights", type=int, default=3)
    parser.add_argument("--duration", type=float, default=60.0)
    args = parser.parse_args()
    config = EvaluationConfig(
        mcas=("dpc", "washout", "nmpc-rti"),
        cases=(
            EvaluationCase("A", "light", tuple(range(1000, 1000 + args.flights))),
            EvaluationCase("B", "jet", tuple(range(2000, 2000 + args.flights))),
        ),
        duration_s=args.duration,
    )
    print(f"{os.cpu_count()} cores; calibration {calibration_s()}")
    tasks = len(config.mcas) * 2 * args.flights
    with tempfile.TemporaryDirectory() as tmp:
        warm = Path(tmp) / "warm"
        only_dpc = EvaluationConfig(mcas=("dpc",), cases=config.cases, duration_s=args.duration)
        run_evaluation(only_dpc, warm, progress=False)  # flies and caches every flight
        walls = {}
        for workers in (1, args.workers):
            out = Path(tmp) / f"w{workers}"
            shutil.copytree(warm / "flights", out / "flights")
            start = time.perf_counter()
            run_evaluation(config, out, workers=workers, progress=False)
            walls[workers] = time.perf_counter() - start
            print(f"{tasks} runs, {workers} worker(s): {walls[workers]:.1f} s wall")
    speedup = walls[1] / walls[args.workers]
    print(
        f"speed-up {speedup:.2f} on {args.workers} workers: efficiency "
        f"{speedup / args.workers:.2f} (Ray start-up included)"
    )


if __name__ == "__main__":
    main()
