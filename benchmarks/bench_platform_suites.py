"""The evaluation suite on every packaged platform, at a size two cores run in an hour.

    python benchmarks/bench_platform_suites.py [--flights 2] [--duration 120]
        [--mcas dpc,nmpc-rti,washout] [--platforms kr500,kr500-rail,fanuc-m900ib700]
        [--workers 1] [--runs-dir results/platform_suites] [--json results/platform_suites.json]
        [--keep-others]

Runs the suite's cases A-E (`mca_drake.studies.evaluation_cases.default_cases`: the light
aircraft, the jet, aircraft neither trained nor tuned on, drives, the route pilot's flights)
with their first `--flights` seeds each, through each MCA as its name means on each platform
(the platform's shipped policy, its tuned settings), on every packaged platform, in one run
on one machine: the suite of `mca-drake evaluate --suite --platform P` for every P, cut to a
size that runs where the converged NMPC's core-hours do not (`--mcas` adds it). The flights
are flown once for all platforms (one cache). Runs are resumable (`--runs-dir`, one folder
per platform). Writes per platform, case and MCA: median PI and perceived PI, the worst
flight, flights better than zero motion, joint range used, violations and safety
interventions; and per platform and MCA the median PI and perceived PI over every flight
(a platform that ships no DPC policy runs without the DPC: `skipped`); with the date,
command, machine and calibration, to `--json` (default
`benchmarks/results/platform_suites.json`). With `--keep-others` what this run does not
run keeps its figures from that file: the platforms not run, each with the date and
calibration of the run that made it (`run`), and on a platform run again the MCAs not run
(`kept_mcas`). The figures are deterministic, so an MCA whose policy or settings changed is
rerun alone (`--platforms hexapod --mcas dpc --keep-others`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing import DpcConfig, mca_config_from_name
from mca_drake.platforms.files import load_platform, packaged_platforms
from mca_drake.studies.evaluation import run_evaluation
from mca_drake.studies.evaluation_cases import EvaluationConfig, default_cases

# The figures kept per case and MCA from the suite's report (`evaluation.json`).
KEPT = (
    "runs",
    "pi_median",
    "perceived_pi_median",
    "pi_zero_motion_median",
    "better_than_zero_motion",
    "joint_range_used_median",
    "violations",
    "safety_interventions",
)


def has_policy(platform: str) -> bool:
    """Whether the platform ships DPC policies (else the suite runs without the DPC)."""
    try:
        DpcConfig().policy_path(platform)
    except FileNotFoundError:
        return False
    return True


def platform_suite(platform: str, args, runs_dir: Path) -> dict:
    """The cut suite on `platform`: its report's figures per case and MCA, and per MCA the
    median over every flight of every case."""
    cases = tuple(dataclasses.replace(c, seeds=c.seeds[: args.flights]) for c in default_cases())
    names = [m for m in args.mcas.split(",") if m != "dpc" or has_policy(platform)]
    config = EvaluationConfig(
        mcas=tuple(mca_config_from_name(m) for m in names),
        cases=cases,
        duration_s=args.duration,
        platform=platform,
    )
    out = runs_dir / platform
    out.mkdir(parents=True, exist_ok=True)
    flights = out / "flights"
    if not flights.exists():  # every platform flies the same flights: one cache
        (runs_dir / "flights").mkdir(exist_ok=True)
        flights.symlink_to(Path("..") / "flights", target_is_directory=True)
    report = run_evaluation(config, out, workers=args.workers, progress=True)
    skipped = sorted(set(args.mcas.split(",")) - set(names))
    result: dict = {"cases": {}, "all": {}, "skipped": skipped}
    every: dict[str, list[float]] = {}
    perceived: dict[str, list[float]] = {}
    for name, case in report["cases"].items():
        result["cases"][name] = {
            "vehicle": case["vehicle"],
            "mcas": {m: {k: e[k] for k in KEPT} for m, e in case["mcas"].items()},
        }
        for m, e in case["mcas"].items():
            every.setdefault(m, []).extend(e["pi"])
            perceived.setdefault(m, []).extend(e["perceived_pi"])
    for m, pis in every.items():
        result["all"][m] = {
            "flights": len(pis),
            "pi_median": float(np.median(pis)),
            "perceived_pi_median": float(np.median(perceived[m])),
        }
    return result


def kept_platforms(args) -> dict:
    """Every platform's entry in the existing `--json` file (made with the same flights and
    duration, else ValueError), each with the date and calibration of its run."""
    path = Path(args.json)
    if not path.is_file():
        return {}
    old = json.loads(path.read_text())
    if (old["flights_per_case"], old["duration_s"]) != (args.flights, args.duration):
        raise ValueError(
            f"{path} holds {old['flights_per_case']} flights of {old['duration_s']} s per "
            f"case, not {args.flights} of {args.duration} s: rerun every platform"
        )
    date = old["provenance"]["date"]
    calibration = old["provenance"]["calibration"]
    return {
        name: {"run": {"date": date, "calibration": calibration}, **entry}
        for name, entry in old["platforms"].items()
    }


def with_kept_mcas(entry: dict, old: dict | None) -> dict:
    """A platform's new `entry` with the MCAs of its `old` entry that this run did not run
    (per case and over every flight), named in `kept_mcas` with the date of their run."""
    if old is None:
        return entry
    kept = sorted(set(old["all"]) - set(entry["all"]))
    for name, case in entry["cases"].items():
        for mca in kept:
            if mca in old["cases"][name]["mcas"]:
                case["mcas"][mca] = old["cases"][name]["mcas"][mca]
    entry["all"] |= {mca: old["all"][mca] for mca in kept}
    entry["skipped"] = sorted(set(entry["skipped"]) - set(kept))
    entry["kept_mcas"] = {mca: old["run"]["date"] for mca in kept}
    return entry


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=2, help="first seeds of each case")
    parser.add_argument("--duration", type=float, default=120.0, help="s per flight")
    parser.add_argument("--mcas", default="dpc,nmpc-rti,washout")
    parser.add_argument("--platforms", default=",".join(packaged_platforms()))
    parser.add_argument("--workers", type=int, default=1, help="CPUs of a local Ray")
    parser.add_argument("--runs-dir", default="results/platform_suites")
    parser.add_argument("--json", default=default_result_path("platform_suites.json"))
    parser.add_argument(
        "--keep-others", action="store_true", help="keep the --json file's other platforms"
    )
    args = parser.parse_args()
    calibration = print_calibration()
    header = result_header(calibration)
    runs_dir = Path(args.runs_dir).resolve()
    results = kept_platforms(args) if args.keep_others else {}
    for platform in args.platforms.split(","):
        entry = {
            "platform": load_platform(platform).summary(),
            "run": {"date": header["date"], "calibration": header["calibration"]},
            **platform_suite(platform, args, runs_dir),
        }
        results[platform] = with_kept_mcas(entry, results.get(platform))
    print()
    for platform, figures in results.items():
        for mca, entry in figures["all"].items():
            cases = ", ".join(
                f"{c} {figures['cases'][c]['mcas'][mca]['pi_median']:.3f}"
                for c in figures["cases"]
                if mca in figures["cases"][c]["mcas"]
            )
            print(
                f"{platform:>16} {mca:>9}: median PI {entry['pi_median']:.3f} over "
                f"{entry['flights']} flights ({cases})"
            )
    atomic_write_json(
        args.json,
        {
            "provenance": header,
            "flights_per_case": args.flights,
            "duration_s": args.duration,
            "platforms": results,
        },
    )
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
