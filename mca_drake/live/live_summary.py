"""A live run's summary: the closed loop scored as `run_closed_loop` scores it, and the
`live` (telemetry, latency, health, pacing) and `rsi` blocks (docs/guides/live.md)."""

from __future__ import annotations

import dataclasses
import ipaddress

import numpy as np
from pydrake.systems.framework import Context

from mca_drake.cueing import McaConfig, mca_config_record, mca_name
from mca_drake.live.controls import MODES
from mca_drake.live.pacing import RealTimePacer
from mca_drake.live.receiver import TelemetryReceiver
from mca_drake.live.rsi.link import RobotClockServo, RsiLink
from mca_drake.live.supervisor import HEALTH_STATES
from mca_drake.live.telemetry import Decoder
from mca_drake.platforms.kinematics import plant_output
from mca_drake.platforms.serial import SerialChain
from mca_drake.references.vehicle_signals import SIGNALS
from mca_drake.simulation.closed_loop import (
    check_alignment,
    closed_loop_summary,
    station_signals,
    step_time_summary,
)
from mca_drake.simulation.trajectory import trajectory_csv

# A control interval over this many periods on the wall clock counts as a stall in the
# summary: the loop (or the machine) held up for half the supervisor's default stale time.
STALL_PERIODS = 5


@dataclasses.dataclass
class PacedRun:
    """What a finished live run leaves for its summary."""

    context: Context
    wall_s: float
    cpu_s: float
    phase_shifts_s: list
    pacer: RealTimePacer | None
    link: RsiLink | None
    servo: RobotClockServo | None
    rsi_status: dict | None
    # what the loop told the user while it ran (`live.loop.first_look`)
    notices: list[str] = dataclasses.field(default_factory=list)


# The summary's scores of what was cued: taken over the span the telemetry covered.
SPAN_SCORES = ("pi", "pi_zero_motion", "rmse", "cc", "false_rotation", "perceived")


def scored_summary(
    handles: dict,
    config: McaConfig,
    plant: str,
    decoder: Decoder,
    robot: SerialChain,
    h: float,
    wall_s: float,
) -> dict:
    """The closed-loop summary of the recorded run, scored as `run_closed_loop` scores.

    The limits, the step times and the jolts count the whole run; the tracking scores
    (SPAN_SCORES) count the span the telemetry covered, from the control period of the
    first sample to that of the last (`scored_span_s`, s of loop time): before the first
    sample the robot waits at home, after the last it washes out, and neither is a cue of
    the stream (a gap inside the span still counts).
    """
    source = handles["receiver"]
    rows = handles["recorder"].rows
    reference, outputs, states, accelerations = live_signals(handles, plant, robot, h)
    n = reference.shape[0]
    arguments = dict(
        mca=mca_name(config),
        mca_config=mca_config_record(config),
        plant=plant,
        reference_name=f"live {decoder.protocol} udp://{source.address[0]}:{source.address[1]}",
        robot=robot,
        time_step=h,
        wall_s=wall_s,
    )
    statistics = rows("statistics")
    summary, _ = closed_loop_summary(
        **arguments,
        duration_s=n * h,
        reference=reference,
        outputs=outputs,
        states=states,
        accelerations=accelerations,
        statistics=statistics,
    )
    first, last = scored_span(handles["probe"].sample_instants, n)
    summary["scored_span_s"] = [first * h, (last - 1) * h]
    if last - first >= 2 and (first, last) != (0, n):
        span = slice(first, last)
        scored, _ = closed_loop_summary(
            **arguments,
            duration_s=(last - first) * h,
            reference=reference[span],
            outputs=outputs[span],
            states=states[span],
            accelerations=accelerations[span],
            statistics=None,
        )
        summary |= {key: scored[key] for key in SPAN_SCORES}
    return summary


def scored_span(sample_instants: list[int], periods: int) -> tuple[int, int]:
    """[first, last) control periods of the span the telemetry covered: from the period
    of the first sample to the one of the last, within the run's `periods` (all of them
    when no sample came)."""
    if not sample_instants:
        return 0, periods
    first = min(max(int(sample_instants[0]), 0), periods - 1)
    return first, min(max(int(sample_instants[-1]) + 1, first + 1), periods)


def live_signals(handles: dict, plant: str, robot: SerialChain, h: float):
    """(reference, outputs, states, accelerations) of the recorded run, one row per control
    period, as `run_closed_loop` aligns them: the reference received, what the cabin did
    (the analytical plant's output, or the station's IMU without its delay), [q, qd] and
    the joint accelerations over each period."""
    rows = handles["recorder"].rows
    commands, reference = rows("command"), rows("reference")  # period k: rows 0..N-1
    n = commands.shape[0]
    if plant == "analytical":
        states = rows("state")  # x_k before each poll: rows 0..N
        # the plant integrated exactly the recorded commands (it steps after the recorder)
        check_alignment(states[: n + 1], commands, h)
        states = states[:n]
        n_joints = robot.num_joints
        outputs = plant_output(states[:, :n_joints], states[:, n_joints:], commands, robot)
        return reference, outputs, states, commands
    # what the occupant felt (the IMU without its delay), as run_closed_loop scores it
    states, accelerations, outputs = station_signals(
        rows("true_state"), rows("measured_output"), n, h
    )
    return reference, outputs, states, accelerations


def live_trajectory(handles: dict, plant: str, robot: SerialChain, h: float) -> str:
    """The recorded run's time series as trajectory CSV text (`simulation.trajectory`), with
    the supervisor's health, the operator's mode and the intensity in effect in each
    period (`LIVE_COLUMNS`), then the controls and vehicle state of each period's sample
    where the protocol carried them (a column per `vehicle_signals.SIGNALS` name, SI, nan
    for a sample without it)."""
    reference, outputs, states, accelerations = live_signals(handles, plant, robot, h)
    rows = handles["recorder"].rows
    n = reference.shape[0]
    live = {"health": [HEALTH_STATES[int(v)] for v in rows("health")[:n, 0]]}
    if handles.get("operator") is not None:
        settings = rows("settings")[:n]
        live["mode"] = [MODES[int(v)] for v in rows("mode")[:n, 0]]
        live["intensity"] = [repr(float(v)) for v in settings[:, 0] * settings[:, -1]]
    else:
        live["mode"], live["intensity"] = ["run"] * n, ["1.0"] * n
    reactions = rows("reaction")[:n, 0] if handles.get("reference_guard") is not None else None
    signals = rows("signals")[:n]
    for i, name in enumerate(SIGNALS):  # those the protocol carried, NaN where a sample lacked
        if np.isfinite(signals[:, i]).any():
            live[name] = [repr(float(v)) for v in signals[:, i]]
    return trajectory_csv(
        robot, np.arange(n) * h, reference, outputs, states, accelerations, reactions, live
    )


def live_block(
    handles: dict, run: PacedRun, decoder: Decoder, realtime_rate: float, h: float
) -> dict:
    """The summary's `live` block: telemetry counters, latency, health and pacing."""
    source, guard, probe = handles["receiver"], handles["supervisor"], handles["probe"]
    telemetry = source.counters(source.GetMyContextFromRoot(run.context))
    health = guard.health(guard.GetMyContextFromRoot(run.context))
    pacer = run.pacer
    return {
        "protocol": decoder.protocol,
        "address": f"udp://{source.address[0]}:{source.address[1]}",
        # who was read: the locked first sender, or the senders the scenario allows
        "sender": sender_text(telemetry, source),
        "packets": int(telemetry["packets"]),
        "bad": int(telemetry["bad"]),
        "foreign": int(telemetry["foreign"]),
        "out_of_order": int(telemetry["out_of_order"]),
        "time_jumps": int(telemetry["time_jumps"]),
        "restarts": int(telemetry["restarts"]),
        "sender_changes": int(telemetry["sender_changes"]),
        "dropped": int(telemetry["dropped"]),
        "kernel_dropped": int(telemetry["kernel_dropped"]),
        "stale_periods": int(telemetry["stale_periods"]),
        "stale_events": sum(
            1 for _, _, to, why in guard.transitions if why == "telemetry stale" and to == "fault"
        ),
        "latency_s": step_time_summary(np.asarray(probe.latencies_s)),
        # how long samples waited in the socket for their poll (part of the latency)
        "wait_s": step_time_summary(np.asarray(probe.waits_s)),
        # the phase lock's shifts of the control instants, s (> 0: earlier)
        "phase_shifts_s": run.phase_shifts_s,
        # polls that came after their instant (the loop had overrun)
        "late_polls": 0 if pacer is None else pacer.late_polls,
        # control intervals over STALL_PERIODS periods on the wall clock: the process was
        # held up (by the OS or a slow step) long enough for telemetry to look stale
        "stalls": stalls(probe.instants_s, h, realtime_rate),
        # polls a datagram brought forward (phase lock's wake window)
        "early_polls": 0 if pacer is None else pacer.early_polls,
        # what the loop told the user while it ran (every datagram refused, and why)
        "notices": list(run.notices),
        "health": {
            "ok_s": float(health["ok_s"]),
            "degraded_s": float(health["degraded_s"]),
            "fault_s": float(health["fault_s"]),
        },
        "transitions": [
            {"t_s": t, "from": a, "to": b, "why": why} for t, a, b, why in guard.transitions
        ],
        "realtime_rate": realtime_rate,
        "control_period_s": h,
        # |period - h| of the loop's control instants on the wall clock
        "loop_jitter_s": step_time_summary(
            np.abs(np.diff(probe.instants_s) - h / max(realtime_rate, 1e-9))
            if realtime_rate > 0
            else np.zeros(0)
        ),
        # this process's CPU time over wall time (1.0: one core busy)
        "cpu_load": run.cpu_s / max(run.wall_s, 1e-9),
    }


def sender_text(telemetry: dict, source: TelemetryReceiver) -> str:
    """The sender a run read, as the live block says it."""
    allowed = source.allowed_senders
    if allowed:
        return f"allowed: {', '.join(allowed)}"
    if not np.isfinite(telemetry["sender_ip"]):
        return "none (no datagram arrived)"
    ip = ipaddress.IPv4Address(int(telemetry["sender_ip"]))
    return f"udp://{ip}:{int(telemetry['sender_port'])} (the first sender, locked in)"


def rsi_block(handles: dict, run: PacedRun) -> dict:
    """The summary's `rsi` block: segments sent, the clock servo and the driver's counters."""
    sender, link, servo = handles["rsi"], run.link, run.servo
    return {
        "address": f"rsi://{link.address[0]}:{link.address[1]}",
        "segments_sent": sender.sent,
        "segments_unsent": sender.unsent,
        # the loop's clock following the robot's (`RobotClockServo`)
        "rate_trim_ppm": 1e6 * run.pacer.rate_trim,
        # the driver's lead against its first report, less the phase lock's shifts, s
        "lead_error_s": {
            "max_abs": max((abs(e) for _, e, _ in servo.reports), default=0.0),
            "last": servo.reports[-1][1] if servo.reports else 0.0,
        },
        **run.rsi_status,
    }


def stalls(instants_s: list[float], period_s: float, realtime_rate: float) -> int:
    """How many wall intervals between consecutive control instants exceed STALL_PERIODS
    control periods (of wall time at `realtime_rate`); 0 when not paced."""
    if realtime_rate <= 0 or len(instants_s) < 2:
        return 0
    return int(np.sum(np.diff(instants_s) > STALL_PERIODS * period_s / realtime_rate))
