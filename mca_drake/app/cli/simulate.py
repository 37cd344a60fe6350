"""`mca-drake simulate`: the main job, closed-loop motion cueing with a readable result."""

from __future__ import annotations

import argparse

from mca_drake.app.cli.closed_loop_flags import (
    add_flight_flags,
    add_mca_flags,
    closed_loop_scenario_from_flags,
)
from mca_drake.app.cli.flags import (
    add_comfort_flag,
    add_config_flags,
    add_platform_flag,
    add_quiet,
    add_scaling_flags,
    add_trajectory_flag,
)
from mca_drake.app.cli.report import format_closed_loop_report, hold_meshcat
from mca_drake.app.jobs import closed_loop_outputs, run_closed_loop_scenario, start_meshcat
from mca_drake.app.scenarios import ClosedLoopScenario
from mca_drake.simulation.builders import default_visualization
from mca_drake.simulation.closed_loop import PLANTS


def add_parser(commands) -> None:
    """Adds `simulate` to the sub-command parsers `commands`."""
    defaults = ClosedLoopScenario()
    parser = commands.add_parser(
        "simulate",
        help="the main job: closed-loop motion cueing (default: the shipped DPC policy) on a "
        "built-in flight or a recording; prints a result table, writes the summary and plots",
    )
    add_config_flags(
        parser,
        defaults,
        {"duration_s": "--duration", "random_seed": "--noise-seed"},
        help_suffix={
            "duration_s": "a --reference recording: whole",
            "random_seed": "the default station has no noise",
        },
    )
    add_mca_flags(parser, defaults.mca)
    add_platform_flag(parser)
    parser.add_argument("--reference", help="recording CSV (default: the built-in flight)")
    add_flight_flags(parser)
    parser.add_argument(
        "--json",
        help=f"result summary JSON (default {defaults.output_dir}/summary.json; '' for none)",
    )
    parser.add_argument(
        "--plant",
        choices=PLANTS,
        help="multibody: the platform's MultibodyPlant with inverse-dynamics control and head "
        "IMU; "
        f"analytical: the ideal joint-space plant of the paper (default {defaults.plant})",
    )
    parser.add_argument("--meshcat", action="store_true", help="watch it in Meshcat")
    parser.add_argument("--realtime", action="store_true", help="run at real-time rate 1")
    parser.add_argument(
        "--plots",
        help="folder for tracking.png (Fig. 4), perceived.png and joint_usage.png (Fig. 5) "
        f"(default: the scenario's output_dir, {defaults.output_dir}); '' for none",
    )
    add_trajectory_flag(parser)
    add_comfort_flag(parser)
    add_scaling_flags(parser)
    add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Runs the closed loop the flags describe; prints its result table."""
    scenario = closed_loop_scenario_from_flags(args)
    if args.plant is not None:
        scenario.plant = args.plant
    if args.meshcat:
        scenario.visualization = default_visualization()
    if args.realtime:
        scenario.simulator_config.target_realtime_rate = 1.0
    if args.random_seed is not None:
        scenario.random_seed = args.random_seed
    if args.trajectory is not None:
        scenario.trajectory = args.trajectory
    scenario.validate()
    meshcat = start_meshcat() if scenario.visualization is not None else None
    result = run_closed_loop_scenario(
        scenario,
        progress=not args.quiet,
        meshcat=meshcat,
        json_path=args.json,
        plot_dir=args.plots,
    )
    print(format_closed_loop_report(result))
    summary, plots = closed_loop_outputs(scenario, args.json, args.plots)
    print()
    if summary:
        print(f"summary (the full MCA config, every figure): {summary}")
    if plots:
        print(f"plots: {plots}/tracking.png, {plots}/perceived.png, {plots}/joint_usage.png")
    if scenario.trajectory:
        print(f"time series: {scenario.trajectory}")
    hold_meshcat(meshcat)
    return 0
