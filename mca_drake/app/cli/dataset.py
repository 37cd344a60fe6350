"""`mca-drake dataset open-loop | closed-loop | join | bound`: training and test datasets."""

from __future__ import annotations

import argparse

from mca_drake.app.cli.flags import (
    ADDRESS_HELP,
    add_config_flags,
    add_quiet,
    check_outputs,
    given_fields,
)
from mca_drake.app.jobs import run_scenario
from mca_drake.app.scenarios import DatasetScenario
from mca_drake.cueing import mca_config_from_name, mca_name
from mca_drake.cueing.optimal import OptimalConfig
from mca_drake.platforms.excitation import ExcitationConfig, generate_excitation_dataset
from mca_drake.references.driving import CARS
from mca_drake.references.jsbsim import TRAINING_VEHICLES
from mca_drake.studies.bound_dataset import generate_bound_dataset
from mca_drake.studies.closed_loop_dataset import join_datasets

# ExcitationConfig fields with a flag, and the flag's name where it is not the field's.
OPEN_LOOP_FLAGS = {
    "repetitions": "",
    "duration_s": "--duration",
    "horizon": "",
    "seed": "",
    "initial_state_fraction": "",
    "platform": "",
}
CLOSED_LOOP_FLAGS = {
    "vehicle": "",
    "random_style_share": "",
    "synthetic_share": "",
    "horizon": "",
    "workers": "",
    "output_dir": "--out-dir",
    "platform": "",
}


def add_parser(commands) -> None:
    """Adds `dataset` and its three kinds to the sub-command parsers `commands`."""
    dataset = commands.add_parser("dataset", help="generate training and test datasets")
    kinds = dataset.add_subparsers(dest="dataset_kind", required=True)

    open_loop = kinds.add_parser(
        "open-loop", help="open-loop excitation dataset (Algorithm 1; defaults: paper size)"
    )
    add_config_flags(open_loop, ExcitationConfig(), OPEN_LOOP_FLAGS)
    open_loop.add_argument("--out", default="open_loop.npz", help="the dataset file (.npz)")
    add_quiet(open_loop)
    open_loop.set_defaults(func=run_open_loop)

    defaults = DatasetScenario()
    closed = kinds.add_parser(
        "closed-loop",
        help="MCA closed loops over JSBSim flights or drives (defaults: paper size)",
    )
    add_config_flags(closed, defaults, CLOSED_LOOP_FLAGS)
    closed.add_argument(
        "--vehicles",
        help="a mixed set: comma-separated vehicles, dealt to the seeds in turn (seed i flies "
        f"vehicle i mod n); training aircraft: {', '.join(TRAINING_VEHICLES)}; a car "
        f"({', '.join(CARS)}) drives a lap (even seeds) or the proving ground (odd seeds)",
    )
    closed.add_argument(
        "--flights", type=int, help=f"flights (default {len(defaults.flight_seeds)})"
    )
    closed.add_argument(
        "--first-seed",
        type=int,
        help=f"seed of the first flight (default {defaults.flight_seeds[0]})",
    )
    closed.add_argument(
        "--minutes", type=float, help=f"per flight (default {defaults.flight_duration_s / 60:g})"
    )
    closed.add_argument(
        "--mca", help=f"MCA that generates the data (default {mca_name(defaults.mca)})"
    )
    closed.add_argument("--address", help=ADDRESS_HELP)
    add_quiet(closed)
    closed.set_defaults(func=run_closed_loop)

    join = kinds.add_parser(
        "join", help="join closed-loop datasets of different flights into one file"
    )
    join.add_argument("datasets", nargs="+", help="dataset.npz files (two or more)")
    join.add_argument("--out", required=True, help="the joined file (.npz)")
    join.set_defaults(func=run_join)

    bound = kinds.add_parser(
        "bound",
        help="a closed-loop dataset re-cued by each flight's offline-optimal bound (training "
        "targets: train-policy --targets achieved)",
    )
    bound.add_argument("dataset", help="a closed-loop dataset.npz (with references R)")
    bound.add_argument(
        "--out-dir", required=True, help="where the flights' bounds and dataset.npz go"
    )
    bound.add_argument(
        "--max-iterations",
        type=int,
        default=OptimalConfig.max_iterations,
        help="Gauss-Newton iterations per flight at most (default %(default)s)",
    )
    bound.add_argument("--workers", type=int, default=1, help="CPUs of a local Ray (default 1)")
    bound.add_argument("--address", help=ADDRESS_HELP)
    add_quiet(bound)
    bound.set_defaults(func=run_bound)


def run_open_loop(args: argparse.Namespace) -> int:
    """Generates the excitation dataset and writes it."""
    config = ExcitationConfig(**given_fields(args, OPEN_LOOP_FLAGS))
    config.validate()
    check_outputs(args.out)
    dataset = generate_excitation_dataset(config, progress=not args.quiet)
    dataset.save(args.out)
    print(
        f"{len(dataset)} segments of {config.horizon} steps "
        f"({dataset.metadata['kept_steps']} of {dataset.metadata['simulated_steps']} simulated "
        f"steps kept) in {dataset.metadata['generation_wall_s']:.1f} s, written to {args.out}"
    )
    return 0


def run_closed_loop(args: argparse.Namespace) -> int:
    """Flies the MCA over the flights and writes the dataset."""
    scenario = DatasetScenario(**given_fields(args, [*CLOSED_LOOP_FLAGS, "address"]))
    if args.vehicles is not None:
        scenario.vehicles = [v.strip() for v in args.vehicles.split(",") if v.strip()]
    if args.mca is not None:
        scenario.mca = mca_config_from_name(args.mca)
    if args.minutes is not None:
        scenario.flight_duration_s = args.minutes * 60.0
    if args.flights is not None or args.first_seed is not None:
        first = args.first_seed if args.first_seed is not None else scenario.flight_seeds[0]
        count = args.flights if args.flights is not None else len(scenario.flight_seeds)
        scenario.flight_seeds = list(range(first, first + count))
    summary = run_scenario(scenario, progress=not args.quiet)
    print(f"closed-loop dataset written to {summary['dataset']}")
    return 0


def run_join(args: argparse.Namespace) -> int:
    """Joins datasets into one file."""
    path = join_datasets(args.datasets, args.out)
    print(f"joined dataset written to {path}")
    return 0


def run_bound(args: argparse.Namespace) -> int:
    """Solves each flight's bound and writes the bound dataset."""
    config = OptimalConfig(max_iterations=args.max_iterations)
    config.validate()
    path = generate_bound_dataset(
        args.dataset,
        args.out_dir,
        config,
        workers=args.workers,
        address=args.address,
        progress=not args.quiet,
    )
    print(f"bound dataset written to {path}")
    return 0
