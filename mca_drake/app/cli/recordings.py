"""`mca-drake flight`, `mca-drake drive` and `mca-drake plot-recording`: vehicle recordings."""

from __future__ import annotations

import argparse

from mca_drake.app.cli.flags import add_quiet, check_outputs
from mca_drake.plotting import plot_recording, save_figure
from mca_drake.references.driving import (
    CARS,
    DEFAULT_HEAD_OFFSET_M,
    MANOEUVRES,
    ROAD_CLASSES,
    drive,
)
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

    drive = commands.add_parser(
        "drive", help="drive a car through a manoeuvre and record the driver's head IMU"
    )
    drive.add_argument("--manoeuvre", default="double-lane-change", help=", ".join(MANOEUVRES))
    drive.add_argument(
        "--seed", type=int, default=0, help="seed of the manoeuvre's settings and the road"
    )
    drive.add_argument(
        "--seconds",
        type=float,
        help="drive length, s (default: the manoeuvre's course to its end; a lap: one lap)",
    )
    drive.add_argument("--car", default="bmw-320i", help=", ".join(CARS))
    drive.add_argument(
        "--road", default="B", help=f"ISO 8608 road class, {'-'.join(ROAD_CLASSES)}, or none"
    )
    drive.add_argument(
        "--head-offset",
        default=",".join(f"{v:g}" for v in DEFAULT_HEAD_OFFSET_M),
        help="the driver's head from the centre of gravity, m: x,y,z (forward, left, up)",
    )
    drive.add_argument("--out", default="drive.csv", help="recording CSV to write")
    drive.add_argument("--plot", help="also write a PNG of the six channels")
    add_quiet(drive)
    drive.set_defaults(func=run_drive)

    plot = commands.add_parser("plot-recording", help="plot a recording CSV (six channels, PNG)")
    plot.add_argument("recording", help="recording CSV (t, omega_x..z, f_x..z)")
    plot.add_argument("--out", help="PNG to write (default: next to the recording)")
    plot.set_defaults(func=run_plot_recording)


def run_flight(args: argparse.Namespace) -> int:
    """Flies the aircraft and writes its recording (and a plot)."""
    check_outputs(args.out, args.plot)
    recording = fly(args.vehicle, args.minutes * 60.0, args.seed, progress=not args.quiet)
    return _write(args, recording, f"{args.vehicle} flight, seed {args.seed}")


def _write(args: argparse.Namespace, recording, what: str) -> int:
    """Writes the recording to --out (and its plot to --plot) and says so."""
    save_recording(args.out, recording)
    print(
        f"{what}: {recording.duration_s:.0f} s at {recording.rate_hz:.0f} Hz written to {args.out}"
    )
    if args.plot:
        save_figure(plot_recording(recording), args.plot)
        print(f"plot written to {args.plot}")
    return 0


def run_drive(args: argparse.Namespace) -> int:
    """Drives the manoeuvre and writes its recording (and a plot)."""
    check_outputs(args.out, args.plot)
    try:
        offset = [float(v) for v in args.head_offset.split(",")]
    except ValueError:
        raise ValueError(
            f"--head-offset must be three numbers x,y,z; got {args.head_offset}"
        ) from None
    road = "" if args.road.lower() == "none" else args.road
    recording = drive(
        args.manoeuvre,
        args.seconds,
        args.seed,
        car=args.car,
        road_class=road,
        head_offset_m=offset,
        progress=not args.quiet,
    )
    meta = recording.metadata
    what = f"{meta['description']} ({args.car}, road {meta['road_class']}, seed {args.seed})"
    return _write(args, recording, what)


def run_plot_recording(args: argparse.Namespace) -> int:
    """Plots a recording's six channels."""
    out = args.out or str(args.recording).rsplit(".", 1)[0] + ".png"
    check_outputs(out)
    recording = load_recording(args.recording)
    save_figure(plot_recording(recording, title=str(args.recording)), out)
    print(f"plot written to {out}")
    return 0
