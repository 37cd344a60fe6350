"""`mca-drake evaluate`: one recording through an MCA, or the evaluation suite."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from mca_drake.app.cli.closed_loop_flags import (
    add_mca_flags,
    closed_loop_scenario_from_flags,
)
from mca_drake.app.cli.flags import (
    ADDRESS_HELP,
    SCALING_FLAGS,
    add_comfort_flag,
    add_config_flags,
    add_platform_flag,
    add_quiet,
    add_scaling_flags,
    add_trajectory_flag,
    check_outputs,
    given_fields,
)
from mca_drake.app.cli.report import format_pi
from mca_drake.app.jobs import run_closed_loop_scenario, run_scenario
from mca_drake.app.scenarios import ClosedLoopScenario, EvaluationScenario, SuiteCase
from mca_drake.cueing import DpcConfig, mca_config_from_name, mca_name
from mca_drake.cueing.optimal import OptimalConfig
from mca_drake.plotting import save_figure
from mca_drake.simulation.plots import tracking_figure
from mca_drake.studies.evaluation import (
    default_cases,
    load_report,
    run_evaluation,
    write_report,
)

# EvaluationScenario fields with a flag (the suite's), by flag name where it differs.
SUITE_FLAGS = {"workers": "", "output_dir": "--out-dir"}


def add_parser(commands) -> None:
    """Adds `evaluate` to the sub-command parsers `commands`."""
    suite = EvaluationScenario()
    parser = commands.add_parser(
        "evaluate",
        help="run one recording through an MCA on the analytical plant, or the suite",
    )
    add_mca_flags(parser, ClosedLoopScenario().mca)
    add_platform_flag(parser)
    parser.add_argument("--reference", help="recording CSV (one run)")
    parser.add_argument(
        "--suite",
        action="store_true",
        help="the scenario set: cases A-E (flights and drives), report, box plot",
    )
    parser.add_argument(
        "--cases",
        help=f"suite: cases to run (default {','.join(c.name for c in default_cases())})",
    )
    parser.add_argument(
        "--flights", type=int, help="suite: the first N flights of each case (default all)"
    )
    parser.add_argument(
        "--bound",
        action="store_true",
        help="suite: also each flight's offline-optimal bound and every MCA's share of the "
        "achievable improvement",
    )
    parser.add_argument(
        "--mcas",
        help=f"suite: MCAs to compare (default {','.join(mca_name(m) for m in suite.mcas)})",
    )
    add_config_flags(parser, suite, SUITE_FLAGS, help_suffix={"workers": "suite"})
    parser.add_argument("--address", help=ADDRESS_HELP)
    parser.add_argument(
        "--duration",
        dest="duration_s",
        type=float,
        help=f"simulated seconds (default: all; suite: {suite.duration_s:g})",
    )
    parser.add_argument(
        "--report-only",
        action="store_true",
        help="suite: run nothing; rewrite the report from the finished runs in --out-dir "
        "(a case's MCA without runs is left out)",
    )
    parser.add_argument(
        "--keep-report",
        action="store_true",
        help="suite: a case's NMPC or washout without runs in --out-dir keeps its entry from "
        "the evaluation.json there (same duration and config) and is not run, nor is a "
        "bound the report has: a new DPC policy is measured by running the DPCs alone",
    )
    parser.add_argument("--json", help="write the result summary here")
    parser.add_argument("--plot", help="PNG of target versus achieved outputs")
    add_trajectory_flag(parser)
    add_comfort_flag(parser)
    add_scaling_flags(parser)
    add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """One recording (--reference) or the suite (--suite)."""
    if args.suite:
        return run_suite(args)
    if args.report_only or args.keep_report:
        raise ValueError("--report-only and --keep-report are for the suite's report: add --suite")
    if not args.reference:
        raise ValueError("give --reference flight.csv (one recording) or --suite (scenario set)")
    scenario = closed_loop_scenario_from_flags(args, plant="analytical")
    if args.trajectory is not None:
        scenario.trajectory = args.trajectory
    check_outputs(args.plot)
    result = run_closed_loop_scenario(
        scenario, progress=not args.quiet, json_path=args.json or "", plot_dir=""
    )
    if args.plot:
        save_figure(tracking_figure(result), args.plot)
    print(json.dumps(result.summary, indent=2))
    print(format_pi(result.summary))
    return 0


def run_suite(args: argparse.Namespace) -> int:
    """The evaluation suite over the cases and MCAs the flags choose; prints its report."""
    if args.max_force_change is not None:
        raise ValueError("--max-force-change is for one run: the suite cues without the bound")
    scaled = [f"--{f.replace('_', '-')}" for f in given_fields(args, SCALING_FLAGS)]
    if scaled:
        raise ValueError(
            f"{', '.join(scaled)} is for one run: the suite cues at the default scaling, "
            "so that its figures compare with the published ones"
        )
    scenario = EvaluationScenario(
        **given_fields(args, [*SUITE_FLAGS, "duration_s", "address", "platform"])
    )
    if args.mcas is not None:
        scenario.mcas = [mca_config_from_name(n) for n in args.mcas.split(",")]
    if args.policy is not None:
        # the policy of the suite's default DPC; a profile's DPC keeps the profile's policy
        plain = [isinstance(m, DpcConfig) and not m.profile for m in scenario.mcas]
        if not any(plain):
            raise ValueError("--policy is the policy file of dpc, which --mcas leaves out")
        scenario.mcas = [
            DpcConfig(policy=args.policy) if is_plain else m
            for m, is_plain in zip(scenario.mcas, plain, strict=True)
        ]
    if args.bound:
        scenario.bound = OptimalConfig()
    if args.flights is not None and args.flights < 1:
        raise ValueError(f"--flights must be at least 1; got {args.flights}")
    cases = {c.name: c for c in default_cases()}  # A-C: flights, D: drives, E: route pilot
    wanted = args.cases.split(",") if args.cases is not None else list(cases)
    unknown = [c for c in wanted if c not in cases]
    if unknown:
        raise ValueError(f"--cases: unknown case {unknown}; valid: {', '.join(cases)}")
    scenario.cases = [
        SuiteCase.of(dataclasses.replace(cases[name], seeds=cases[name].seeds[: args.flights]))
        for name in cases
        if name in wanted
    ]
    out = Path(scenario.output_dir).resolve()
    previous = None
    if args.keep_report:
        # read before any run: a run rewrites the report from the runs on disk alone
        previous = load_report(out / "evaluation.json")
    scenario.validate()
    if args.report_only:
        write_report(scenario.to_config(), out, previous)
    elif previous is not None:
        run_evaluation(
            scenario.to_config(),
            out,
            workers=scenario.workers,
            address=scenario.address or None,
            progress=not args.quiet,
            previous=previous,
        )
    else:
        run_scenario(scenario, progress=not args.quiet)
    print((Path(scenario.output_dir) / "evaluation.md").read_text())
    return 0
