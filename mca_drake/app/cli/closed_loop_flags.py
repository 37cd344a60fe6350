"""The flags that choose an MCA, a platform and a reference (a recording or a built-in
flight), shared by `simulate`, `evaluate` and `optimal`."""

from __future__ import annotations

import argparse
import dataclasses

from mca_drake.app.cli.flags import add_config_flags, apply_scaling_flags, given_fields
from mca_drake.app.scenarios import ClosedLoopScenario
from mca_drake.cueing import MCA_NAMES, DpcConfig, mca_config_from_name, mca_name
from mca_drake.references.flights import FlightSpec
from mca_drake.references.jsbsim import VEHICLES
from mca_drake.references.recording import load_recording
from mca_drake.resources import PROFILES


def add_mca_flags(parser: argparse.ArgumentParser, default_mca, *, policy: bool = True) -> None:
    """--mca NAME (a default config) and, with `policy`, --policy FILE (that of --mca dpc)."""
    parser.add_argument(
        "--mca",
        help=f"{', '.join(MCA_NAMES)}, each at its default config, or with a profile's "
        f"settings ({', '.join(f'-{p}' for p in PROFILES)}: washout-ground) (default "
        f"{mca_name(default_mca)})",
    )
    if policy:
        parser.add_argument(
            "--policy",
            help="policy file for --mca dpc (default: the shipped one), or for --mca "
            "dpc-predictive a policy trained with a preview, which reads the forecast",
        )


# FlightSpec fields with a flag: the built-in flight a command cues. `--seed` is kept for the
# seed of what a command itself draws (`flight`'s pilot, `train-policy`'s batches).
FLIGHT_FLAGS = {"vehicle": "--vehicle", "seed": "--flight-seed", "pilot": "--pilot"}


def add_flight_flags(parser: argparse.ArgumentParser) -> None:
    """--vehicle, --flight-seed and --pilot: the built-in flight cued when no --reference
    recording is given (`references.flights.FlightSpec`)."""
    add_config_flags(
        parser,
        FlightSpec(),
        FLIGHT_FLAGS,
        help_suffix={"vehicle": f"one of {', '.join(VEHICLES)}"},
    )


def flight_from_flags(args: argparse.Namespace, flight: FlightSpec) -> FlightSpec:
    """`flight` with the flight flags that were given, or a recording's spec for
    --reference (which the flight flags cannot describe)."""
    chosen = given_fields(args, FLIGHT_FLAGS)
    if getattr(args, "reference", None):
        if chosen:
            flags = ", ".join(FLIGHT_FLAGS[f] for f in chosen)
            raise ValueError(f"{flags} choose a built-in flight: leave out --reference")
        return FlightSpec(recording=args.reference)
    return dataclasses.replace(flight, **chosen)


def mca_from_flags(args: argparse.Namespace, default):
    """The MCA config of --mca NAME and --policy FILE (a DPC policy), or `default`."""
    mca = mca_config_from_name(args.mca) if args.mca is not None else default
    if args.policy is not None:
        if not isinstance(mca, DpcConfig):
            raise ValueError("--policy is the policy file of --mca dpc")
        mca = DpcConfig(policy=args.policy, profile=mca.profile, predictor=mca.predictor)
    return mca


def closed_loop_scenario_from_flags(args: argparse.Namespace, **fixed) -> ClosedLoopScenario:
    """A ClosedLoopScenario: its defaults, overridden by the flags that were given. A
    recording (--reference) is cued whole unless --duration says otherwise."""
    scenario = ClosedLoopScenario(**fixed)
    if getattr(args, "platform", None) is not None:
        scenario.platform = args.platform
    scenario.mca = mca_from_flags(args, scenario.mca)
    if args.reference is not None:
        scenario.flight = flight_from_flags(args, scenario.flight)
        scenario.duration_s = load_recording(args.reference).duration_s
    elif isinstance(scenario.flight, FlightSpec):
        scenario.flight = flight_from_flags(args, scenario.flight)
    if args.duration_s is not None:
        scenario.duration_s = args.duration_s
    if getattr(args, "max_force_change", None) is not None:
        scenario.comfort.max_force_change = args.max_force_change
    apply_scaling_flags(args, scenario.scaling)
    return scenario
