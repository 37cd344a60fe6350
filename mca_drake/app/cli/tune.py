"""`mca-drake tune`: tune an MCA's config on training flights (Ray Tune, Optuna TPE)."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from mca_drake.app.cli.flags import ADDRESS_HELP, add_config_flags, add_quiet, given_fields
from mca_drake.references.driving import CARS
from mca_drake.studies.tuning import TUNABLE_MCAS, TuningConfig, run_tuning

# TuningConfig fields with a flag, by flag name where it differs from the field's.
TUNING_FLAGS = {
    "mca": "",
    "trials": "",
    "duration_s": "--duration",
    "max_false_rotation_deg_s": "--max-false-rotation",
    "score": "",
    "nmpc_objective": "",
    "seed": "",
    "platform": "",
}


def add_parser(commands) -> None:
    """Adds `tune` to the sub-command parsers `commands`."""
    defaults = TuningConfig()
    parser = commands.add_parser(
        "tune",
        help="tune an MCA's config (Ray Tune, Optuna TPE) on training flights; writes "
        "best.yaml, trials.csv and a report",
    )
    add_config_flags(parser, defaults, TUNING_FLAGS, help_suffix={"mca": ", ".join(TUNABLE_MCAS)})
    parser.add_argument(
        "--flights",
        help="vehicle:seed list, e.g. light:100,jet:101 (seeds below 1000); a car "
        f"({', '.join(CARS)}) drives a lap (even seeds) or the proving ground (odd seeds) "
        "instead",
    )
    parser.add_argument("--vehicles", help="with --seeds: every vehicle on every seed")
    parser.add_argument("--seeds", help="e.g. 100,101,102 (the training range: below 1000)")
    parser.add_argument(
        "--budget-ms",
        type=float,
        help="a trial whose 99th-percentile MCA step time exceeds this is infeasible, ms "
        f"(default {defaults.step_time_budget_s * 1e3:g}: none)",
    )
    parser.add_argument("--workers", type=int, help="trials at once, on a local Ray (default 1)")
    parser.add_argument("--address", help=ADDRESS_HELP)
    parser.add_argument("--out-dir", default="results/tune", help="the study's folder")
    parser.add_argument("--resume", action="store_true", help="continue the tune in --out-dir")
    add_quiet(parser)
    parser.set_defaults(func=run)


def flights_from_flags(args: argparse.Namespace, default: tuple) -> tuple[tuple[str, int], ...]:
    """--flights vehicle:seed,... or the product of --vehicles and --seeds (each defaulting
    to the vehicles and seeds of `default`)."""
    if args.flights is not None:
        flights = []
        for item in args.flights.split(","):
            vehicle, _, seed = item.partition(":")
            if not seed.strip().lstrip("-").isdigit():
                raise ValueError(f"--flights: '{item}' is not vehicle:seed (e.g. light:100)")
            flights.append((vehicle.strip(), int(seed)))
        return tuple(flights)
    vehicles = (
        args.vehicles.split(",") if args.vehicles else list(dict.fromkeys(v for v, _ in default))
    )
    try:
        seeds = [int(s) for s in args.seeds.split(",")] if args.seeds else None
    except ValueError:
        raise ValueError(
            f"--seeds: whole numbers separated by commas, not '{args.seeds}'"
        ) from None
    seeds = seeds or list(dict.fromkeys(s for _, s in default))
    return tuple((v, s) for v in vehicles for s in seeds)


def run(args: argparse.Namespace) -> int:
    """Runs (or resumes) the study; prints its report."""
    defaults = TuningConfig()
    tuning = dataclasses.replace(
        defaults,
        **given_fields(args, TUNING_FLAGS),
        flights=flights_from_flags(args, defaults.flights),
    )
    if args.budget_ms is not None:
        tuning.step_time_budget_s = args.budget_ms / 1e3
    command = "mca-drake " + " ".join(sys.argv[1:]) if sys.argv[0].endswith("mca-drake") else ""
    report = run_tuning(
        tuning,
        args.out_dir,
        workers=args.workers if args.workers is not None else 1,
        address=args.address,
        resume=args.resume,
        command=command,
        progress=not args.quiet,
    )
    out = Path(args.out_dir)
    print((out / "report.md").read_text())
    print(f"best config: {out / 'best.yaml'}; all trials: {out / 'trials.csv'}")
    return 0 if report else 1
