"""RSI driver figures: reply latency per robot cycle and late replies, live.

    python benchmarks/bench_rsi.py [--duration 600] [--cycles-ms 4,12] [--mca dpc]
        [--platform kr500] [--json results/rsi.json]

For each RSI cycle: the live loop of `bench_live.py` (JSBSim flies the light aircraft in
real time and streams FGNetFDM packets over loopback; the MCA on the analytical plant at
real-time rate 1) drives a robot over RSI (`mca-drake live --robot`): the driver in its own
process, the loopback RSI robot emulator (`mca_drake.live.rsi.emulator`) in another, started
at the platform's home pose (the DPC's and the NMPC's), sending its state every cycle for the
whole run. `--platform kr500-rail` drives the rail as the controller's external axis E1
beside A1-A6. Prints, per cycle, the
reply latency as the robot sees it (its state left -> the reply in its socket, both the
kernel's stamps: median, p99, max), the driver's own (the state's kernel arrival -> reply
sent), late and missed replies, the emulator's own stalls (overruns, late sends), and the
loop's telemetry latency beside them. The machine's calibration first.

Where a reply's time goes: the driver logs each cycle's state arrival
(`RsiDriverConfig.timing_path`), the emulator its states' departures and the late replies'
arrivals, on the clock both share, so each reply splits into the way there and the answer
(`rsi.emulator.split_reply_latency`; median, p99, max); and a stall probe per CPU
(`machine_stalls.py`: when that CPU was not there for a SCHED_FIFO 40 process, and its steal
time; it wakes every 5 ms, a few microseconds each, above the live loop) says for each cycle
left without a reply on time whether the machine stalled in it. Writes the figures with
their provenance (date, command, calibration, machine) to `--json`, by default
`benchmarks/results/rsi.json` (the KR500) or `rsi-PLATFORM.json`.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from common import default_result_path, in_ms, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing import mca_config_from_name
from mca_drake.live.demo import DEMO_TIME_RESOLUTION_S, start_demo_sender
from mca_drake.live.loop import make_decoder, run_live
from mca_drake.live.receiver import ReceiverConfig
from mca_drake.live.rsi.driver import RsiDriverConfig
from mca_drake.live.rsi.emulator import default_axis_map, split_reply_latency
from mca_drake.live.rsi.motion import RsiMotionConfig
from mca_drake.platforms.files import load_platform
from mca_drake.simulation.closed_loop import step_time_summary

STALL_PROBE = Path(__file__).with_name("machine_stalls.py")


def start_stall_probes(duration_s: float, folder: Path, tag: str) -> list:
    """One `machine_stalls.py` per CPU this process may use: (process, its JSON file)."""
    probes = []
    for cpu in sorted(os.sched_getaffinity(0)):
        out = folder / f"stalls_{tag}_cpu{cpu}.json"
        command = [sys.executable, str(STALL_PROBE), "--cpu", str(cpu)]
        command += ["--duration", repr(duration_s), "--out", str(out)]
        probes.append((subprocess.Popen(command), out))
    return probes


def where_replies_went(recording: dict, timing: dict, stalls: list, cycle_s: float) -> dict:
    """The split of each reply's time (ms: median, p99, max of each part); the cycles left
    without a reply on time while the driver ran, counted by where the cycle went (the state
    reached the driver after the cycle had passed, or else the answer came late or never: a
    state the driver has no record of counts there too), each with its parts (ms) and the
    machine's stalls (ms, on any CPU) that overlapped it."""
    split = split_reply_latency(recording, timing)
    parts = {
        part: in_ms(step_time_summary(values[np.isfinite(values)]))
        for part, values in ((p, split[p]) for p in ("there_s", "answer_s"))
    }
    unanswered, state_too_late = [], 0
    for cycle in split["unanswered"]:
        state_too_late += cycle["there_s"] > cycle_s
        start, end = cycle["sent_s"], cycle["sent_s"] + cycle_s
        overlapping = [late for at, late in stalls if at < end and at + late > start]
        unanswered.append(
            {
                "ipoc": cycle["ipoc"],
                **in_ms({p: cycle[p] for p in ("there_s", "answer_s")}),
                "machine_stalls_ms": [f"{late * 1e3:.2f}" for late in overlapping],
            }
        )
    return {
        "parts_ms": parts,
        "state_reached_the_driver_after_its_cycle": state_too_late,
        "answer_late_or_lost": len(unanswered) - state_too_late,
        "unanswered": unanswered,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=600.0, help="s per cycle time")
    parser.add_argument("--cycles-ms", default="4,12")
    parser.add_argument("--mca", default="dpc")
    parser.add_argument("--platform", default="kr500", help="a packaged platform or a file")
    parser.add_argument("--json", help="write the figures here (default: by platform)")
    args = parser.parse_args()
    platform = load_platform(args.platform)
    if args.json is None:
        name = "rsi.json" if platform.name == "kr500" else f"rsi-{platform.name}.json"
        args.json = default_result_path(name)
    # the emulated controller starts where the driver expects the robot: the home pose, A1-A6
    # in degrees and the joints that carry the robot (a rail) as E1.. in mm or degrees
    axes = default_axis_map(platform)
    start_deg = ",".join(repr(v) for v in axes.home[axes.external :])
    start_external = ",".join(repr(v) for v in axes.home[: axes.external])
    report = {"provenance": result_header(print_calibration()), "runs": {}}
    report["platform"] = platform.summary()
    folder = Path(tempfile.mkdtemp(prefix="bench_rsi_"))
    for cycle_ms in (int(c) for c in args.cycles_ms.split(",")):
        # port 0: the driver takes a free one, written back into rsi.port before start()
        rsi = RsiDriverConfig(
            port=0,
            motion=RsiMotionConfig(cycle_s=cycle_ms * 1e-3),
            timing_path=str(folder / f"driver_timing_{cycle_ms}.npz"),
        )
        processes = []
        emulator_report = folder / f"emulator_{cycle_ms}.json"
        emulator_recording = folder / f"emulator_{cycle_ms}.npz"
        probes = start_stall_probes(args.duration + 6.0, folder, str(cycle_ms))

        def start(
            address,
            processes=processes,
            rsi=rsi,
            c=cycle_ms,
            files=(emulator_report, emulator_recording),
        ):
            processes.append(start_demo_sender(address[1], args.duration + 3.0))
            command = [sys.executable, "-m", "mca_drake.live.rsi.emulator"]
            command += ["--driver", f"127.0.0.1:{rsi.port}", "--cycle-ms", str(c)]
            command += ["--duration", repr(args.duration + 2.0), "--platform", args.platform]
            command += ["--start-deg", start_deg]
            if start_external:
                command += ["--start-external", start_external]
            command += ["--report", str(files[0]), "--recording", str(files[1])]
            processes.append(subprocess.Popen(command, stdout=subprocess.DEVNULL))

        summary = run_live(
            make_decoder("fgnetfdm", fgnetfdm_time_resolution_s=DEMO_TIME_RESOLUTION_S),
            mca_config_from_name(args.mca),
            args.duration,
            receiver=ReceiverConfig(port=0),
            on_listening=start,
            rsi=rsi,
            robot=platform,
        )
        sender, emulator = processes
        sender.terminate()
        sender.wait(timeout=10)
        emulator.wait(timeout=60)
        robot = json.loads(emulator_report.read_text())
        driver = summary["rsi"]
        live = summary["live"]
        for probe, _ in probes:
            probe.wait(timeout=60)
        machine = [json.loads(out.read_text()) for _, out in probes]
        stalls = [stall for cpu in machine for stall in cpu["stalls"]]
        recording, timing = dict(np.load(emulator_recording)), dict(np.load(rsi.timing_path))
        replies = where_replies_went(recording, timing, stalls, cycle_ms * 1e-3)
        label = f"{args.mca}, RSI cycle {cycle_ms} ms"
        report["runs"][label] = {
            "emulator": robot,
            "driver": driver,
            "replies": replies,
            "machine": [{k: v for k, v in cpu.items() if k != "stalls"} for cpu in machine],
            "machine_stalls": stalls,
            "live_latency_s": live["latency_s"],
            "cpu_load": live["cpu_load"],
            "violations": summary["violations"],
            "pi": summary["pi"],
            # how far each external axis (a rail's E1, mm) travelled: it moved with the loop
            "external_travel": np.ptp(recording["external_axes"], axis=0).tolist()
            if recording["external_axes"].size
            else [],
        }
        print(
            f"{label}: {args.duration:g} s; the robot's view: {robot['cycles']} cycles, "
            f"{robot['on_time']} replies on time, {robot['late']} late, "
            f"{robot['missed_before_stop']} missed before the driver's end, "
            f"{robot['bad_replies']} bad, {robot['overruns']} of its own overruns, "
            f"{robot['late_sends']} of its own late sends, "
            f"SCHED_FIFO {robot['realtime_priority']}, reply latency ms "
            f"{in_ms(robot['reply_latency_s'])}, stopped: {robot['stop_reason'] or 'no'}; the "
            f"driver's: {driver['cycles']} cycles, {driver['late_replies']} late, "
            f"{driver['missed_cycles']} missed, latency ms {in_ms(driver['reply_latency_s'])}, "
            f"trajectory lead ms {in_ms(driver['lead_s'])}, SCHED_FIFO "
            f"{driver['realtime_priority']}, rate trim {driver['rate_trim_ppm']:.0f} ppm, "
            f"ended {driver['mode']} "
            f"({driver['reason']}); loop latency ms {in_ms(live['latency_s'])}, CPU load "
            f"{live['cpu_load']:.2f}; violations {summary['violations']}; PI "
            f"{summary['pi']:.3f}"
            + (
                f"; external axes travelled {report['runs'][label]['external_travel']} (mm or deg)"
                if report["runs"][label]["external_travel"]
                else ""
            ),
            flush=True,
        )
        worst = sorted(late for _, late in stalls)[-3:]
        print(
            f"  where the replies' time went (ms): {replies['parts_ms']}; cycles without a "
            f"reply on time: the state reached the driver after its cycle "
            f"{replies['state_reached_the_driver_after_its_cycle']}, the answer late or lost "
            f"{replies['answer_late_or_lost']}; machine: "
            f"{len(stalls)} stalls over 1 ms on its CPUs (longest "
            f"{', '.join(f'{late * 1e3:.1f}' for late in worst) or '-'}), steal "
            f"{sum(cpu['steal_s'] for cpu in machine):.2f} s",
            flush=True,
        )
        for cycle in replies["unanswered"]:
            print(f"  no reply on time: {cycle}", flush=True)
    if args.json:
        atomic_write_json(args.json, report)


if __name__ == "__main__":
    main()
