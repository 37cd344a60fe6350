"""`mca-drake live`: cue a running simulator's UDP telemetry in real time."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
from pathlib import Path

from mca_drake.app.cli.closed_loop_flags import add_mca_flags
from mca_drake.app.cli.flags import (
    add_comfort_flag,
    add_config_flags,
    add_scaling_flags,
    add_trajectory_flag,
    apply_scaling_flags,
    given_fields,
)
from mca_drake.app.cli.report import format_pi, hold_meshcat, policy_lines
from mca_drake.app.jobs import run_live_scenario, start_meshcat
from mca_drake.app.scenarios import LiveScenario
from mca_drake.cueing import mca_config_from_name

# LiveScenario fields with a flag of the same name.
LIVE_FLAGS = ("host", "port", "allowed_senders", "rsi_cycle_ms", "realtime_rate", "platform")


def add_parser(commands) -> None:
    """Adds `live` to the sub-command parsers `commands`."""
    defaults = LiveScenario()
    parser = commands.add_parser(
        "live", help="cue a running flight or racing simulator's UDP telemetry in real time"
    )
    parser.add_argument(
        "--protocol",
        help="fgnetfdm, xplane, csv, beamng (BeamNG.drive MotionSim), outsim (Live for Speed) "
        "or f1 (F1 23/24)",
    )
    parser.add_argument("--xplane-version", type=int, help="11 or 12 (protocol xplane)")
    parser.add_argument(
        "--outsim-opts",
        type=_hexadecimal,
        help="LFS cfg.txt OutSim Opts, hexadecimal as there (protocol outsim; default 0: the "
        "classic OutSimPack)",
    )
    parser.add_argument(
        "--f1-format",
        type=int,
        help="the game's UDP Format, 2023 or 2024 (protocol f1; default 2024)",
    )
    add_config_flags(parser, defaults, LIVE_FLAGS)
    parser.add_argument("--duration", type=float, help="s of live cueing (demo: 60)")
    add_mca_flags(parser, defaults.mca, policy=False)
    parser.add_argument(
        "--plant", help="analytical (default) or multibody (the KR500 station; demo default)"
    )
    parser.add_argument(
        "--meshcat",
        action="store_true",
        help="the operator page in Meshcat: controls and traces of the reference and the cue, "
        "with the station drawn on --plant multibody",
    )
    parser.add_argument("--json", help="result summary with its live block")
    add_trajectory_flag(parser)
    add_comfort_flag(parser)
    add_scaling_flags(parser)
    parser.add_argument(
        "--control-port",
        help="HOST:PORT: a UDP port for the operator's commands while the run goes on "
        "(intensity V, gain CH V, pause, resume, washout, estop, status; from loopback "
        "unless the scenario allows others)",
    )
    parser.add_argument(
        "--intensity", type=float, help="the master intensity the run starts with, in [0, 1]"
    )
    parser.add_argument(
        "--rig",
        help="send the actuator positions every control period to udp://HOST:PORT or "
        "serial://PATH?baud=N (one ASCII line, SI units, comma-separated; the scenario's rig "
        "field sets a template or a binary layout)",
    )
    parser.add_argument(
        "--pose-stream",
        help="udp://HOST:PORT: the head's pose relative to home every control period, one "
        "line t,x,y,z,qw,qx,qy,qz (s, m, unit quaternion), for VR motion compensation",
    )
    parser.add_argument(
        "--no-keyboard",
        action="store_true",
        help="ignore the terminal's keys (by default + and - intensity, space pause/resume, "
        "h wash out, x or Esc emergency stop)",
    )
    parser.add_argument(
        "--robot",
        help="rsi://HOST:PORT: drive a KUKA robot over RSI (the driver listens there for the "
        "controller's state packets; analytical plant)",
    )
    parser.add_argument(
        "--demo",
        action="store_true",
        help="JSBSim flies the light aircraft and streams FlightGear packets to this loop, "
        "cued on the KR500 station in Meshcat; with --protocol beamng a car drives a training "
        "drive and streams BeamNG MotionSim packets instead",
    )
    parser.set_defaults(func=run)


def _hexadecimal(text: str) -> int:
    """An OutSim Opts value as LFS's cfg.txt writes it: hexadecimal, `1ff` or `0x1ff`."""
    try:
        return int(text, 16)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a hexadecimal number: {text!r}") from None


def _scenario_from_flags(args: argparse.Namespace) -> LiveScenario:
    """The LiveScenario of the flags; with --demo, the demo's protocol and defaults."""
    scenario = LiveScenario(
        **({"mca": mca_config_from_name(args.mca)} if args.mca is not None else {}),
        robot=args.robot or "",
        output_json=args.json or "",
        trajectory=args.trajectory or "",
        **given_fields(args, LIVE_FLAGS),
    )
    if args.demo:
        if args.protocol not in (None, "fgnetfdm", "beamng"):
            raise ValueError("--demo streams fgnetfdm (a flight) or beamng (a drive)")
        if args.protocol == "beamng":
            # the driving demo: a car's training drive as BeamNG MotionSim packets
            scenario.protocol, scenario.port = "beamng", 0
        else:
            # the flight demo: JSBSim streaming FGNetFDM at its own time resolution
            from mca_drake.live.demo import DEMO_TIME_RESOLUTION_S

            scenario.protocol, scenario.port = "fgnetfdm", 0
            scenario.fgnetfdm_time_resolution_s = DEMO_TIME_RESOLUTION_S
        args.plant = args.plant or ("analytical" if args.robot else "multibody")
        args.meshcat = args.meshcat or args.plant == "multibody"
        args.duration = args.duration or 60.0
    elif args.protocol is None or args.duration is None:
        raise ValueError("live needs --protocol and --duration (or --demo)")
    else:
        scenario.protocol, scenario.xplane_version = args.protocol, args.xplane_version or 0
        if args.outsim_opts is not None:
            scenario.outsim.opts = args.outsim_opts
        if args.f1_format is not None:
            scenario.f1.packet_format = args.f1_format
    scenario.plant = args.plant or "analytical"
    scenario.duration_s = args.duration
    if args.control_port:
        scenario.controls.udp = args.control_port
    if args.intensity is not None:
        scenario.controls.intensity = args.intensity
    if args.no_keyboard:
        scenario.controls.keyboard = False
    if args.max_force_change is not None:
        scenario.comfort.max_force_change = args.max_force_change
    apply_scaling_flags(args, scenario.scaling)
    if args.rig:
        scenario.rig.url = args.rig
    if args.pose_stream:
        scenario.pose_stream = args.pose_stream
    scenario.validate()
    return scenario


def _ms(figures: dict) -> dict:
    return {k: f"{v * 1e3:.3f} ms" for k, v in figures.items()}


def format_live_report(summary: dict) -> str:
    """The live block of a summary (and its robot's, when there is one) as text."""
    live = summary["live"]
    lines = [
        f"telemetry from {live['sender']}: {live['packets']} packets ({live['bad']} bad, "
        f"{live['foreign']} from other senders, {live['dropped']} missing from the sequence, "
        f"{live['kernel_dropped']} dropped by the kernel, {live['out_of_order']} out of "
        f"order, {live['time_jumps']} ahead of the clock, {live['restarts']} clock restarts), "
        f"{live['stale_events']} stale events; "
        f"latency {_ms(live['latency_s'])} (of which waiting for the poll "
        f"{_ms(live['wait_s'])}); health {live['health']}; {format_pi(summary)}; "
        f"violations {summary['violations']}"
    ]
    lines += policy_lines(summary)
    lines += controls_lines(summary.get("controls"))
    if "rsi" in summary:
        r = summary["rsi"]
        lines.append(
            f"robot {r['address']}: {r.get('cycles', 0)} cycles, {r.get('late_replies', 0)} "
            f"late, {r.get('missed_cycles', 0)} missed, {r.get('bad_state', 0)} bad state "
            f"packets; reply latency {_ms(r.get('reply_latency_s', {}))}; ended "
            f"{r.get('mode')} ({r.get('reason')})"
        )
    return "\n".join(lines)


def controls_lines(controls: dict | None) -> list[str]:
    """The operator's part of a live report: the commands taken and the emergency stop."""
    if not controls or not (controls["commands"] or controls["estop"]):
        return []
    final = controls["final"]
    lines = [
        f"operator: {controls['commands']} commands ({controls['refused']} refused) from "
        f"{', '.join(controls['sources'])}; at the end {final['mode']}, intensity "
        f"{final['intensity']:.2f}"
    ]
    estop = controls["estop"]
    if estop:
        rest = estop["time_to_rest_s"]
        rest_text = "not at rest by the end" if rest is None else f"at rest after {rest:.3f} s"
        lines.append(f"emergency stop at {estop['t_s']:.2f} s from {estop['source']}: {rest_text}")
    return lines


def controls_hint(scenario: LiveScenario, keyboard: bool, meshcat: bool) -> str:
    """Where the operator's commands are read, for the terminal ("" when nowhere)."""
    places = []
    if scenario.controls.udp:
        places.append(f"udp://{scenario.controls.udp} (intensity V, gain CH V, pause, ...)")
    if keyboard and scenario.controls.keyboard:
        places.append("keys: + - intensity, space pause/resume, h wash out, x or Esc STOP")
    if meshcat and scenario.controls.meshcat:
        places.append("the Meshcat page's sliders and buttons")
    return "operator controls: " + "; ".join(places) if places else ""


def _demo_sender(protocol: str, duration_s: float, tmp: Path):
    """The demo's sender as port -> process: JSBSim flying (fgnetfdm), or the car's drive,
    driven now, before the loop listens, into `tmp` (beamng). The senders' models load only
    for the demo."""
    if protocol == "beamng":
        from mca_drake.live.drive_demo import demo_drive, start_drive_sender  # demo only
        from mca_drake.references.recording import save_recording  # demo only

        print("driving the demo's drive ...", flush=True)
        recording = tmp / "drive.csv"
        save_recording(recording, demo_drive(duration_s))
        return lambda port: start_drive_sender(port, duration_s, recording=recording)
    from mca_drake.live.demo import start_demo_sender  # JSBSim: demo only

    return lambda port: start_demo_sender(port, duration_s)


def _terminal() -> int | None:
    """The file descriptor of stdin when it is a terminal (its keys control the run)."""
    try:
        fd = sys.stdin.fileno()
    except (AttributeError, OSError, ValueError):
        return None
    return fd if os.isatty(fd) else None


def _stop_on_sigterm(*_) -> None:
    # SIGTERM ends the run as Ctrl-C does: through the loop's clean-up, which brakes a
    # driven robot to rest and stops its driver, instead of killing the process outright
    raise KeyboardInterrupt


def run(args: argparse.Namespace) -> int:
    """Runs the live loop (and, with --demo, its JSBSim sender); prints the live figures."""
    signal.signal(signal.SIGTERM, _stop_on_sigterm)
    scenario = _scenario_from_flags(args)
    meshcat = start_meshcat() if args.meshcat else None
    sender = []
    # the stream runs a little longer than the loop, so that it does not stop before it
    stream_s = (args.duration or 0.0) + 2.0
    with tempfile.TemporaryDirectory() as tmp:
        start_sender = _demo_sender(scenario.protocol, stream_s, Path(tmp)) if args.demo else None

        keyboard = _terminal()
        hint = controls_hint(scenario, keyboard is not None, meshcat is not None)

        def listening(address):
            print(f"listening on udp://{address[0]}:{address[1]}", flush=True)
            if hint:
                print(hint, flush=True)
            if start_sender is not None:
                sender.append(start_sender(address[1]))

        try:
            summary = run_live_scenario(
                scenario, on_listening=listening, meshcat=meshcat, keyboard_fd=keyboard
            )
        finally:
            for process in sender:
                process.terminate()
                process.wait(timeout=10)
    print(format_live_report(summary))
    hold_meshcat(meshcat)
    return 0
