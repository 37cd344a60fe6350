"""A legged platform's shipped DPC policies against the alternatives they were chosen over and
the NMPC-rti, on validation flights and drives that nothing trains or tunes on.

    python benchmarks/bench_platform_selection.py [--platforms hexapod,rig-2dof,rig-3dof]
        [--candidates LABEL=POLICY.npz,...] [--duration 120] [--out-dir results/platform_selection]
        [--json benchmarks/results/platform_selection.json]

Flies the validation flights of `bench_platforms.py` (light aircraft and jet in turn, seeds
700-703) and two drives of each car (seeds 700 and 701: a lap and the proving ground; not
the suite's case D) on each platform's analytical plant, through `dpc` as its name means
there (the policy the platform picks for each vehicle: `DpcConfig.policy_path`), the
NMPC-rti with the platform's tuned settings and each candidate policy file given (a
training run's `policy.npz`, labelled; the same candidates on every platform listed, so
give one platform at a time with them). Runs are kept under --out-dir (one JSON per run,
resumable; a run of a policy file that has changed since is flown again). Writes per
platform and MCA the median PI on the flights and on the drives, the worst run against not
moving (PI - PI of zero motion), the runs better than not moving, the clamp's interventions
and violations, with each run's PI; with the date, command and calibration.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from bench_platforms import FIRST_SEED, VEHICLES
from bench_validation import finished_run
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing import DpcConfig, mca_config_from_name
from mca_drake.cueing.configs import on_platform
from mca_drake.platforms.files import load_platform
from mca_drake.references.drives import is_car, motion_reference, training_spec
from mca_drake.references.driving import CARS
from mca_drake.references.flights import FlightSpec
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.evaluation import policy_fingerprint

FLIGHTS = tuple((VEHICLES[i % len(VEHICLES)], FIRST_SEED + i) for i in range(4))
DRIVES = tuple((car, FIRST_SEED + i) for car in CARS for i in range(2))


def mca_for(label: str, policy: str, platform: str, vehicle: str):
    """The MCA config of `label` on `platform` for `vehicle`: the platform's own pick for
    "dpc", its tuned NMPC-rti for "nmpc-rti", else the candidate policy file."""
    if label == "nmpc-rti":
        return on_platform(mca_config_from_name("nmpc-rti"), platform)
    if label == "dpc":
        return DpcConfig(vehicle=vehicle)
    return DpcConfig(policy=policy, vehicle=vehicle)


def run_once(label, policy, platform, robot, vehicle, seed, args, out: Path) -> dict:
    """One run's figures, from out/<label>_<vehicle>_<seed>.json when it is there for the
    same policy file."""
    config = mca_for(label, policy, platform, vehicle)
    fingerprint = policy_fingerprint(config, platform)
    path = out / f"{label}_{vehicle}_{seed}.json"
    if finished_run(path, fingerprint):
        return json.loads(path.read_text())
    spec = (
        training_spec(vehicle, seed) if is_car(vehicle) else FlightSpec(vehicle=vehicle, seed=seed)
    )
    reference = motion_reference(spec, args.duration, cache_dir=Path(args.out_dir) / "flights")
    summary = run_closed_loop(mca=config, reference=reference, progress=False, robot=robot).summary
    figures = {
        "pi": summary["pi"],
        "pi_zero_motion": summary["pi_zero_motion"],
        "violations": int(sum(summary["violations"].values())),
        "safety_interventions": summary["safety_interventions"],
        "policy_sha256": fingerprint,
    }
    atomic_write_json(path, figures)
    return figures


def figures_of(runs: dict) -> dict:
    """Medians on the flights and drives, and the worst run against not moving."""
    flights = [r["pi"] for (vehicle, _), r in runs.items() if not is_car(vehicle)]
    drives = [r["pi"] for (vehicle, _), r in runs.items() if is_car(vehicle)]
    against_zero = [r["pi"] - r["pi_zero_motion"] for r in runs.values()]
    return {
        "flights_pi_median": float(np.median(flights)),
        "drives_pi_median": float(np.median(drives)),
        "worst_against_zero_motion": float(max(against_zero)),
        "better_than_zero_motion": int(sum(d < 0 for d in against_zero)),
        "runs": len(runs),
        "safety_interventions": int(sum(r["safety_interventions"] for r in runs.values())),
        "violations": int(sum(r["violations"] for r in runs.values())),
        "pi": {f"{v}_{s}": r["pi"] for (v, s), r in runs.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--platforms", default="hexapod,rig-2dof,rig-3dof")
    parser.add_argument("--candidates", default="", help="LABEL=POLICY.npz,...")
    parser.add_argument("--duration", type=float, default=120.0, help="s per run")
    parser.add_argument("--out-dir", default="results/platform_selection")
    parser.add_argument("--json", default=default_result_path("platform_selection.json"))
    args = parser.parse_args()
    candidates = dict(c.split("=", 1) for c in args.candidates.split(",") if c)
    for label, policy in candidates.items():
        if label in ("dpc", "nmpc-rti") or not Path(policy).is_file():
            parser.error(f"candidate {label}={policy}: a new label and an existing file")
    calibration = print_calibration()
    results = {}
    for platform in args.platforms.split(","):
        robot = load_platform(platform)
        out = Path(args.out_dir) / platform
        out.mkdir(parents=True, exist_ok=True)
        mcas = {"dpc": "", "nmpc-rti": "", **candidates}
        results[platform] = {}
        for label, policy in mcas.items():
            runs = {
                (vehicle, seed): run_once(label, policy, platform, robot, vehicle, seed, args, out)
                for vehicle, seed in FLIGHTS + DRIVES
            }
            entry = figures_of(runs) | ({"policy": policy} if policy else {})
            results[platform][label] = entry
            print(
                f"{platform:>9} {label:>14}: median PI flights {entry['flights_pi_median']:.3f}"
                f", drives {entry['drives_pi_median']:.3f}, worst against zero motion "
                f"{entry['worst_against_zero_motion']:+.3f}, interventions "
                f"{entry['safety_interventions']}",
                flush=True,
            )
    atomic_write_json(
        args.json,
        {"provenance": result_header(calibration), "duration_s": args.duration, **results},
    )
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
