"""Perceived motion: the NMPC's perceived objective against its inertial one, and the suite's
PI and perceived PI per MCA.

    python benchmarks/bench_perceived.py [--duration 300] [--vehicle light] [--seed 1000]
        [--repeats 2] [--suite benchmarks/results/evaluation] [--json results/perceived.json]
        [--suite-only]

1. NMPC-rti at the shipped (tuned) weights with the inertial and the perceived objective on
   one evaluation flight (analytical plant, closed loop), alternated `--repeats` times in
   this run so that both see the same load: step median, p99 and max (ms), the PI and the
   perceived PI (`mca_drake.perception`). The perceived objective's target is a p99 of 5 ms.
2. From the evaluation suite's run files (`--suite`, as `mca-drake evaluate --suite` leaves
   them): per case and MCA, the median PI and perceived PI with their interquartile ranges,
   zero motion's, and what the runs cost in core-hours (their wall times: each run is one
   core's work).

The machine's calibration is printed first; every figure goes to `--json` with its
provenance, by default `benchmarks/results/perceived.json`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing import NmpcConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")

OBJECTIVES = ("inertial", "perceived")


def measure_objectives(vehicle: str, seed: int, duration_s: float, repeats: int) -> dict:
    """Both objectives of NMPC-rti on one flight, alternated: per objective the step times of
    every run (ms) and the PI and perceived PI (the same in every run: deterministic)."""
    reference = flight_reference(FlightSpec(vehicle=vehicle, seed=seed), duration_s)
    figures = {o: {"runs": []} for o in OBJECTIVES}
    for repeat in range(repeats):
        for objective in OBJECTIVES:
            result = run_closed_loop(
                mca=NmpcConfig(mode="rti", objective=objective),
                reference=reference,
                progress=False,
                robot=KR500,
            )
            s = result.summary
            steps = s["step_time_s"]
            run = {k: steps[k] * 1e3 for k in ("median", "p99", "max")}
            figures[objective]["runs"].append(run)
            figures[objective] |= {
                "pi": s["pi"],
                "perceived_pi": s["perceived"]["pi"],
                "pi_zero_motion": s["pi_zero_motion"],
                "perceived_pi_zero_motion": s["perceived"]["pi_zero_motion"],
                "solver_failures": s["solver_failures"],
                "violations": s["violations"],
            }
            print(
                f"run {repeat + 1}/{repeats} {objective}: step median {run['median']:.3f} ms, "
                f"p99 {run['p99']:.3f} ms, max {run['max']:.2f} ms; PI {s['pi']:.3f}, "
                f"perceived PI {s['perceived']['pi']:.3f}",
                flush=True,
            )
    for entry in figures.values():
        for key in ("median", "p99", "max"):
            values = [r[key] for r in entry["runs"]]
            entry[f"{key}_ms"] = {
                "median": float(np.median(values)),
                "min": float(min(values)),
                "max": float(max(values)),
            }
    return figures


def _spread(values: list[float]) -> dict:
    return {
        "median": float(np.median(values)),
        "iqr": [float(np.percentile(values, 25)), float(np.percentile(values, 75))],
    }


def suite_figures(runs_dir: Path) -> dict:
    """Per case and MCA, from the suite's run files that carry a perceived block: flights,
    PI and perceived PI (median, IQR), zero motion's medians and the core-hours spent."""
    cases: dict = {}
    for path in sorted(runs_dir.glob("*.json")):
        run = json.loads(path.read_text())
        if not isinstance(run, dict) or "perceived" not in run:
            continue
        cases.setdefault(run["case"], {}).setdefault(run["mca"], []).append(run)
    out = {}
    for case, mcas in sorted(cases.items()):
        out[case] = {}
        for mca, runs in sorted(mcas.items()):
            out[case][mca] = {
                "flights": len(runs),
                "pi": _spread([r["pi"] for r in runs]),
                "perceived_pi": _spread([r["perceived"]["pi"] for r in runs]),
                "pi_zero_motion_median": float(np.median([r["pi_zero_motion"] for r in runs])),
                "perceived_pi_zero_motion_median": float(
                    np.median([r["perceived"]["pi_zero_motion"] for r in runs])
                ),
                "core_hours": float(sum(r["wall_time_s"] for r in runs) / 3600.0),
            }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=300.0, help="flight length, s")
    parser.add_argument("--vehicle", default="light")
    parser.add_argument("--seed", type=int, default=1000, help="an evaluation flight's seed")
    parser.add_argument("--repeats", type=int, default=2, help="runs per objective")
    parser.add_argument(
        "--suite",
        default=default_result_path("evaluation"),
        help="the evaluation suite's folder (its runs/ are read)",
    )
    parser.add_argument("--json", default=default_result_path("perceived.json"))
    parser.add_argument(
        "--suite-only",
        action="store_true",
        help="refresh the suite's figures only, keeping the step times already in --json "
        "(their measurement's provenance kept beside the new one)",
    )
    args = parser.parse_args()
    calibration = print_calibration()
    result = {"provenance": result_header(calibration)}
    if args.suite_only:
        kept = json.loads(Path(args.json).read_text())
        result["timing_provenance"] = kept.get("timing_provenance", kept["provenance"])
        result |= {"flight": kept["flight"], "objectives": kept["objectives"]}
    else:
        result["flight"] = {"vehicle": args.vehicle, "seed": args.seed, "duration_s": args.duration}
        result["objectives"] = measure_objectives(
            args.vehicle, args.seed, args.duration, args.repeats
        )
    result["suite"] = suite_figures(Path(args.suite) / "runs")
    for case, mcas in result["suite"].items():
        for mca, m in mcas.items():
            print(
                f"case {case} {mca}: {m['flights']} flights, PI {m['pi']['median']:.3f}, "
                f"perceived PI {m['perceived_pi']['median']:.3f}, {m['core_hours']:.2f} "
                "core-hours"
            )
    atomic_write_json(args.json, result)
    print(f"figures: {args.json}")


if __name__ == "__main__":
    main()
