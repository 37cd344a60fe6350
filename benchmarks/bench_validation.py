"""DPC policies and MCAs on the validation flights: aircraft no training saw, kept apart from
evaluation case C so that choosing between training recipes does not choose on it.

    python benchmarks/bench_validation.py --mca dpc=mca_drake/data/default_policy.npz \
        --mca candidate=results/policy/policy.npz --mca nmpc-rti [--out-dir results/validation]
        [--json results/validation.json]

Flies `VALIDATION_VEHICLES` (A4, F4N) over seeds 700 on (below the evaluation seeds, never
training seeds), 300 s each on the analytical plant, every MCA on every flight. `--vehicles
light,jet` flies development flights of the training aircraft of cases A and B at the same
seeds (the evaluation's are 1000 on), so that a recipe's cost there is seen before the
suite; `--vehicles bmw-320i,ford-escort,vw-vanagon` drives validation drives of the cars
(a lap on even seeds, the proving ground on odd ones; case D's are 4000 on);
`--first-seed 600 --seeds 14 --vehicles light` is the light aircraft's trap check
(fourteen more flights, where a policy that rides the joint limits shows) and `--first-seed
600 --seeds 14 --vehicles T37` the aerobatic one (the training set's jet trainer, whose
sustained pulls trap a policy at the limits as case C's aerobatic types may); `--pilot
random-style` flies the same aircraft and seeds with a pilot whose style is drawn from the
seed (a check against pilots other than the scripted one). One JSON per run
under out-dir/runs (atomic; a finished run is not flown again, so a killed study resumes).
A DPC run records its policy file's SHA-256: a label whose file has changed is flown again.
Prints per MCA the median PI per vehicle and over all flights, clamp interventions, and for
each MCA after the first the paired difference to the first (median, better on how many
flights, signed-rank p), the flight where it does worst against the first and, per channel,
the median of its RMSE - CC less the first's (where a gap comes from). An MCA is
`label=policy.npz` (DPC) or an MCA name. On the validation aircraft the figures go with
their provenance (date, command, calibration, machine) to `--json`, by default
`benchmarks/results/validation.json` (from seed 700); other flights are written only where
`--json` names a file.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
from common import default_result_path, parse_mca, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.conventions import CHANNELS, FIRST_EVALUATION_SEED
from mca_drake.cueing.configs import mca_config_from_name
from mca_drake.cueing.dpc import for_vehicle
from mca_drake.metrics import wilcoxon_signed_rank
from mca_drake.platforms.files import load_platform
from mca_drake.references.drives import is_car, motion_reference, training_spec
from mca_drake.references.flights import FlightSpec
from mca_drake.references.jsbsim import UNSEEN_VEHICLES, VALIDATION_VEHICLES, check_vehicle
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.studies.evaluation import policy_fingerprint

KR500 = load_platform("kr500")

FIRST_VALIDATION_SEED = 700


def run_flights(
    mcas,
    flights,
    out_dir: Path,
    duration_s: float,
    cache_dir: Path,
    pilot: str = "scripted",
    unnamed: bool = False,
) -> dict:
    """{label: {(vehicle, seed): summary}}, flying what is not in out_dir/runs yet (a DPC
    run whose policy file has changed since is flown again). `unnamed`: each reference is
    cued without its vehicle's name, as a recording that names none."""
    results: dict[str, dict] = {label: {} for label, _ in mcas}
    # A pilot other than the scripted one gets its own run names: its flights differ; so
    # do unnamed references (the DPC's policy is chosen otherwise).
    tag = ("" if pilot == "scripted" else f"_{pilot}") + ("_unnamed" if unnamed else "")
    configs = {
        label: mca_config_from_name(config) if isinstance(config, str) else config
        for label, config in mcas
    }
    for vehicle, seed in flights:
        reference = None
        for label, config in mcas:
            path = out_dir / "runs" / f"{label}_{vehicle}_{seed}{tag}.json"
            # the DPC's policy is the vehicle's where its config names none
            named = configs[label] if unnamed else for_vehicle(configs[label], vehicle)
            fingerprint = policy_fingerprint(named, KR500.name)
            if not finished_run(path, fingerprint):
                if reference is None:
                    spec = (
                        training_spec(vehicle, seed)
                        if is_car(vehicle)
                        else FlightSpec(vehicle=vehicle, seed=seed, pilot=pilot)
                    )
                    reference = motion_reference(spec, duration_s, cache_dir=cache_dir)
                    if unnamed:
                        reference = dataclasses.replace(reference, vehicle="")
                result = run_closed_loop(
                    mca=config, reference=reference, progress=False, robot=KR500
                )
                keep = ("pi", "pi_zero_motion", "rmse", "cc", "safety_interventions")
                keep += ("violations", "step_time_s", "policy_file", "policy_changes")
                summary = {k: result.summary[k] for k in keep if k in result.summary}
                atomic_write_json(path, {**summary, "policy_sha256": fingerprint})
                print(f"{label} {vehicle} {seed}: PI {result.summary['pi']:.3f}", flush=True)
            results[label][vehicle, seed] = json.loads(path.read_text())
    return results


def finished_run(path: Path, fingerprint: str) -> bool:
    """Whether `path` holds a run of the same policy file (by SHA-256; "" for an MCA that is
    not a DPC): a label that now names another policy is flown again, not reused."""
    if not path.is_file():
        return False
    try:
        run = json.loads(path.read_text())
    except (OSError, ValueError):
        return False  # unreadable: fly it again
    return isinstance(run, dict) and run.get("policy_sha256", "") == fingerprint


def report(results: dict, flights) -> dict:
    """Prints and returns the medians and the paired differences to the first MCA."""
    labels = list(results)
    figures = {}
    for label in labels:
        pis = {key: results[label][key]["pi"] for key in flights}
        row = {
            vehicle: float(np.median([pi for (v, _), pi in pis.items() if v == vehicle]))
            for vehicle in dict.fromkeys(v for v, _ in flights)
        }
        row["all"] = float(np.median(list(pis.values())))
        row["interventions"] = int(
            sum(results[label][key]["safety_interventions"] for key in flights)
        )
        figures[label] = row
        medians = "  ".join(f"{k} {v:.3f}" for k, v in row.items() if k != "interventions")
        print(f"{label:12s} {medians}  interventions {row['interventions']}")
    first = labels[0]
    for label in labels[1:]:
        a = np.array([results[label][key]["pi"] for key in flights])
        b = np.array([results[first][key]["pi"] for key in flights])
        test = wilcoxon_signed_rank(a, b)
        worst = int(np.argmax(a - b))
        split = channel_differences(
            [results[label][key] for key in flights], [results[first][key] for key in flights]
        )
        figures[label]["paired_vs_" + first] = {
            "median_difference": float(test.median_difference),
            "better_on": int(test.a_better),
            "flights": int(test.n),
            "signed_rank_p": float(test.p),
            "worst_flight": " ".join(map(str, flights[worst])),
            "worst_difference": float(a[worst] - b[worst]),
            "channel_differences": split,
        }
        print(
            f"{label} - {first}: median {test.median_difference:+.3f}, better on "
            f"{test.a_better} of {test.n}, signed-rank p {test.p:.3f}; worst flight "
            f"{' '.join(map(str, flights[worst]))} {a[worst] - b[worst]:+.3f}"
        )
        print("  by channel: " + "  ".join(f"{k} {v:+.3f}" for k, v in split.items()))
    return figures


def channel_differences(runs: list[dict], others: list[dict]) -> dict[str, float]:
    """Where a PI difference comes from: per channel of `CHANNELS`, the median over the
    flights of that channel's RMSE - CC in `runs` less the same in `others` (runs of two
    MCAs on the same flights, in the same order, as run summaries with "rmse" and "cc").
    Positive where the first MCA does worse; the medians need not add up to the median
    PI difference."""
    terms = [
        np.subtract(run["rmse"], run["cc"]) - np.subtract(other["rmse"], other["cc"])
        for run, other in zip(runs, others, strict=True)
    ]
    medians = np.median(terms, axis=0)
    return {channel: float(v) for channel, v in zip(CHANNELS, medians, strict=True)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mca", action="append", required=True, help="label=policy.npz or name")
    parser.add_argument(
        "--vehicles",
        default=",".join(VALIDATION_VEHICLES),
        help="comma-separated (default the validation aircraft; training aircraft give "
        "development flights of their own vehicle, e.g. light,jet for cases A and B; never "
        "case C's)",
    )
    parser.add_argument("--seeds", type=int, default=4, help="flights per vehicle (default 4)")
    parser.add_argument(
        "--first-seed",
        type=int,
        default=FIRST_VALIDATION_SEED,
        help=f"the first flight's seed (default {FIRST_VALIDATION_SEED}; below "
        f"{FIRST_EVALUATION_SEED}, where the evaluation's seeds begin)",
    )
    parser.add_argument(
        "--pilot",
        default="scripted",
        choices=("scripted", "random-style", "human"),
        help="who flies the aircraft (default scripted; random-style: a style drawn from each "
        "seed, a check against pilots other than the scripted one; human: the human-operator "
        "pilot no training flies; the route pilot flies evaluation flights only)",
    )
    parser.add_argument(
        "--unnamed",
        action="store_true",
        help="cue each flight without its vehicle's name, as a recording that names none (a "
        "DPC that names no policy recognizes the vehicle: DpcConfig.unnamed)",
    )
    parser.add_argument("--duration", type=float, default=300.0, help="s per flight")
    parser.add_argument("--out-dir", default="results/validation")
    parser.add_argument(
        "--json",
        help="write the figures here (default on the validation aircraft: "
        "benchmarks/results/validation.json)",
    )
    args = parser.parse_args()
    mcas = [parse_mca(text) for text in args.mca]
    if len({label for label, _ in mcas}) != len(mcas):
        raise SystemExit("two --mca share a label")
    out_dir = Path(args.out_dir)
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    if seeds.start < 0 or seeds.stop > FIRST_EVALUATION_SEED:
        raise SystemExit(
            f"--first-seed/--seeds: seeds {seeds.start}-{seeds.stop - 1} leave [0, "
            f"{FIRST_EVALUATION_SEED}): the evaluation's flights are never flown for choosing"
        )
    try:
        vehicles = [v if is_car(v) else check_vehicle(v) for v in args.vehicles.split(",")]
    except ValueError as error:  # unknown or reserved: a message, not a traceback
        raise SystemExit(f"--vehicles: {error}") from None
    if set(vehicles) & set(UNSEEN_VEHICLES):
        raise SystemExit(f"{', '.join(UNSEEN_VEHICLES)} are kept for evaluation case C")
    flights = [(vehicle, seed) for vehicle in vehicles for seed in seeds]
    calibration = print_calibration()
    results = run_flights(
        mcas,
        flights,
        out_dir,
        args.duration,
        out_dir / "flights",
        pilot=args.pilot,
        unnamed=args.unnamed,
    )
    figures = report(results, flights)
    json_path = args.json
    validation = (
        vehicles == list(VALIDATION_VEHICLES)
        and seeds.start == FIRST_VALIDATION_SEED
        and args.pilot == "scripted"
        and not args.unnamed
    )
    if json_path is None and validation:
        json_path = default_result_path("validation.json")
    if json_path:
        atomic_write_json(json_path, {"provenance": result_header(calibration), "mcas": figures})


if __name__ == "__main__":
    main()
