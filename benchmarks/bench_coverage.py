"""What a closed-loop training set covers, per vehicle, beside the evaluation flights.

cd benchmarks && ../.venv/bin/python bench_coverage.py --dataset ../datasets/mixed/dataset.npz
    [--duration 300] [--json results/coverage.json]

Prints the standard deviation of every scaled reference channel and the 99th percentile of
|a_z| per vehicle of the dataset (`mca_drake.studies.coverage`) and of the default
evaluation cases' flights (flown here, or read from --cache), as one markdown table. The
evaluation flights are only looked at, never trained or tuned on.
"""

from __future__ import annotations

import argparse

from common import print_calibration

from mca_drake.atomic_io import atomic_write_json
from mca_drake.segments import SegmentDataset
from mca_drake.studies.coverage import (
    dataset_reference_spread,
    flight_reference_spread,
    spread_markdown,
)
from mca_drake.studies.evaluation import default_cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--dataset", required=True, help="a merged closed-loop dataset")
    parser.add_argument("--duration", type=float, default=300.0, help="evaluation flight, s")
    parser.add_argument("--cache", default=None, help="folder of cached flight CSVs")
    parser.add_argument("--json", default=None, help="also write the tables here")
    args = parser.parse_args()
    print_calibration()
    tables = {"training set": dataset_reference_spread(SegmentDataset.load(args.dataset))}
    for case in default_cases():
        flights = [(case.vehicle_of(seed), seed) for seed in case.seeds]
        tables[f"evaluation case {case.name}"] = flight_reference_spread(
            flights, args.duration, cache_dir=args.cache
        )
    print(spread_markdown(tables))
    if args.json:
        atomic_write_json(args.json, {"dataset": args.dataset, "tables": tables})
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
