"""`mca-drake flight` and `mca-drake plot-recording`: vehicle recordings."""

from __future__ import annotations

import argparse

from mca_drake.app.cli.flags import add_quiet, check_outputs
from mca_drake.plotting import plot_recording, save_figure
from mca_drake.references.jsbsim import VEHICLES, fly
from mca_drake.references.recording import load_recording, save_recording


def add_parsers(commands) -> None:
    """Adds `flight` and `plot-recording` to the sub-command parsers `commands`."""
    flight = commands.add_parser("flight", help="fly a JSBSim aircraft and record the pilot's IMU")
    flight.add_argument(
        "--vehicle",
        default="light",
        help=f"light (c172p), jet (global5000) or a JSBSim model: {', '.join(VEHICLES[2:])}",
    )
    flight.add_argument("--minutes", type=float, default=15.0, help="flight length, min")
    flight.add_argument("--seed", type=int, default=0, help="seed of the scripted pilot")
    flight.add_argument("--out", default="flight.csv", help="recording CSV to write")
    flight.add_argument("--plot", help="also write a PNG of the six channels")
    add_quiet(flight)
    flight.set_defaults(func=run_flight)

    plot = commands.add_parser("plot-recording", help="plot a recording CSV (six channels, PNG)")
    plot.add_argument("recording", help="recording CSV (t, omega_x..z, f_x..z)")
    plot.add_argument("--out", help="PNG to write (default: next to the recording)")
    plot.set_defaults(func=run_plot_recording)


def run_flight(args: argparse.Namespace) -> int:
    """Flies the aircraft and writes its recording (and a plot)."""
    check_outputs(args.out, args.plot)
    recording = fly(args.vehicle, args.minutes * 60.0, args.seed, progress=not args.quiet)
    save_recording(args.out, recording)
    print(
        f"{args.vehicle} flight, seed {args.seed}: {recording.duration_s:.0f} s at "
        f"{recording.rate_hz:.0f} Hz written to {args.out}"
    )
    if args.plot:
        save_figure(plot_recording(recording), args.plot)
        print(f"plot written to {args.plot}")
    return 0


def run_plot_recording(args: argparse.Namespace) -> int:
    """Plots a recording's six channels."""
    out = args.out or str(args.recording).rsplit(".", 1)[0] + ".png"
    check_outputs(out)
    recording = load_recording(args.recording)
    save_figure(plot_recording(recording, title=str(args.recording)), out)
    print(f"plot written to {out}")
    return 0
