"""Tuned MCA configs against their baselines on evaluation flights.

    python benchmarks/bench_tuned.py --nmpc nmpc-rti --washout washout [--flights 10]
        [--duration 120] [--workers 2] [--json results/tuned.json]

NMPC-rti at the tuned config against the paper's weights (`NmpcConfig.paper()`), and the
tuned washout against zero motion, each on the first `--flights` evaluation flights of the
light aircraft (seeds 1000 on) and of the jet (2000 on), `--duration` s each, on the
analytical plant. Prints per flight and per vehicle the PIs, the median PI gain and on how
many flights the tuned config is better, the step-time p99 of the tuned NMPC, and the
machine's calibration (`common.calibration_s`). Runs are tasks of
`mca_drake.studies.parallel.run_tasks` (a local Ray with `--workers` CPUs). `--nmpc` and
`--washout` take a best.yaml of `mca-drake tune` or an MCA name (its defaults: the shipped,
tuned configs). Writes the figures with their provenance (date, command, calibration,
machine) to `--json`, by default `benchmarks/results/tuned.json`.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.app.scenarios import load_scenario
from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing import NmpcConfig, mca_config_from_name
from mca_drake.platforms.files import load_platform
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.parallel import run_tasks

KR500 = load_platform("kr500")

REPO = Path(__file__).resolve().parents[1]


def tuned_config(path: str):
    """The MCA of a best.yaml (a scenario override) of `mca-drake tune`; "nmpc-rti" or
    "washout": the shipped defaults (the tuned ones)."""
    if path in ("nmpc-rti", "washout"):
        return mca_config_from_name(path)
    text = Path(path).read_text()
    return load_scenario(REPO / "diagrams" / "closed_loop_dpc.yaml", text).mca


def _run(label: str, config, vehicle: str, seed: int, duration: float, out: str) -> None:
    reference = flight_reference(
        FlightSpec(vehicle=vehicle, seed=seed), duration, cache_dir=Path(out) / "flights"
    )
    s = run_closed_loop(
        mca=config, reference=reference, duration_s=duration, progress=False, robot=KR500
    )
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
    parser.add_argument("--nmpc", help="best.yaml of the NMPC tune, or nmpc-rti (the defaults)")
    parser.add_argument("--washout", help="best.yaml of the washout tune, or washout")
    parser.add_argument("--flights", type=int, default=10)
    parser.add_argument("--duration", type=float, default=120.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--json", default=default_result_path("tuned.json"), help="write the figures here"
    )
    args = parser.parse_args()
    configs = {}
    if args.nmpc:
        configs |= {"nmpc_tuned": tuned_config(args.nmpc), "nmpc_paper": NmpcConfig.paper()}
    if args.washout:
        configs["washout_tuned"] = tuned_config(args.washout)
    if not configs:
        parser.error("give --nmpc and/or --washout")
    flights = [
        (v, base + k) for v, base in (("light", 1000), ("jet", 2000)) for k in range(args.flights)
    ]
    calibration = print_calibration()
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
        f = figures[vehicle] = {"flights": len(seeds)}

        def pis(label, key="pi", seeds=seeds, vehicle=vehicle):
            return np.array([runs[(label, vehicle, s)][key] for s in seeds])

        print(f"\n{vehicle}: flight, " + ", ".join(configs) + ", zero motion")
        label0 = next(iter(configs))
        columns = [pis(label) for label in configs] + [pis(label0, "pi_zero_motion")]
        for k, s in enumerate(seeds):
            print(f"  {s}: " + " ".join(f"{c[k]:7.3f}" for c in columns))
        zero = pis(label0, "pi_zero_motion")
        f["zero_motion_median"] = float(np.median(zero))
        f["violations"] = int(
            sum(runs[(label, vehicle, s)]["violations"] for label in configs for s in seeds)
        )
        if "nmpc_tuned" in configs:
            tuned, paper = pis("nmpc_tuned"), pis("nmpc_paper")
            p99 = pis("nmpc_tuned", "p99") * 1e3
            f |= {
                "nmpc_tuned_median": float(np.median(tuned)),
                "nmpc_paper_median": float(np.median(paper)),
                "median_gain": float(np.median(paper) - np.median(tuned)),
                "tuned_better_on": int(np.sum(tuned < paper)),
                "nmpc_tuned_step_p99_ms": {
                    "median": float(np.median(p99)),
                    "max": float(p99.max()),
                },
                "joint_range_used": {
                    "tuned": float(np.median(pis("nmpc_tuned", "range"))),
                    "paper": float(np.median(pis("nmpc_paper", "range"))),
                },
            }
            print(
                f"  NMPC-rti median PI tuned {f['nmpc_tuned_median']:.3f} vs paper "
                f"{f['nmpc_paper_median']:.3f}: gain {f['median_gain']:+.3f}, tuned better on "
                f"{f['tuned_better_on']} of {len(seeds)}; step p99 median {np.median(p99):.2f} ms"
                f" (max {p99.max():.2f}); joint range used {f['joint_range_used']}"
            )
        if "washout_tuned" in configs:
            washout = pis("washout_tuned")
            f |= {
                "washout_median": float(np.median(washout)),
                "washout_beats_zero_on": int(np.sum(washout < zero)),
            }
            print(
                f"  washout median PI {f['washout_median']:.3f} vs zero motion "
                f"{f['zero_motion_median']:.3f}: better on {f['washout_beats_zero_on']} of "
                f"{len(seeds)}"
            )
        print(f"  violations: {f['violations']}")
    atomic_write_json(args.json, {"provenance": result_header(calibration), "vehicles": figures})


if __name__ == "__main__":
    main()
