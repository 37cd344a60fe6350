"""`mca-drake optimal`: the offline-optimal bound of a recording or a built-in flight."""

from __future__ import annotations

import argparse
import dataclasses

from mca_drake.app.cli.closed_loop_flags import add_flight_flags, flight_from_flags
from mca_drake.app.cli.flags import (
    add_config_flags,
    add_platform_flag,
    add_quiet,
    check_outputs,
    given_fields,
)
from mca_drake.app.cli.report import format_closed_loop_report
from mca_drake.cueing import as_mca_config, on_platform
from mca_drake.cueing.optimal import OptimalConfig
from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform, packaged_name
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.references.recording import load_recording
from mca_drake.simulation.optimal_bound import DEFAULT_STARTS, run_optimal_bound

# OptimalConfig fields with a flag.
OPTIMAL_FLAGS = {
    "objective": "",
    "perception_model": "",
    "max_iterations": "",
    "kkt_tolerance": "",
}


def add_parser(commands) -> None:
    """Adds `optimal` to the sub-command parsers `commands`."""
    parser = commands.add_parser(
        "optimal",
        help="the offline-optimal bound: the best cue the robot can give a whole recording "
        "with perfect preview, under every limit (analytical plant); prints a result table",
    )
    parser.add_argument("--reference", help="recording CSV (default: the built-in flight)")
    add_flight_flags(parser)
    parser.add_argument(
        "--duration",
        dest="duration_s",
        type=float,
        help="seconds to solve (default: the whole recording; a built-in flight: 300)",
    )
    parser.add_argument(
        "--starts",
        help="causal MCAs whose trajectories are candidate starts (default "
        f"{','.join(DEFAULT_STARTS)}; '' for none: start from no motion)",
    )
    add_config_flags(parser, OptimalConfig(), OPTIMAL_FLAGS)
    add_platform_flag(parser)
    parser.add_argument("--json", help="result summary JSON (default: none)")
    parser.add_argument("--plots", help="folder for tracking.png, perceived.png, joint_usage.png")
    add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Solves the bound the flags describe; prints its result table."""
    check_outputs(args.json)
    flight = flight_from_flags(args, FlightSpec())
    flight.validate()
    duration = args.duration_s
    if duration is None:
        duration = load_recording(flight.recording).duration_s if flight.recording else 300.0
    reference = flight_reference(flight, duration, progress=not args.quiet)
    config = dataclasses.replace(OptimalConfig(), **given_fields(args, OPTIMAL_FLAGS))
    starts = DEFAULT_STARTS if args.starts is None else [s for s in args.starts.split(",") if s]
    platform = args.platform or DEFAULT_PLATFORM
    result = run_optimal_bound(
        reference=reference,
        config=config,
        starts=[on_platform(as_mca_config(s), packaged_name(platform)) for s in starts],
        robot=load_platform(platform),
        duration_s=min(duration, reference.duration_s),
        progress=not args.quiet,
        json_path=args.json or None,
        plot_dir=args.plots or None,
    )
    print(format_closed_loop_report(result))
    if args.json:
        print(f"\nsummary: {args.json}")
    return 0
