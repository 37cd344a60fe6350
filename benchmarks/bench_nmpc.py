"""NMPC on a light-aircraft flight: per-step solve time and PI of both modes, and closed-loop
dataset throughput with 1 and 2 worker processes.

    python benchmarks/bench_nmpc.py [--minutes 5] [--converged-seconds 300] [--seed 1000]
"""

from __future__ import annotations

import argparse
import tempfile
import time

from mca_drake.references.jsbsim import fly
from mca_drake.references.reference import reference_from_recording
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.closed_loop_dataset import (
    ClosedLoopDatasetConfig,
    generate_closed_loop_dataset,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--minutes", type=float, default=5.0)
    parser.add_argument(
        "--converged-seconds",
        type=float,
        default=300.0,
        help="converged mode is slow: evaluate it on this many seconds",
    )
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument(
        "--dataset-seconds",
        type=float,
        default=60.0,
        help="flight length for the dataset throughput runs (0: skip)",
    )
    args = parser.parse_args()
    reference = reference_from_recording(fly("light", args.minutes * 60, args.seed))
    window = min(args.converged_seconds, args.minutes * 60)
    results = {}
    for mca, duration in (("nmpc-rti", args.minutes * 60), ("nmpc-converged", window)):
        r = run_closed_loop(mca=mca, reference=reference, duration_s=duration, progress=False)
        results[mca] = r
        s = r.summary
        t = {k: f"{v * 1e3:.2f} ms" for k, v in s["step_time_s"].items()}
        print(
            f"{mca:15s} {duration:5.0f} s: PI {s['pi']:.4f} (zero motion "
            f"{s['pi_zero_motion']:.4f}), step {t}, violations "
            f"{s['violations']}, failures {s['solver_failures']}, "
            f"interventions {s['safety_interventions']}, {s['realtime_factor']:.2f}x real time"
        )
    # PI of rti over the converged window, for a like-for-like comparison
    rti_window = run_closed_loop(
        mca="nmpc-rti", reference=reference, duration_s=window, progress=False
    )
    gap = rti_window.summary["pi"] - results["nmpc-converged"].summary["pi"]
    print(
        f"PI over the first {window:.0f} s: rti {rti_window.summary['pi']:.4f}, converged "
        f"{results['nmpc-converged'].summary['pi']:.4f}, gap {gap:+.4f}"
    )
    if args.dataset_seconds > 0:
        for workers in (1, 2):
            config = ClosedLoopDatasetConfig(
                flight_seeds=(7, 8), flight_duration_s=args.dataset_seconds
            )
            with tempfile.TemporaryDirectory() as out:
                start = time.perf_counter()
                generate_closed_loop_dataset(config, out, workers=workers, progress=False)
                wall = time.perf_counter() - start
            print(
                f"dataset, {workers} worker(s): {2 * args.dataset_seconds / wall:.2f} "
                f"simulated s per wall s (2 flights x {args.dataset_seconds:.0f} s)"
            )


if __name__ == "__main__":
    main()
