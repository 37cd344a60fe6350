"""`mca-drake run`: any scenario, from a YAML file or by its packaged name."""

from __future__ import annotations

import argparse
import json

from mca_drake.app.cli.flags import add_quiet, add_trajectory_flag
from mca_drake.app.jobs import run_scenario
from mca_drake.app.scenarios import load_scenario
from mca_drake.resources import packaged_scenarios


def add_parser(commands) -> None:
    """Adds `run` to the sub-command parsers `commands`."""
    parser = commands.add_parser(
        "run", help="run a scenario: a YAML file or a packaged scenario's name"
    )
    parser.add_argument(
        "scenario",
        help="YAML scenario file (diagrams/plant_demo.yaml) or the name of one the package "
        f"carries: {', '.join(packaged_scenarios())}",
    )
    parser.add_argument(
        "--set",
        action="append",
        help="YAML override of the scenario (repeatable, applied in order), e.g. "
        "'{duration_s: 5, station: {torque_limits: true}}' or "
        "'{mca: !NmpcConfig {mode: rti, washout_weight: 0.3}}'",
    )
    parser.add_argument("--json", help="write the result summary to this JSON file")
    add_trajectory_flag(parser)
    add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Loads the scenario with its overrides, runs it and prints its summary."""
    scenario = load_scenario(args.scenario, args.set)
    if args.trajectory is not None:
        if not hasattr(scenario, "trajectory"):
            raise ValueError(
                f"--trajectory: a {type(scenario).__name__} has no single run's time series"
            )
        scenario.trajectory = args.trajectory
    summary = run_scenario(scenario, progress=not args.quiet, json_path=args.json)
    print(json.dumps(summary, indent=2, default=str))
    return 0
