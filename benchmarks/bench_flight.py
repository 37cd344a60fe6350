"""JSBSim flights with the scripted pilot: simulated seconds per wall second, per vehicle.

cd benchmarks && ../.venv/bin/python bench_flight.py [--seeds 3] [--duration 300]

Each flight is timed whole (model load, trim, pilot, recorder); flights of 600 s or more take
off and land (see FULL_FLIGHT_MIN_DURATION_S), shorter ones start airborne.
"""

from __future__ import annotations

import argparse
import statistics
import time

from common import print_calibration

from mca_drake.references.jsbsim import VEHICLES, fly


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=3, help="flights per vehicle")
    parser.add_argument("--duration", type=float, default=300.0, help="flight length, s")
    args = parser.parse_args()
    print_calibration()
    fly("light", 1.0, seed=0)  # warm-up: imports, first model load
    for vehicle in VEHICLES:
        rates = []
        for seed in range(args.seeds):
            start = time.perf_counter()
            recording = fly(vehicle, args.duration, seed=seed)
            wall = time.perf_counter() - start
            rates.append(args.duration / wall)
            print(
                f"  {vehicle} seed {seed}: {args.duration:.0f} s simulated in {wall:.2f} s "
                f"({rates[-1]:.0f}x, {recording.t.size} samples)"
            )
        print(
            f"{vehicle}: {args.seeds} x {args.duration:.0f} s flights: simulated s per wall s "
            f"median {statistics.median(rates):.0f} (min {min(rates):.0f}, max {max(rates):.0f})"
        )


if __name__ == "__main__":
    main()
