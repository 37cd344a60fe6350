"""A loopback RSI robot: the controller side of KUKA RSI, for tests and demos.

    python -m mca_drake.live.rsi.emulator --driver 127.0.0.1:49152 --duration 60
        [--cycle-ms 4] [--platform kr500] [--start-deg A1,..,A6] [--start-external E1,..]
        [--report report.json] [--recording recording.npz]

Every cycle (4 or 12 ms, on the monotonic clock) it sends the driver a state packet
(`rsi.xml.format_state`: the axis positions, deg, and the IPOC, ms) and waits for the reply
for a cycle. A reply with this cycle's IPOC that reaches its socket within a cycle of the
state's leaving (both the kernel's stamps: a controller's cycle runs from when its state
goes out; a stall of this process before it does is this process's own, as its oversleeping
is: one of over a cycle is counted as a late send, a whole cycle overslept as an overrun,
skipped) is on time, and its corrections (deg, relative to the start pose; mm for a linear
external axis) become the axes' new positions; a reply for an earlier cycle is late and
ignored; none by then is a missed cycle (the axes hold). Like a controller, it stops (and
sends nothing more) when `max_missed` cycles in a row go without an on-time reply, and when
a correction would take an axis beyond its limits: position, velocity (per-cycle
difference) or acceleration (second difference), each with the real robot's values
(`mca_drake.platforms.serial.SerialChain`, in degrees or, for a linear axis, mm). A
platform of more than six joints is one controller with external axes: the joints that
carry the robot (a rail) are E1.. (`mca_drake.live.rsi.axes`), whose positions the state
carries in its EIPos element and whose corrections the reply must carry in EK, checked
alike. After a missed cycle the differences are taken over the time since the last
correction applied, as an interpolating controller moves its set point from one correction
to the next.

It records what it received, per cycle: IPOC, when the state packet left, the reply's
latency from then (NaN: none on time), the corrections and the axis positions (the external
axes' apart); and every late reply's IPOC and arrival.
"""

from __future__ import annotations

import argparse
import array
import dataclasses
import gc
import math
import select
import socket
import sys
import time

import numpy as np

from mca_drake.atomic_io import atomic_write_json, atomic_write_npz
from mca_drake.input_checks import check_config_numbers
from mca_drake.live.pacing import wait_until
from mca_drake.live.realtime import request_realtime_priority
from mca_drake.live.rsi.axes import ROBOT_AXES, RsiAxisMap
from mca_drake.live.rsi.xml import (
    MAX_RSI_BYTES,
    RSI_RESOLUTION_DEG,
    BadRsiPacket,
    RsiTags,
    format_state,
    parse_reply,
)
from mca_drake.live.socket_stamps import (
    arrival_time,
    departure_time,
    enable_kernel_timestamps,
    enable_send_timestamps,
)
from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform
from mca_drake.platforms.serial import SerialChain
from mca_drake.simulation.closed_loop import step_time_summary

# Counters the emulator reports, in this order.
EMULATOR_COUNTERS = (
    "cycles",  # state packets sent
    "on_time",  # replies with the cycle's IPOC within a cycle of its sending
    "late",  # replies to earlier cycles (arrived after their cycle)
    "missed",  # cycles without an on-time reply
    "bad_replies",  # replies that did not parse
    "overruns",  # cycles this process could not send on time (its own stall: skipped)
    "late_sends",  # states that left more than a cycle after they were due (its own stall)
)


@dataclasses.dataclass
class RsiEmulatorConfig:
    """The emulated controller's cycle, start pose and limits."""

    # Interpolation cycle, s (RSI: 0.004 or 0.012).
    cycle_s: float = 0.004
    # Axis positions A1..A6 at the start, deg (the driver checks it is its home pose).
    start_deg: list[float] = dataclasses.field(default_factory=lambda: [0.0] * ROBOT_AXES)
    # External axis positions E1.. at the start, mm or deg, one per platform joint beyond
    # the robot's six (empty: the platform's home, the model's zero being the axis's).
    start_external: list[float] = dataclasses.field(default_factory=list)
    # Stop after this many cycles in a row without an on-time reply.
    max_missed: int = 10
    # IPOC of the first cycle (a controller's counter does not start at 0).
    first_ipoc: int = 1_000_000
    # How the IPOC counts: "ms", as KUKA controllers stamp it, or "cycles" (+1 a cycle), as
    # ROS-Industrial's kuka_rsi_simulator counts.
    ipoc_unit: str = "ms"
    # Slack on the limit checks, relative (round-off of the driver's degrees, not room).
    relative_tolerance: float = 1e-6
    # The platform the controller drives, whose axis limits it enforces: a packaged
    # platform's name or a platform file (six joints, or more as external axes).
    platform: str = DEFAULT_PLATFORM

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        if not 0 < self.cycle_s <= 0.1 or round(self.cycle_s * 1e3) < 1:
            raise ValueError(
                f"RsiEmulatorConfig.cycle_s must be in [0.001, 0.1] s; got {self.cycle_s}"
            )
        if len(self.start_deg) != ROBOT_AXES:
            raise ValueError(
                f"RsiEmulatorConfig.start_deg must hold six angles; got {self.start_deg}"
            )
        if self.ipoc_unit not in ("ms", "cycles"):
            raise ValueError(
                f"RsiEmulatorConfig.ipoc_unit must be ms or cycles; got {self.ipoc_unit!r}"
            )
        if self.max_missed < 1 or self.first_ipoc < 0:
            raise ValueError("RsiEmulatorConfig.max_missed must be >= 1 and first_ipoc >= 0")


@dataclasses.dataclass
class AxisLimits:
    """Axis limits in the controller's units (deg, deg/s, deg/s^2; mm, mm/s, mm/s^2 for a
    linear axis), one value per axis in the messages' order: A1..A6, then E1.."""

    min_deg: list[float]
    max_deg: list[float]
    velocity_deg_s: list[float]
    acceleration_deg_s2: list[float]

    @classmethod
    def of_robot(cls, robot: SerialChain, axes: RsiAxisMap | None = None) -> AxisLimits:
        """A platform's joint limits as the controller's axes see them through `axes` (its
        default: the model's zero is the controller's, every sign +1; a sign of -1 swaps an
        axis's position limits)."""
        axes = axes or default_axis_map(robot)
        scale = np.asarray(axes.scales)
        home, home_q = np.asarray(axes.home), np.asarray(axes.home_q)
        a, b = home + scale * (robot.q_min - home_q), home + scale * (robot.q_max - home_q)
        ordered = [
            axes.in_message_order(values.tolist())
            for values in (
                np.minimum(a, b),
                np.maximum(a, b),
                np.abs(scale) * robot.qd_max,
                np.abs(scale) * robot.qdd_max,
            )
        ]
        return cls(*ordered)


def default_axis_map(robot: SerialChain, tags: RsiTags | None = None) -> RsiAxisMap:
    """The controller axes of `robot`'s joints with every sign +1 and the model's zero the
    controller's (`RsiAxisMap.build`'s defaults)."""
    tags = tags or RsiTags()
    return RsiAxisMap.build(robot.joint_kinds, robot.home, tags.axes, tags.external_axes)


class RsiEmulator:
    """The controller side of RSI over loopback (module docstring).

    Args:
        driver: the driver's (host, port).
        config: cycle, start pose, stop rule, platform.
        limits: the axes' limits, A1..A6 then E1.. (None: the configured platform's).
        tags: the messages' XML names.
    """

    def __init__(
        self,
        driver: tuple[str, int],
        config: RsiEmulatorConfig | None = None,
        limits: AxisLimits | None = None,
        tags: RsiTags | None = None,
    ):
        self.config = config or RsiEmulatorConfig()
        self.config.validate()
        self.tags = tags or RsiTags()
        platform = load_platform(self.config.platform)
        axes = default_axis_map(platform, self.tags)
        self.external = axes.external
        start = self.config.start_external
        if start and len(start) != self.external:
            raise ValueError(
                f"RsiEmulatorConfig.start_external must hold {self.external} values for "
                f"{platform.name} (its external axes); got {start}"
            )
        self._start_external = [float(v) for v in start] or list(axes.home[: self.external])
        self.limits = limits or AxisLimits.of_robot(platform, axes)
        if len(self.limits.min_deg) != ROBOT_AXES + self.external:
            raise ValueError(
                f"the axis limits hold {len(self.limits.min_deg)} axes; {platform.name} has "
                f"{ROBOT_AXES + self.external}"
            )
        self._names = axes.in_message_order(axes.names)
        self._units = axes.in_message_order(axes.units)
        self._driver = driver
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._socket.bind(("127.0.0.1", 0))
        self._socket.setblocking(False)
        enable_kernel_timestamps(self._socket)  # replies judged by when they arrived
        # and from when the state left: the kernel's stamp, not this process's clock before
        # sendto (a stall in between is this process's, as its oversleeping is)
        self._departures = enable_send_timestamps(self._socket)
        self.counters = dict.fromkeys(EMULATOR_COUNTERS, 0)
        self.stop_reason = ""
        self.final_missed = 0  # the run of missed cycles that stopped it (the driver's end)
        # (IPOC, arrival: time.perf_counter(), s) of every late reply
        self.late_replies: list[tuple[int, float]] = []
        # per cycle, in flat arrays of numbers: no object the garbage collector must visit
        # piles up (rows of lists did: a full collection came due about every 46000 cycles
        # and held this SCHED_FIFO process 60-145 ms, a cycle's send among them)
        self.rows: dict[str, array.array] = {
            "ipoc": array.array("q"),
            "sent_s": array.array("d"),
            "latency_s": array.array("d"),
            # the axes A1..A6 then E1.., a cycle (deg; mm for a linear external axis)
            "corrections": array.array("d"),
            "axes": array.array("d"),
        }

    def close(self) -> None:
        """Closes the socket."""
        self._socket.close()

    def run(self, duration_s: float) -> dict:
        """Runs cycles for `duration_s` (or until it stops); returns `report()`."""
        cfg = self.config
        cycle_ms = round(cfg.cycle_s * 1e3)
        cycle = cycle_ms * 1e-3
        start = [*map(float, cfg.start_deg), *self._start_external]
        count = len(start)
        axes, velocity = list(start), [0.0] * count
        last_applied, last_step = -1, cycle  # cycle of the last correction, time before it
        missed_in_a_row = 0
        t0 = time.perf_counter() + cycle
        n_cycles = max(1, math.floor(duration_s / cycle))
        n = -1
        while (n := n + 1) < n_cycles:
            due = t0 + n * cycle
            wait_until(due)
            behind = math.floor((time.perf_counter() - due) / cycle)
            if behind > 0:
                # this process overslept whole cycles, which a controller never does: skip
                # them (the IPOC jumps, as after missed cycles) and do not blame the driver
                self.counters["overruns"] += behind
                n += behind
                due += behind * cycle
                if n >= n_cycles:
                    break
            ipoc = cfg.first_ipoc + n * (cycle_ms if cfg.ipoc_unit == "ms" else 1)
            sent = time.perf_counter()
            self._socket.sendto(self._state_packet(n, ipoc, axes), self._driver)
            if self._departures:
                sent = departure_time(self._socket, sent) or sent
            self.counters["cycles"] += 1
            self.counters["late_sends"] += sent - due > cycle
            # a reply is on time within a cycle of the state's leaving
            reply = self._reply_for(ipoc, sent + cycle)
            corrections = [math.nan] * count
            latency = math.nan
            if reply is None:
                self.counters["missed"] += 1
                missed_in_a_row += 1
            else:
                latency, corrections = reply[0] - sent, reply[1]
                self.counters["on_time"] += 1
                missed_in_a_row = 0
                new_axes = [s + c for s, c in zip(start, corrections, strict=True)]
                step = (n - last_applied) * cycle
                problem = self._check(axes, velocity, new_axes, step, last_step)
                if problem:
                    self.stop_reason = problem
                else:
                    velocity = [(b - a) / step for a, b in zip(axes, new_axes, strict=True)]
                    axes, last_applied, last_step = new_axes, n, step
            self._record(ipoc, sent, latency, corrections, axes)
            if self.stop_reason:
                break
            if missed_in_a_row >= cfg.max_missed:
                self.stop_reason = f"{missed_in_a_row} cycles in a row without an on-time reply"
                self.final_missed = missed_in_a_row
                break
        return self.report()

    def report(self) -> dict:
        """Counters, reply latency on time (median, p99, max, s) and why it stopped ("" if
        it ran its time)."""
        out: dict = dict(self.counters)
        latencies = np.asarray(self.rows["latency_s"], float)
        out["reply_latency_s"] = step_time_summary(latencies[np.isfinite(latencies)])
        out["stop_reason"] = self.stop_reason
        # missed cycles before the run of them that stopped the emulator
        out["missed_before_stop"] = self.counters["missed"] - self.final_missed
        return out

    def recording(self) -> dict[str, np.ndarray]:
        """The recording: per cycle ipoc (n,), sent_s (n,) when its state packet left (the
        kernel's stamp where there is one; time.perf_counter(), s), latency_s (n,),
        corrections_deg (n, 6) and axes_deg (n, 6) of A1..A6, external_corrections (n, e)
        and external_axes (n, e) of E1.. (mm or deg; e = 0 without external axes); per
        late reply late_ipoc (m,) and late_arrival_s (m,) (perf_counter, s)."""
        late = np.asarray(self.late_replies, float).reshape(-1, 2)
        width = ROBOT_AXES + self.external
        corrections = np.asarray(self.rows["corrections"], float).reshape(-1, width)
        axes = np.asarray(self.rows["axes"], float).reshape(-1, width)
        return {
            "ipoc": np.asarray(self.rows["ipoc"], np.int64),
            "sent_s": np.asarray(self.rows["sent_s"], float),
            "late_ipoc": late[:, 0].astype(np.int64),
            "late_arrival_s": late[:, 1],
            "latency_s": np.asarray(self.rows["latency_s"], float),
            "corrections_deg": corrections[:, :ROBOT_AXES],
            "axes_deg": axes[:, :ROBOT_AXES],
            "external_corrections": corrections[:, ROBOT_AXES:],
            "external_axes": axes[:, ROBOT_AXES:],
        }

    def _state_packet(self, n: int, ipoc: int, axes: list[float]) -> bytes:
        """Cycle n's state message (a test's subclass may corrupt it)."""
        return format_state(ipoc, axes[:ROBOT_AXES], self.tags, axes[ROBOT_AXES:])

    def _record(self, ipoc, sent, latency, corrections, axes) -> None:
        rows = self.rows
        rows["ipoc"].append(ipoc)
        rows["sent_s"].append(sent)
        rows["latency_s"].append(latency)
        rows["corrections"].extend(corrections)
        rows["axes"].extend(axes)

    def _reply_for(self, ipoc: int, deadline: float) -> tuple[float, list[float]] | None:
        """(arrival time, corrections) of this cycle's reply if it reached the socket by
        `deadline` (the kernel's stamp: a reply that came in time is on time even when this
        process reads it late, as a controller's network stack would have it); late replies
        (to earlier cycles, or this one's after the deadline) and malformed ones are counted
        on the way."""
        while True:
            left = deadline - time.perf_counter()
            # past the deadline, only what has already arrived is read
            if not select.select([self._socket], [], [], max(left, 0.0))[0]:
                return None
            try:
                datagram, ancillary, _, _ = self._socket.recvmsg(MAX_RSI_BYTES + 1, 64)
            except BlockingIOError:  # a send's stamp made the socket look readable
                departure_time(self._socket, math.inf)  # takes every stamp off
                if left <= 0.0:
                    return None  # past the deadline: no spinning on a stamp that stays
                continue
            arrived = arrival_time(ancillary)
            try:
                reply = parse_reply(datagram, self.tags, self.external)
            except BadRsiPacket:
                self.counters["bad_replies"] += 1
                continue
            if reply.ipoc == ipoc and arrived <= deadline:
                return arrived, [*reply.axes_deg, *reply.external]
            self.counters["late"] += 1
            self.late_replies.append((reply.ipoc, arrived))

    def _check(self, axes, velocity, new_axes, step: float, last_step: float) -> str:
        """Why `new_axes`, `step` s after the last correction applied (`axes`, reached at
        `velocity` over `last_step` s), cannot be applied ("" if they can)."""
        lim, tol = self.limits, self.config.relative_tolerance
        names, units = self._names, self._units
        # the replies' rounding to RSI_RESOLUTION_DEG shows in the differences: allowed
        position_slack = RSI_RESOLUTION_DEG
        velocity_slack = 2 * RSI_RESOLUTION_DEG / step
        mean_step = 0.5 * (step + last_step)
        acceleration_slack = 4 * RSI_RESOLUTION_DEG / (step * mean_step)
        for j in range(len(new_axes)):
            low, high = lim.min_deg[j], lim.max_deg[j]
            if (
                not low - tol * abs(low) - position_slack
                <= new_axes[j]
                <= high + tol * abs(high) + position_slack
            ):
                return f"{names[j]} position {new_axes[j]:.4f} {units[j]} beyond its limits"
            v = (new_axes[j] - axes[j]) / step
            if abs(v) > lim.velocity_deg_s[j] * (1 + tol) + velocity_slack:
                return f"{names[j]} velocity {v:.3f} {units[j]}/s over its limit"
            a = (v - velocity[j]) / mean_step
            if abs(a) > lim.acceleration_deg_s2[j] * (1 + tol) + acceleration_slack:
                return f"{names[j]} acceleration {a:.2f} {units[j]}/s^2 over its limit"
        return ""


def split_reply_latency(recording: dict, driver_timing: dict) -> dict:
    """Where each cycle's reply time went, from the emulator's `recording()` and the driver's
    `RsiDriver.timing()` of one run on one machine (both on the shared perf_counter clock):

    - there_s (n,): the state packet left -> the kernel's receive stamp for the driver (on
      loopback both stamps are taken as the packet passes the loopback device, so this is
      about 0 with the emulator's transmit stamps; without them it holds the emulator's
      own delay between its clock and the send);
    - answer_s (n,): that receive stamp -> the reply in the emulator's socket, on time or
      late: the packet's delivery to the driver's socket, the driver's own time and the way
      back (over loopback the reply reaches the emulator within the driver's `sendto`);

    NaN where the driver did not answer that cycle or its reply never came. And "unanswered":
    per cycle without an on-time reply while the driver ran (IPOC up to its last answer), a
    dict of ipoc, sent_s and the two parts (s, NaN where unknown)."""
    ipoc = np.asarray(recording["ipoc"], np.int64)
    sent = np.asarray(recording["sent_s"], float)
    latency = np.asarray(recording["latency_s"], float)
    robot_arrival = sent + latency
    # a late reply's arrival stands in where none came on time (the first, if several)
    late_ipoc = np.asarray(recording["late_ipoc"], np.int64)
    late_arrival = np.asarray(recording["late_arrival_s"], float)
    for m in np.unique(late_ipoc):
        rows = np.flatnonzero(ipoc == m)
        if rows.size and not np.isfinite(robot_arrival[rows[0]]):
            robot_arrival[rows[0]] = late_arrival[late_ipoc == m].min()
    # the driver answers each IPOC at most once: its rows by IPOC
    row_of = {int(m): j for j, m in enumerate(driver_timing["ipoc"])}
    rows = np.array([row_of.get(int(m), -1) for m in ipoc], np.int64)
    arrival = np.full(ipoc.shape, np.nan)
    arrival[rows >= 0] = np.asarray(driver_timing["arrival_s"], float)[rows[rows >= 0]]
    there, answer = arrival - sent, robot_arrival - arrival
    last_answered = max(row_of, default=-1)
    unanswered = [
        {
            "ipoc": int(ipoc[i]),
            "sent_s": float(sent[i]),
            "there_s": float(there[i]),
            "answer_s": float(answer[i]),
        }
        for i in np.flatnonzero(~np.isfinite(latency) & (ipoc <= last_answered))
    ]
    return {"there_s": there, "answer_s": answer, "unanswered": unanswered}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--driver", required=True, help="HOST:PORT the driver listens on")
    parser.add_argument("--duration", type=float, default=60.0, help="s")
    parser.add_argument("--cycle-ms", type=int, default=4, help="4 or 12")
    parser.add_argument("--start-deg", help="six comma-separated angles (default zeros)")
    parser.add_argument(
        "--platform", default=DEFAULT_PLATFORM, help="packaged platform name or platform file"
    )
    parser.add_argument(
        "--start-external",
        help="comma-separated external axis positions E1.. (mm or deg; default the home)",
    )
    parser.add_argument("--report", help="write the counters here (JSON)")
    parser.add_argument("--recording", help="write the per-cycle recording here (npz)")
    parser.add_argument(
        "--realtime-priority", type=int, default=60, help="SCHED_FIFO priority (0: none)"
    )
    args = parser.parse_args(argv)
    host, _, port = args.driver.rpartition(":")
    config = RsiEmulatorConfig(cycle_s=args.cycle_ms * 1e-3, platform=args.platform)
    if args.start_external:
        config.start_external = [float(v) for v in args.start_external.split(",")]
    if args.start_deg:
        config.start_deg = [float(v) for v in args.start_deg.split(",")]
    emulator = RsiEmulator((host, int(port)), config)
    # what was built (numpy, the robot model) leaves the garbage collector's view: a full
    # collection of it would hold this SCHED_FIFO process for tens of milliseconds
    gc.collect()
    gc.freeze()
    # a controller is hard real time: the emulator asks for it where it may, once built
    # (loading the model is no real-time work and would hold a core at that priority)
    realtime = request_realtime_priority(args.realtime_priority)
    try:
        report = emulator.run(args.duration)
    finally:
        emulator.close()
    report["realtime_priority"] = args.realtime_priority if realtime else 0
    if args.report:
        atomic_write_json(args.report, report)
    if args.recording:
        atomic_write_npz(args.recording, emulator.recording())
    print(report, flush=True)
    return 0 if not report["stop_reason"] else 1


if __name__ == "__main__":
    sys.exit(main())
