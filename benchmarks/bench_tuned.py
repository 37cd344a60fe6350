"""Tuned MCA configs against their baselines on evaluation flights (issue 17's figures).

    python benchmarks/bench_tuned.py --nmpc results/tune_nmpc/best.yaml \
        --washout results/tune_washout/best.yaml [--flights 10] [--duration 120] [--workers 2]

NMPC-rti at the tuned config against the paper's weights (`NmpcConfig.paper()`), and the
tuned washout against zero motion, each on the first `--flights` evaluation flights of the
light aircraft (seeds 1000 on) and of the jet (2000 on), `--duration` s each, on the
analytical plant. Prints per flight and per vehicle the PIs, the median PI gain and on how
many flights the tuned config is better, the step-time p99 of the tuned NMPC, and the
machine's calibration (`bench_closed_loop.calibration_s`). Runs are tasks of
`mca_drake.studies.parallel.run_tasks` (a local Ray with `--workers` CPUs).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from bench_closed_loop import calibration_s

from mca_drake.app.scenarios import load_scenario
from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing import NmpcConfig
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.parallel import run_tasks

REPO = Path(__file__).resolve().parents[1]


def tuned_config(path: str):
    """The MCA of a best.yaml (a scenario override) of `mca-drake tune`."""
    text = Path(path).read_text()
    return load_scenario(REPO / "diagrams" / "closed_loop_dpc.yaml", text).mca


def _run(label: str, config, vehicle: str, seed: int, duration: float, out: str) -> None:
    reference = flight_reference(
        FlightSpec(vehicle=vehicle, seed=seed), duration, cache_dir=Path(out) / "flights"
    )
    s = run_closed_loop(mca=config, reference=reference, duration_s=duration, progress=False)
    summary = s.summary
    atomic_write_json(
        Path(out) / f"{label}_{vehicle}_{seed}.json",
        {
            "pi": summary["pi"],
            "pi_zero_motion": summary["pi_zero_motion"],
            "p99": summary["step_time_s"]["p99"],
            "max": summary["step_time_s"]["max"],
            "violations": sum(summary["violations"].values()),
            "range": max(summary["joint_range_used"]),
        },
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nmpc", required=True, help="best.yaml of the NMPC tune")
    parser.add_argument("--washout", required=True, help="best.yaml of the washout tune")
    parser.add_argument("--flights", type=int, default=10)
    parser.add_argument("--duration", type=float, default=120.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", help="also write the figures here")
    args = parser.parse_args()
    configs = {
        "nmpc_tuned": tuned_config(args.nmpc),
        "nmpc_paper": NmpcConfig.paper(),
        "washout_tuned": tuned_config(args.washout),
    }
    flights = [
        (v, base + k) for v, base in (("light", 1000), ("jet", 2000)) for k in range(args.flights)
    ]
    print(f"calibration: {calibration_s()}")
    with tempfile.TemporaryDirectory() as tmp:
        tasks = [
            (label, config, v, s, args.duration, tmp)
            for v, s in flights
            for label, config in configs.items()
        ]
        run_tasks(_run, tasks, workers=args.workers, description="runs")
        runs = {
            (label, v, s): json.loads(Path(tmp, f"{label}_{v}_{s}.json").read_text())
            for label, _, v, s, _, _ in tasks
        }
    figures = {}
    for vehicle in ("light", "jet"):
        seeds = [s for v, s in flights if v == vehicle]
        tuned = np.array([runs[("nmpc_tuned", vehicle, s)]["pi"] for s in seeds])
        paper = np.array([runs[("nmpc_paper", vehicle, s)]["pi"] for s in seeds])
        washout = np.array([runs[("washout_tuned", vehicle, s)]["pi"] for s in seeds])
        zero = np.array([runs[("washout_tuned", vehicle, s)]["pi_zero_motion"] for s in seeds])
        p99 = [runs[("nmpc_tuned", vehicle, s)]["p99"] for s in seeds]
        violations = sum(runs[(k, vehicle, s)]["violations"] for k in configs for s in seeds)
        print(f"\n{vehicle}: flight, NMPC tuned, NMPC paper, washout tuned, zero motion")
        for k, s in enumerate(seeds):
            print(f"  {s}: {tuned[k]:7.3f} {paper[k]:7.3f} {washout[k]:7.3f} {zero[k]:7.3f}")
        gain = float(np.median(paper) - np.median(tuned))
        figures[vehicle] = {
            "nmpc_tuned_median": float(np.median(tuned)),
            "nmpc_paper_median": float(np.median(paper)),
            "median_gain": gain,
            "tuned_better_on": int(np.sum(tuned < paper)),
            "washout_median": float(np.median(washout)),
            "zero_motion_median": float(np.median(zero)),
            "washout_beats_zero_on": int(np.sum(washout < zero)),
            "nmpc_tuned_step_p99_ms": {
                "median": float(np.median(p99) * 1e3),
                "max": float(np.max(p99) * 1e3),
            },
            "violations": int(violations),
            "flights": len(seeds),
        }
        f = figures[vehicle]
        print(
            f"  NMPC-rti median PI tuned {f['nmpc_tuned_median']:.3f} vs paper "
            f"{f['nmpc_paper_median']:.3f}: gain {gain:+.3f}, tuned better on "
            f"{f['tuned_better_on']} of {len(seeds)}; washout {f['washout_median']:.3f} vs zero "
            f"motion {f['zero_motion_median']:.3f}, better on {f['washout_beats_zero_on']} of "
            f"{len(seeds)}; tuned NMPC step p99 median {f['nmpc_tuned_step_p99_ms']['median']:.2f}"
            f" ms (max {f['nmpc_tuned_step_p99_ms']['max']:.2f}); violations {violations}"
        )
    if args.json:
        atomic_write_json(args.json, figures)


if __name__ == "__main__":
    main()
