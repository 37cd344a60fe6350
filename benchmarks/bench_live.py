"""Live loop figures on JSBSim's own telemetry: latency, jitter and CPU load.

    python benchmarks/bench_live.py [--duration 600] [--mcas dpc,nmpc-rti]
        [--plant analytical] [--phase-lock on|off|both] [--guard on|off|both]
        [--controls on|off|both] [--protocol fgnetfdm|beamng] [--platform kr500]
        [--rig] [--json results/live.json]

For each MCA, `mca-drake live --demo`'s set-up without Meshcat: a JSBSim process flies the
light aircraft (a training seed) in real time and streams its FGNetFDM packets over
loopback at 100 Hz, or (`--protocol beamng`, written to live_driving.json by default) a
process streams a car's training drive as BeamNG MotionSim packets at 100 Hz
(`mca_drake.live.drive_demo`); the loop cues them at real-time rate 1 for `--duration` s, with the
phase lock (`mca_drake.live.phase_lock`) on, off or both one after the other, and the
input plausibility guard (`mca_drake.cueing.plausibility`) on, off or both, and the
operator's controls (`mca_drake.live.controls`: the console in the loop, polling a UDP
control port and the Meshcat page's sliders and buttons every period) on, off or both
(what they cost in latency, measured in the same run), on `--platform` (the KR500 by
default; written to live_<platform>.json by default for another), with `--rig` the rig's
own output (`mca_drake.live.rig_output`: the actuator positions, a hexapod's leg lengths,
one ASCII datagram per period to a loopback listener that drains them). Prints the
latency from a sample's arrival to the command computed from it (median, p99, max), the
part of it the sample waited in the socket for its poll, the
loop's jitter (|period - 10 ms| of its control instants on the wall clock), with `--rig`
the latency from a sample's arrival to the rig's datagram computed from it, the loop
process's CPU load and the sender's, and the stream's counters. The machine's calibration
first. Writes the figures with their provenance (date, command, calibration, machine) to
`--json`, by default `benchmarks/results/live.json` (`live_driving.json` for beamng).
"""

from __future__ import annotations

import argparse
import resource
import socket
import tempfile
import threading
from pathlib import Path

from common import default_result_path, in_ms, print_calibration, result_header
from pydrake.geometry import Meshcat, MeshcatParams

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing import mca_config_from_name
from mca_drake.cueing.plausibility import PlausibilityConfig
from mca_drake.live.controls import ControlsConfig
from mca_drake.live.demo import DEMO_TIME_RESOLUTION_S, start_demo_sender
from mca_drake.live.drive_demo import DEMO_CAR, demo_drive, start_drive_sender
from mca_drake.live.drive_demo import DEMO_SEED as DRIVE_SEED
from mca_drake.live.loop import make_decoder, run_live
from mca_drake.live.phase_lock import PhaseLockConfig
from mca_drake.live.receiver import ReceiverConfig
from mca_drake.live.rig_output import RigOutputConfig
from mca_drake.platforms.files import load_platform
from mca_drake.references.recording import save_recording


def children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def free_udp_port() -> int:
    """A UDP port free on loopback now (the control port's)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=600.0, help="s per MCA")
    parser.add_argument("--mcas", default="dpc,nmpc-rti")
    parser.add_argument("--plant", default="analytical")
    parser.add_argument("--phase-lock", choices=("on", "off", "both"), default="on")
    parser.add_argument("--guard", choices=("on", "off", "both"), default="on")
    parser.add_argument("--controls", choices=("on", "off", "both"), default="on")
    parser.add_argument("--protocol", choices=("fgnetfdm", "beamng"), default="fgnetfdm")
    parser.add_argument("--platform", default="kr500", help="a packaged platform or a file")
    parser.add_argument(
        "--rig", action="store_true", help="send the rig's datagrams to a loopback listener"
    )
    parser.add_argument(
        "--json", help="write the figures here (default: by the protocol and platform)"
    )
    args = parser.parse_args()
    stem = "live_driving" if args.protocol == "beamng" else "live"
    if args.platform != "kr500":
        stem += f"_{Path(args.platform).stem}"
    args.json = args.json or default_result_path(f"{stem}.json")
    robot = load_platform(args.platform)
    listener = None
    if args.rig:  # a loopback listener that drains the datagrams, as a rig's controller
        listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        listener.bind(("127.0.0.1", 0))
        listener.settimeout(0.2)
        draining = threading.Event()

        def drain():
            while not draining.is_set():
                try:
                    listener.recv(4096)
                except OSError:
                    pass

        threading.Thread(target=drain, daemon=True).start()
        rig = RigOutputConfig(url=f"udp://127.0.0.1:{listener.getsockname()[1]}")
    locks = {"on": (True,), "off": (False,), "both": (False, True)}[args.phase_lock]
    report = {"provenance": result_header(print_calibration()), "runs": {}}
    tmp = tempfile.TemporaryDirectory()
    if args.protocol == "beamng":
        drive = Path(tmp.name) / "drive.csv"
        save_recording(drive, demo_drive(args.duration + 3.0))
        report["sender"] = (
            f"BeamNG MotionSim packets of the demo drive ({DEMO_CAR}, seed {DRIVE_SEED})"
        )
    else:
        report["sender"] = "JSBSim's FGNetFDM packets of the light aircraft, seed 7"
    choices = {"on": (True,), "off": (False,), "both": (False, True)}
    guards, consoles = choices[args.guard], choices[args.controls]
    runs = [
        (n, lock, g, c)
        for n in args.mcas.split(",")
        for lock in locks
        for g in guards
        for c in consoles
    ]
    meshcat = Meshcat(MeshcatParams(host="localhost")) if True in consoles else None
    for name, lock, guard, console in runs:
        senders = []

        def start(address, senders=senders):
            if args.protocol == "beamng":
                senders.append(start_drive_sender(address[1], args.duration + 3.0, recording=drive))
            else:
                senders.append(start_demo_sender(address[1], args.duration + 3.0))

        cpu0 = children_cpu_s()
        decoder = (
            make_decoder("beamng")
            if args.protocol == "beamng"
            else make_decoder("fgnetfdm", fgnetfdm_time_resolution_s=DEMO_TIME_RESOLUTION_S)
        )
        summary = run_live(
            decoder,
            mca_config_from_name(name),
            args.duration,
            receiver=ReceiverConfig(port=0),
            on_listening=start,
            plant=args.plant,
            phase_lock=PhaseLockConfig(enabled=lock),
            robot=robot,
            rig=rig if args.rig else None,
            plausibility=PlausibilityConfig(enabled=guard),
            controls=ControlsConfig(enabled=console, udp=f"127.0.0.1:{free_udp_port()}"),
            meshcat=meshcat,
        )
        for process in senders:
            process.terminate()
            process.wait(timeout=10)
        live = summary["live"]
        live["sender_cpu_load"] = (children_cpu_s() - cpu0) / max(summary["wall_time_s"], 1e-9)
        label = f"{name}, phase lock {'on' if lock else 'off'}"
        if args.guard != "on":
            label += f", guard {'on' if guard else 'off'}"
        if args.controls != "on":
            label += f", controls {'on' if console else 'off'}"
        report["runs"][label] = {
            "platform": robot.summary(),
            "rig": summary.get("rig"),
            "live": live,
            "pi": summary["pi"],
            "pi_zero_motion": summary["pi_zero_motion"],
            "violations": summary["violations"],
            "step_time_s": summary["step_time_s"],
        }
        ms = in_ms(live["latency_s"])
        wait = in_ms(live["wait_s"])
        jitter = in_ms(live["loop_jitter_s"])
        print(
            f"{label}: {args.duration:g} s, latency ms {ms} (waiting for the poll {wait}; "
            f"{len(live['phase_shifts_s'])} phase shifts, {live['early_polls']} polls brought "
            f"forward by their sample), loop jitter ms {jitter}, CPU load "
            f"{live['cpu_load']:.2f} (sender {live['sender_cpu_load']:.2f}); packets "
            f"{live['packets']}, bad {live['bad']}, dropped {live['dropped']}, stale events "
            f"{live['stale_events']}, health {live['health']}; PI {summary['pi']:.3f} (zero "
            f"motion {summary['pi_zero_motion']:.3f}); violations {summary['violations']}",
            flush=True,
        )
        if args.rig:
            rig_block = summary["rig"]
            print(
                f"  rig: {rig_block['sent']} datagrams, {rig_block['failed']} failed; "
                f"sample to datagram latency ms {in_ms(rig_block['latency_s'])}",
                flush=True,
            )
    tmp.cleanup()
    if listener is not None:
        draining.set()
        listener.close()
    if args.json:
        atomic_write_json(args.json, report)


if __name__ == "__main__":
    main()
