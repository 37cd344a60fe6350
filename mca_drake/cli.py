"""The `mca-drake` command. Each subcommand parses arguments and calls one library function."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from mca_drake import __version__


def _print_outputs_table(result, every_s: float = 1.0) -> None:
    from mca_drake.metrics import CHANNELS

    step = max(round(every_s / (result.times[1] - result.times[0])), 1)
    print(f"{'t [s]':>7} " + " ".join(f"{c:>9}" for c in CHANNELS))
    for k in range(0, result.times.size, step):
        print(f"{result.times[k]:7.2f} " + " ".join(f"{v:9.4f}" for v in result.outputs[k]))


def _cmd_simulate(args: argparse.Namespace) -> int:
    from mca_drake.diagrams import PlantDemoScenario
    from mca_drake.jobs import run_plant_demo

    scenario = PlantDemoScenario(duration_s=args.duration)
    result = run_plant_demo(
        scenario=scenario, json_path=args.json, plot_path=args.plot, progress=not args.quiet
    )
    _print_outputs_table(result)
    print(json.dumps(result.summary, indent=2))
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from mca_drake.diagrams import load_scenario
    from mca_drake.jobs import run_plant_demo

    scenario = load_scenario(args.scenario, args.set)
    result = run_plant_demo(scenario=scenario, json_path=args.json, progress=not args.quiet)
    print(json.dumps(result.summary, indent=2))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mca-drake", description="Motion cueing for a KUKA KR500 motion simulator, on Drake."
    )
    parser.add_argument("--version", action="version", version=f"mca-drake {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    simulate = sub.add_parser(
        "simulate",
        help="simulate the analytical plant on the built-in demo motion and print its outputs",
    )
    simulate.add_argument("--duration", type=float, default=20.0, help="simulated seconds")
    simulate.add_argument("--json", help="write the result summary to this JSON file")
    simulate.add_argument("--plot", default="simulate_outputs.png", help="PNG of the outputs")
    simulate.add_argument("--quiet", action="store_true", help="no progress bar")
    simulate.set_defaults(func=_cmd_simulate)

    run = sub.add_parser("run", help="run a scenario file from diagrams/")
    run.add_argument("scenario", help="YAML scenario file, e.g. diagrams/plant_demo.yaml")
    run.add_argument("--set", help="YAML override, e.g. '{scenario: {duration_s: 5}}'")
    run.add_argument("--json", help="write the result summary to this JSON file")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `mca-drake` console script."""
    args = build_parser().parse_args(argv)
    np.set_printoptions(precision=4, suppress=True)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError) as err:
        print(f"mca-drake: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
