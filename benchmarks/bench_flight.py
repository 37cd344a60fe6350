"""JSBSim flights with the scripted pilot, per vehicle: speed, failures, what the IMU saw.

cd benchmarks && ../.venv/bin/python bench_flight.py [--seeds 3] [--first-seed 0]
    [--duration 300] [--vehicles light,jet,...]

Each flight is timed whole (model load, trim, pilot, recorder); flights of 600 s or more
take off and land where the vehicle can (see FULL_FLIGHT_MIN_DURATION_S), shorter ones start
airborne. A flight that leaves the sane envelope is reported with its FlightError, not
hidden. Per vehicle: simulated s per wall s, the scaled reference's spread per channel (what
an MCA sees, `mca_drake.studies.coverage`), and the largest load factor. Seeds below 1000
only: the evaluation flights are not flown to calibrate the pilot.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from common import print_calibration

from mca_drake.conventions import FIRST_EVALUATION_SEED
from mca_drake.references.jsbsim import VEHICLE_CLASSES, VEHICLES, FlightError, fly
from mca_drake.references.reference import reference_from_recording
from mca_drake.studies.coverage import spread, spread_markdown


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=3, help="flights per vehicle")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=300.0, help="flight length, s")
    parser.add_argument("--vehicles", default=",".join(VEHICLES))
    args = parser.parse_args()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    if seeds[-1] >= FIRST_EVALUATION_SEED:
        raise SystemExit(f"seeds from {FIRST_EVALUATION_SEED} on are evaluation flights")
    print_calibration()
    fly("light", 1.0, seed=0)  # warm-up: imports, first model load
    table, failures = {}, 0
    for vehicle in args.vehicles.split(","):
        rates, references, loads = [], [], []
        for seed in seeds:
            start = time.perf_counter()
            try:
                recording = fly(vehicle, args.duration, seed=seed)
            except FlightError as error:
                failures += 1
                print(f"  {vehicle} seed {seed}: FAILED: {error}")
                continue
            wall = time.perf_counter() - start
            rates.append(args.duration / wall)
            references.append(reference_from_recording(recording).y)
            loads.append(float(np.linalg.norm(recording.f, axis=1).max() / 9.81))
            print(
                f"  {vehicle} seed {seed}: {args.duration:.0f} s in {wall:.2f} s "
                f"({rates[-1]:.0f}x), peak load factor {loads[-1]:.2f}"
            )
        if not rates:
            continue
        table[vehicle] = spread(np.concatenate(references), len(references))
        print(
            f"{vehicle} ({VEHICLE_CLASSES[vehicle]}): {len(rates)} of {args.seeds} flights "
            f"flown; simulated s per wall s median {statistics.median(rates):.0f} "
            f"(min {min(rates):.0f}, max {max(rates):.0f}); peak load factor {max(loads):.2f}"
        )
    print()
    print(spread_markdown({f"{args.duration:g} s flights": table}))
    print(f"failed flights: {failures}")


if __name__ == "__main__":
    main()
