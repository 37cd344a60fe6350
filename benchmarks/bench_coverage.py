"""What a closed-loop training set covers, per vehicle, beside the evaluation flights.

    python benchmarks/bench_coverage.py --dataset datasets/mixed_t37/dataset.npz
        [--duration 300] [--cache benchmarks/results/evaluation/flights]
        [--json results/coverage.json]

Prints the standard deviation of every scaled reference channel and the 99th percentile of
|a_z| per vehicle of the dataset (`mca_drake.studies.coverage`) and of the default
evaluation cases' flights (flown here, or read from --cache), as one markdown table. The
evaluation flights are only looked at, never trained or tuned on. Writes the tables with
their provenance (date, command, calibration, machine) to `--json`, by default
`benchmarks/results/coverage.json`.
"""

from __future__ import annotations

import argparse

from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.segments import SegmentDataset
from mca_drake.studies.coverage import (
    dataset_reference_spread,
    flight_reference_spread,
    spread_markdown,
)
from mca_drake.studies.evaluation import default_cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", required=True, help="a merged closed-loop dataset")
    parser.add_argument("--duration", type=float, default=300.0, help="evaluation flight, s")
    parser.add_argument("--cache", default=None, help="folder of cached flight CSVs")
    parser.add_argument(
        "--json", default=default_result_path("coverage.json"), help="write the tables here"
    )
    args = parser.parse_args()
    calibration = print_calibration()
    tables = {"training set": dataset_reference_spread(SegmentDataset.load(args.dataset))}
    for case in default_cases():
        flights = [(case.vehicle_of(seed), seed) for seed in case.seeds]
        tables[f"evaluation case {case.name}"] = flight_reference_spread(
            flights, args.duration, cache_dir=args.cache
        )
    print(spread_markdown(tables))
    report = {"provenance": result_header(calibration), "dataset": args.dataset}
    atomic_write_json(args.json, report | {"tables": tables})
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
