"""What training references cover, per vehicle, beside the evaluation flights.

    python benchmarks/bench_coverage.py --dataset datasets/mixed_t37/dataset.npz
        [--duration 300] [--cache benchmarks/results/evaluation/flights]
        [--json results/coverage.json]
    python benchmarks/bench_coverage.py --sources scripted,random-style,synthetic
        [--flights 28] [--first-seed 200] [--duration 300]
        [--json results/coverage_sources.json]

With `--dataset`: the standard deviation of every scaled reference channel and the 99th
percentile of |a_z| per vehicle of a closed-loop training set (`mca_drake.studies.coverage`)
and of the default evaluation cases' flights, as one markdown table (default result
`benchmarks/results/coverage.json`).

With `--sources`: the same spread for the references of each training source
(`references.flights.TRAINING_SOURCES`: the scripted pilot, random-style pilots, synthetic
motion) over the training vehicles (seed i flies vehicle i mod 7), before any MCA cues
them, and per evaluation case the share of its reference samples that lie inside each
source's 0.5-99.5 percentile range, channel by channel, and inside that of all the sources
together (default result `benchmarks/results/coverage_sources.json`).

The evaluation flights (cases A, B, C and E, flown here or read from `--cache`) are only
looked at, never trained or tuned on. Every table goes to `--json` with its provenance
(date, command, calibration, machine).
"""

from __future__ import annotations

import argparse

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.conventions import CHANNELS
from mca_drake.references.jsbsim import TRAINING_VEHICLES
from mca_drake.segments import SegmentDataset
from mca_drake.studies.coverage import (
    dataset_reference_spread,
    flight_references,
    grouped_spread,
    inside_share,
    source_references,
    spread_markdown,
)
from mca_drake.studies.evaluation import default_cases


def evaluation_references(duration_s: float, cache: str | None) -> dict[str, dict]:
    """Per default evaluation case of flights, its references grouped per vehicle (case D's
    drives are no flight source's to cover)."""
    out = {}
    for case in default_cases():
        if case.manoeuvres:
            continue
        flights = [(case.vehicle_of(seed), seed) for seed in case.seeds]
        out[case.name] = flight_references(flights, duration_s, pilot=case.pilot, cache_dir=cache)
    return out


def pooled(grouped: dict[str, list[np.ndarray]]) -> np.ndarray:
    """Every reference sample of grouped references, (T, 6)."""
    return np.concatenate([y for ys in grouped.values() for y in ys])


def inside_markdown(inside: dict[str, dict[str, list[float]]]) -> str:
    """Markdown: per training source and evaluation case, the share of samples inside."""
    header = " | ".join(CHANNELS)
    lines = [f"| training | evaluation case | {header} |", "|---" * (2 + len(CHANNELS)) + "|"]
    for source, cases in inside.items():
        for case, shares in cases.items():
            cells = " | ".join(f"{v:.1%}" for v in shares)
            lines.append(f"| {source} | {case} | {cells} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", help="a merged closed-loop dataset")
    parser.add_argument(
        "--sources", help="comma-separated training sources to fly instead of --dataset"
    )
    parser.add_argument("--flights", type=int, default=28, help="per source (with --sources)")
    parser.add_argument("--first-seed", type=int, default=200, help="with --sources")
    parser.add_argument("--duration", type=float, default=300.0, help="each flight, s")
    parser.add_argument("--cache", default=None, help="folder of cached flight CSVs")
    parser.add_argument("--json", help="write the tables here")
    args = parser.parse_args()
    if bool(args.dataset) == bool(args.sources):
        parser.error("give either --dataset or --sources")
    calibration = print_calibration()
    evaluation = evaluation_references(args.duration, args.cache)
    tables = {}
    report = {"provenance": result_header(calibration)}
    if args.dataset:
        tables["training set"] = dataset_reference_spread(SegmentDataset.load(args.dataset))
        report["dataset"] = args.dataset
    else:
        sources = [s.strip() for s in args.sources.split(",") if s.strip()]
        seeds = range(args.first_seed, args.first_seed + args.flights)
        flights = [(TRAINING_VEHICLES[i % len(TRAINING_VEHICLES)], s) for i, s in enumerate(seeds)]
        references = {
            s: source_references(s, flights, args.duration, cache_dir=args.cache) for s in sources
        }
        for source, grouped in references.items():
            tables[f"training: {source}"] = grouped_spread(grouped)
        everything = {"all sources": np.concatenate([pooled(g) for g in references.values()])}
        report["inside"] = {
            name: {case: inside_share(y, pooled(refs)) for case, refs in evaluation.items()}
            for name, y in ({s: pooled(g) for s, g in references.items()} | everything).items()
        }
        report["sources"] = {"sources": sources, "flights": flights}
    for case, grouped in evaluation.items():
        tables[f"evaluation case {case}"] = grouped_spread(grouped)
    print(spread_markdown(tables))
    if "inside" in report:
        print(inside_markdown(report["inside"]))
    default = "coverage.json" if args.dataset else "coverage_sources.json"
    path = args.json or default_result_path(default)
    atomic_write_json(path, report | {"tables": tables})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
