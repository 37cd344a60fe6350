"""The default DPC on references that name no vehicle: every suite case's flights cued as a
recording that names none would be, against the NMPC-rti on the same flights.

    python benchmarks/bench_unnamed.py [--cases A,B,C,D,E] [--flights 10] [--duration 300]
        [--runs-dir results/unnamed] [--suite benchmarks/results/evaluation/evaluation.json]
        [--json benchmarks/results/unnamed.json]
    python benchmarks/bench_unnamed.py --pilot human --cases A,B,C --flights 4

`--pilot human` flies the flight cases' aircraft and seeds with the human-operator pilot
that no training flies (`FlightSpec(pilot="human")`) instead, and cues each with the
NMPC-rti too (the suite has no such runs); its figures go to
`benchmarks/results/unnamed_human.json`.

Flies the suite's cases (`mca_drake.studies.evaluation_cases.default_cases`: the light
aircraft, the jet, aircraft neither trained nor tuned on, drives, the route pilot's
flights), their first `--flights` seeds, and cues each reference with its vehicle's name
taken away through `DpcConfig()` (the vehicle recognized from the reference,
`DpcConfig.unnamed = "recognize"`) and through `DpcConfig(unnamed="default")` (the default
policy throughout, what an unnamed reference got before). The NMPC-rti's PI on each flight
is the suite's (`--suite`, its runs of the same flights and duration; the NMPC does not
read the vehicle's name, and for the drives also the ground profile's `nmpc-rti-ground`).
Runs are resumable (`--runs-dir`, one JSON per flight and DPC). Prints and writes per case:
the median PI of each DPC and of the NMPC-rti, the paired difference DPC - NMPC-rti
(median, worst flight, and the worst among the flights whose report does not suggest the
NMPC: `report.suggests_nmpc`), flights better
than zero motion, and which policy each flight ended with; with the date, command, machine
and calibration, to `--json` (default `benchmarks/results/unnamed.json`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from collections import Counter
from pathlib import Path

import numpy as np
from common import default_result_path, print_calibration, result_header

from mca_drake.app.cli.report import OUT_OF_RANGE_NOTICE, suggests_nmpc
from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing.configs import mca_config_from_name
from mca_drake.cueing.dpc import DpcConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.drives import motion_reference
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.evaluation_cases import default_cases, policy_fingerprint

# The DPCs compared, by label: the vehicle recognized from the reference, and the default
# policy throughout.
DPCS = {"recognized": DpcConfig(), "default": DpcConfig(unnamed="default")}
# The suite's MCAs each flight is compared with (those a case's report holds).
NMPCS = ("nmpc-rti", "nmpc-rti-ground")
KEPT = ("pi", "pi_zero_motion", "violations", "safety_interventions", "policy_file")
KEPT += ("out_of_distribution",)


def run_case(
    case, seeds, duration_s: float, runs_dir: Path, robot, pilot: str = "", mcas=None
) -> dict:
    """{label: {seed: summary}} of the case's flights, cued unnamed by each of `mcas`
    (default DPCS; runs on disk made with the same policies are kept); `pilot`: flown by
    this pilot instead of the case's."""
    mcas = DPCS if mcas is None else mcas
    results: dict[str, dict[int, dict]] = {label: {} for label in mcas}
    tag = f"_{pilot}" if pilot else ""
    for seed in seeds:
        reference = None
        for label, config in mcas.items():
            path = runs_dir / f"{case.name}_{label}_{seed}{tag}.json"
            # the policies and the recognizer's settings: a run of others is flown again
            fingerprint = policy_fingerprint(config, robot.name)
            made = {"policy_sha256": fingerprint, "duration_s": duration_s}
            run = json.loads(path.read_text()) if path.is_file() else {}
            if any(run.get(k) != v for k, v in made.items()):
                if reference is None:
                    spec = case.spec_of(seed)
                    if pilot:
                        spec = dataclasses.replace(spec, pilot=pilot)
                    named = motion_reference(spec, duration_s, cache_dir=runs_dir / "flights")
                    reference = dataclasses.replace(named, vehicle="")  # as a recording
                result = run_closed_loop(
                    mca=config, reference=reference, robot=robot, progress=False
                )
                run = {k: result.summary.get(k) for k in KEPT}
                run["policy_changes"] = result.summary.get("policy_changes", [])
                run |= made
                atomic_write_json(path, run)
                print(f"{case.name} {seed} {label}: PI {run['pi']:.3f}", flush=True)
            results[label][seed] = run
    return results


def case_figures(results: dict, suite_case: dict | None, seeds) -> dict:
    """The figures of one case: per DPC the median PI, flights better than zero motion,
    violations and the policies the flights ended with; against each NMPC of the suite on
    the same seeds the paired difference (median, worst flight)."""
    figures: dict = {}
    for label, runs in results.items():
        pis = np.array([runs[s]["pi"] for s in seeds])
        zero = np.array([runs[s]["pi_zero_motion"] for s in seeds])
        shares = [(runs[s]["out_of_distribution"] or {"share": np.nan})["share"] for s in seeds]
        flagged = np.array([suggests_nmpc(runs[s]["out_of_distribution"]) for s in seeds])
        entry = {
            "pi_median": float(np.median(pis)),
            "better_than_zero_motion": int(np.sum(pis < zero)),
            "worst_against_zero_motion": float(np.max(pis - zero)),
            "violations": int(sum(sum(runs[s]["violations"].values()) for s in seeds)),
            "ended_with": dict(Counter(runs[s]["policy_file"] for s in seeds)),
            # share of the time the reference lay outside the running policy's training
            # range (`out_of_distribution`), median and largest over the flights
            "out_of_distribution_median": float(np.median(shares)),
            "out_of_distribution_max": float(np.max(shares)),
            # flights whose report suggests the NMPC (`suggests_nmpc`): the guard a user sees
            "flagged": int(np.sum(flagged)),
        }
        for nmpc in NMPCS:
            other = (suite_case or {}).get("mcas", {}).get(nmpc)
            if other is None:
                continue
            by_seed = dict(zip(other["seeds"], other["pi"], strict=True))
            if not all(s in by_seed for s in seeds):
                continue
            diff = pis - np.array([by_seed[s] for s in seeds])
            worst = int(np.argmax(diff))
            entry[f"vs_{nmpc}"] = {
                "nmpc_pi_median": float(np.median([by_seed[s] for s in seeds])),
                "median_difference": float(np.median(diff)),
                "worst_difference": float(diff[worst]),
                "worst_seed": int(seeds[worst]),
                "behind_by_more_than_0.2": int(np.sum(diff > 0.2)),
                # the same among the flights the guard did not flag (None: it flagged all)
                "worst_difference_unflagged": (
                    float(np.max(diff[~flagged])) if np.any(~flagged) else None
                ),
                "behind_by_more_than_0.2_unflagged": int(np.sum(diff[~flagged] > 0.2)),
            }
        figures[label] = entry
    return figures


def print_case(name: str, dpcs: dict, flights: int) -> None:
    """One line per DPC of a case's figures."""
    for label, entry in dpcs.items():
        versus = entry.get("vs_nmpc-rti", {})
        print(
            f"case {name} {label:10s} median PI {entry['pi_median']:.3f}; against the "
            f"NMPC-rti median {versus.get('median_difference', float('nan')):+.3f}, worst "
            f"{versus.get('worst_difference', float('nan')):+.3f}; better than zero motion "
            f"on {entry['better_than_zero_motion']}/{flights}; outside the training "
            f"range {entry['out_of_distribution_median']:.1%} (median); ended with "
            f"{entry['ended_with']}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", default="A,B,C,D,E", help="suite cases (default all)")
    parser.add_argument("--flights", type=int, default=10, help="seeds per case (default 10)")
    parser.add_argument("--duration", type=float, default=300.0, help="s per flight")
    parser.add_argument("--runs-dir", default="results/unnamed")
    parser.add_argument(
        "--suite",
        default=str(default_result_path("evaluation/evaluation.json")),
        help="the suite's report whose NMPC-rti runs of the same flights are compared",
    )
    parser.add_argument(
        "--pilot",
        choices=("", "human"),
        default="",
        help="'human': the flight cases flown by the human-operator pilot, each also cued by "
        "the NMPC-rti (default: the suite's own flights, against the suite's NMPC-rti)",
    )
    parser.add_argument(
        "--json", help="default benchmarks/results/unnamed.json (unnamed_human.json)"
    )
    args = parser.parse_args()
    calibration = print_calibration()
    suite = None
    if not args.pilot:  # the suite's own NMPC-rti runs of the same flights
        suite = json.loads(Path(args.suite).read_text())
        if abs(suite["duration_s"] - args.duration) > 1e-9:
            raise SystemExit(
                f"--suite {args.suite} flew {suite['duration_s']} s flights, not {args.duration}"
            )
    robot = load_platform("kr500")
    runs_dir = Path(args.runs_dir)
    runs_dir.mkdir(parents=True, exist_ok=True)
    # another pilot's flights have no suite runs: the NMPC-rti is flown on them here
    mcas = {**DPCS, "nmpc-rti": mca_config_from_name("nmpc-rti")} if args.pilot else DPCS
    figures: dict = {}
    for case in default_cases():
        if case.name not in args.cases.split(","):
            continue
        # another pilot flies the scripted pilot's flight cases: drives have no pilot, case
        # E its own
        if args.pilot and (case.manoeuvres or case.pilot != "scripted"):
            continue
        seeds = list(case.seeds[: args.flights])
        results = run_case(case, seeds, args.duration, runs_dir, robot, args.pilot, mcas)
        if args.pilot:
            nmpc = results.pop("nmpc-rti")
            compared = {
                "mcas": {"nmpc-rti": {"seeds": seeds, "pi": [nmpc[s]["pi"] for s in seeds]}}
            }
        else:
            compared = suite["cases"].get(case.name)
        figures[case.name] = {
            "vehicle": case.label(),
            "seeds": seeds,
            "dpcs": case_figures(results, compared, seeds),
        }
        print_case(case.name, figures[case.name]["dpcs"], len(seeds))
    header = result_header(calibration)
    if args.pilot:
        header["pilot"] = args.pilot
    else:
        suite_file = Path(args.suite).resolve()
        root = Path(__file__).resolve().parent.parent
        named = suite_file.relative_to(root) if suite_file.is_relative_to(root) else suite_file
        header["suite"] = {"file": str(named), "date": suite["provenance"]["date"]}
    name = f"unnamed_{args.pilot}.json" if args.pilot else "unnamed.json"
    out = args.json or default_result_path(name)
    record = {"provenance": header, "duration_s": args.duration, "cases": figures}
    atomic_write_json(out, record | {"out_of_range_notice": OUT_OF_RANGE_NOTICE})


if __name__ == "__main__":
    main()
