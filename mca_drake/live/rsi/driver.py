"""RsiDriver: the live loop's joint commands to a KUKA robot over RSI, in a process of its own.

    python -m mca_drake.live.rsi.driver --job job.json --command-fd N [--status status.json]

A KUKA controller running RSI sends its state (`mca_drake.live.rsi.xml`) every interpolation
cycle, 4 or 12 ms, and needs the reply, with the same IPOC, within that cycle; the live loop
steps every 10 ms in Python and may stall, or die. So the RSI socket has a process of its
own that does nothing else: every cycle it reads the state, takes the loop's newest command
segments from its command socket (`rsi.motion.CommandSegment`, Unix datagrams), steps its
`MotionFollower` (the exact trajectory, `delay_s` behind the loop, checked against the
robot's limits, braking when the segments stop) and replies with the axis corrections: the
commanded joint positions relative to the home pose, in degrees, with the axis signs of the
robot (`RsiDriverConfig.axis_signs`). A platform with more than six joints drives the extra
ones, the axes that carry the robot (a rail), as the controller's external axes E1.. (in mm
for a linear one; `mca_drake.live.rsi.axes`).

Safety, in order: the driver refuses to start (sends nothing and exits) unless the robot
reports the expected home pose within `home_tolerance_deg`; every correction it sends is a
state that passed the follower's per-cycle checks (limits, viability at the cycle period)
or a braking step from one; a stalled or killed loop, stale telemetry that ended the loop's
run, a malformed state packet or SIGTERM make it brake to rest and hold there; when the robot
stops sending (RSI ended) it writes its counters and exits.

The loop's simulated time is mapped to the robot's IPOC clock (milliseconds) at the first
cycle that brings segments (the newest of them is the loop's present; older ones that
waited for the robot's first cycle are its past); both are then assumed to run at the same
rate: the driver reports its mean lead (how far the held trajectory reaches beyond the time
it plays, `delay_s` at the start) every 0.6 s, and the loop trims its clock's rate to keep
it (`mca_drake.live.rsi.link.RobotClockServo`), since a controller's crystal drifts from
the PC's by parts per million. A lead that runs out anyway ends in braking, never a jump.
"""

import argparse
import array
import dataclasses
import gc
import json
import math
import os
import signal
import socket
import struct
import sys
import time
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_json, atomic_write_npz
from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.input_checks import check_config_numbers
from mca_drake.live.endpoints import parse_endpoint
from mca_drake.live.realtime import request_realtime_priority
from mca_drake.live.rsi.axes import ROBOT_AXES, RsiAxisMap
from mca_drake.live.rsi.motion import (
    MAX_SEGMENT_BYTES,
    BadSegment,
    CommandSegment,
    MotionFollower,
    RsiMotionConfig,
    SegmentBuffer,
)
from mca_drake.live.rsi.xml import MAX_RSI_BYTES, BadRsiPacket, RsiTags, format_reply, parse_state
from mca_drake.live.socket_stamps import arrival_time, enable_kernel_timestamps
from mca_drake.simulation.closed_loop import step_time_summary

# Counters the driver reports, in this order.
DRIVER_COUNTERS = (
    "cycles",  # state packets answered
    "foreign",  # state packets from another address than the controller's: never answered
    "bad_state",  # state packets that did not parse (no reply: no IPOC to echo)
    "missed_cycles",  # cycles the IPOC skipped (state packets the driver never saw)
    "late_replies",  # replies sent more than one cycle after their state packet arrived
    "segments",  # command segments taken from the loop
    "bad_segments",  # command datagrams that were not segments
)


# What the driver tells the loop once the robot's first state packet showed the home pose:
# the loop may start (`mca_drake.live.rsi.link.wait_for_robot`).
ROBOT_READY = b"robot ready"
# While following, the driver reports its mean lead (s) over this much robot time (s) to the
# loop: LEAD_REPORT then the mean as a little-endian double. 0.6 s is a whole number of the
# lead's sawtooth (the LCM of the 10 ms period and a 4 or 12 ms cycle), so it averages out.
LEAD_REPORT = b"lead"
LEAD_REPORT_EVERY_S = 0.6
_DOUBLE = struct.Struct("<d")


def lead_report(lead_s: float) -> bytes:
    """The datagram that reports a mean lead of `lead_s` seconds to the loop."""
    return LEAD_REPORT + _DOUBLE.pack(lead_s)


def read_lead_report(message: bytes) -> float | None:
    """The lead (s) a `lead_report` datagram carries; None for any other message."""
    if message.startswith(LEAD_REPORT) and len(message) == len(LEAD_REPORT) + _DOUBLE.size:
        return _DOUBLE.unpack_from(message, len(LEAD_REPORT))[0]
    return None


# After a requested stop brought the robot to rest, the driver answers this long (s) more.
HOLD_AFTER_STOP_S = 0.2
# The IPOC's unit is measured against the local clock over this many first state packets
# (the robot holds its home pose meanwhile: the loop starts only after them).
IPOC_CHECK_PACKETS = 10
# A measured IPOC rate within this factor of a unit's is that unit.
IPOC_RATE_TOLERANCE = 1.5
IPOC_UNITS = ("auto", "ms", "cycles")
# The trajectory may lead the time played by delay_s and this much more (s): beyond it the
# robot's clock runs slower than the loop's, which no rate trim catches up.
LEAD_MARGIN_S = 0.5


class RsiRefused(RuntimeError):  # noqa: N818 (a refusal, not a failure)
    """The driver will not move the robot (not at the home pose); the message says why."""


@dataclasses.dataclass
class RsiDriverConfig:
    """Where the driver listens and how joint commands become RSI axis corrections."""

    # Address the driver listens on for the controller's state packets (the RSI config's
    # IP_NUMBER and PORT on the controller side point here).
    host: str = "127.0.0.1"
    port: int = 49152
    # How the trajectory is played (cycle, delay behind the loop).
    motion: RsiMotionConfig = dataclasses.field(default_factory=RsiMotionConfig)
    # The controller's axis positions A1..A6 (deg) at the MCA's home pose; empty: the home
    # pose's joint angles in degrees times axis_signs (the model's zero is the robot's).
    home_deg: list[float] = dataclasses.field(default_factory=list)
    # +1 or -1 per axis: the robot's axis direction against the model's joint.
    axis_signs: list[float] = dataclasses.field(default_factory=lambda: [1.0] * ROBOT_AXES)
    # The same for the external axes E1.. that move a platform's joints beyond the robot's
    # six (a rail: E1, in mm for a linear axis): their positions at the home pose (mm or
    # deg; empty: the home pose's in mm or deg times the sign) and signs (empty: all +1).
    external_home: list[float] = dataclasses.field(default_factory=list)
    external_signs: list[float] = dataclasses.field(default_factory=list)
    # The robot must report its home within these at the first cycle, or nothing moves:
    # deg for a rotary axis, mm for a linear one.
    home_tolerance_deg: float = 0.5
    home_tolerance_mm: float = 1.0
    # No state packet for this long (s) after the first: the controller ended RSI; the
    # driver exits. Before the first it waits (until asked to stop).
    robot_silence_s: float = 0.5
    # The live loop waits this long (s) for the robot's first state packet at home before
    # it starts (`RobotReady`); then it gives up.
    connect_timeout_s: float = 60.0
    # The loop's control period (s): a segment k holds over [k h, (k + 1) h).
    period_s: float = CONTROL_PERIOD_S
    # SCHED_FIFO priority the driver asks for (`live.realtime`; 0: none): it must answer
    # within the cycle while the flight simulator and the loop share the machine.
    realtime_priority: int = 50
    # Where the driver writes each cycle's timing at its end (npz, `RsiDriver.timing`), to
    # tell a late reply's way there from the driver's own time; "": not kept (16 bytes a
    # cycle: 14 MB an hour at 4 ms).
    timing_path: str = ""
    # The RSI object configuration's XML names.
    tags: RsiTags = dataclasses.field(default_factory=RsiTags)
    # The robot controller: "HOST" or "HOST:PORT" (IPv4); "": the first address that sends
    # a state packet is locked in. Packets from any other address are counted, never answered.
    controller: str = ""
    # The unit of the controller's IPOC: "ms" (KUKA controllers stamp milliseconds),
    # "cycles" (a counter of interpolation cycles, as ROS-Industrial's simulator sends) or
    # "auto" (measured against the local clock over the first cycles). A unit that does not
    # match what is measured is refused at the start.
    ipoc_unit: str = "auto"

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        self.motion.validate()
        self.tags.validate()
        if self.ipoc_unit not in IPOC_UNITS:
            raise ValueError(
                f"RsiDriverConfig.ipoc_unit must be one of {', '.join(IPOC_UNITS)}; got "
                f"{self.ipoc_unit!r}"
            )
        if self.controller:
            controller_address(self.controller)
        if not 0 <= self.port <= 65535:
            raise ValueError(f"RsiDriverConfig.port must be in [0, 65535]; got {self.port}")
        if len(self.axis_signs) != ROBOT_AXES or any(s not in (1, -1) for s in self.axis_signs):
            raise ValueError(
                f"RsiDriverConfig.axis_signs must be six of +1 or -1; got {self.axis_signs}"
            )
        if self.home_deg and len(self.home_deg) != ROBOT_AXES:
            raise ValueError(f"RsiDriverConfig.home_deg must hold six angles; got {self.home_deg}")
        if any(s not in (1, -1) for s in self.external_signs):
            raise ValueError(
                f"RsiDriverConfig.external_signs must be +1 or -1 each; got {self.external_signs}"
            )
        for name in ("external_home", "external_signs"):
            if len(getattr(self, name)) > len(self.tags.external_axes):
                raise ValueError(
                    f"RsiDriverConfig.{name} holds more values than the "
                    f"{len(self.tags.external_axes)} external axes RsiTags names"
                )
        positive = (
            "home_tolerance_deg",
            "home_tolerance_mm",
            "robot_silence_s",
            "period_s",
            "connect_timeout_s",
        )
        if not all(getattr(self, name) > 0 for name in positive):
            raise ValueError(f"RsiDriverConfig.{', '.join(positive)} must be positive")
        if not 0 <= self.realtime_priority <= 99:
            raise ValueError("RsiDriverConfig.realtime_priority must be in [0, 99]")

    def axis_map(self, joint_kinds, home) -> RsiAxisMap:
        """The controller axis of each joint of a platform with these joint kinds and home
        pose, by these settings (`RsiAxisMap.build`); ValueError for a platform the
        controller cannot drive or settings of the wrong length, naming them."""
        tags = self.tags
        return RsiAxisMap.build(
            joint_kinds,
            home,
            tags.axes,
            tags.external_axes,
            self.axis_signs,
            self.external_signs,
            self.home_deg,
            self.external_home,
        )

    def to_dict(self) -> dict:
        """The settings as JSON-ready values (`from_dict` reads them back)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> "RsiDriverConfig":
        """Settings from `to_dict`'s form; ValueError naming an unknown key."""
        values = dict(values)
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = set(values) - known
        if unknown:
            raise ValueError(f"unknown RsiDriverConfig settings: {sorted(unknown)}")
        for name in ("home_deg", "external_home", "external_signs"):
            if values.get(name) is None:
                values[name] = []
        if isinstance(values.get("motion"), dict):
            values["motion"] = RsiMotionConfig(**values["motion"])
        if isinstance(values.get("tags"), dict):
            tags = dict(values["tags"])
            for name in ("axes", "external_axes"):
                if name in tags:
                    tags[name] = list(tags[name])
            values["tags"] = RsiTags(**tags)
        return cls(**values)


def controller_address(text: str) -> tuple[str, int | None]:
    """(IPv4 address, port or None) of `RsiDriverConfig.controller` ("HOST" / "HOST:PORT").

    Raises:
        ValueError: naming the setting, for anything else.
    """
    return parse_endpoint(text, "RsiDriverConfig.controller")


def ipoc_unit_of(rate_per_s: float, cycle_s: float) -> str | None:
    """ "ms" or "cycles" for an IPOC that advances `rate_per_s` a second on the local clock;
    None when it is neither (within IPOC_RATE_TOLERANCE)."""
    for unit, expected in (("ms", 1000.0), ("cycles", 1.0 / cycle_s)):
        if rate_per_s > 0 and abs(math.log(rate_per_s / expected)) < math.log(IPOC_RATE_TOLERANCE):
            return unit
    return None


class RsiDriver:
    """Answers the controller's RSI cycles from the loop's command segments (module docstring).

    Args:
        config: addresses, cycle and axis mapping (validated here).
        limits: q_min, q_max (rad or m), qd_max (per s), qdd_max (per s^2), n values each.
        home: the MCA's home pose (n): the loop's first segment starts there.
        commands: the socket the loop's segments arrive on (datagrams), or None.
        joint_kinds: "revolute" or "prismatic" per joint (default: n revolute); the first
            n - 6 joints are external axes (`rsi.axes`).

    Raises:
        ValueError: a bad setting, home pose or joint count. OSError: the RSI address
            cannot be bound.
    """

    def __init__(
        self,
        config: RsiDriverConfig,
        limits,
        home,
        commands: socket.socket | None,
        joint_kinds=None,
    ):
        config.validate()
        self.config = config
        kinds = list(joint_kinds or ["revolute"] * len(home))
        self.axes = config.axis_map(kinds, home)
        units = ["m" if kind == "prismatic" else "rad" for kind in kinds]
        self.follower = MotionFollower(limits, home, config.motion, units)
        motion = config.motion
        capacity = math.ceil((motion.delay_s + 0.5) / config.period_s) + 8
        self.buffer = SegmentBuffer(config.period_s, capacity)
        self._rsi = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._rsi.bind((config.host, config.port))
        # short reads: a stop request is seen while no robot sends
        self._rsi.settimeout(min(0.1, config.robot_silence_s))
        enable_kernel_timestamps(self._rsi)
        self.address = self._rsi.getsockname()
        self._commands = commands
        if commands is not None:
            commands.setblocking(False)
        self.counters = dict.fromkeys(DRIVER_COUNTERS, 0)
        # per cycle (8 bytes each: hours of 250 Hz fit): state packet arrival -> reply sent,
        # and the held trajectory's reach beyond the time played, s
        self.latencies_s = array.array("d")
        self.leads_s = array.array("d")
        # per cycle where config.timing_path asks for them: the IPOC answered and when its
        # state packet reached the socket (time.perf_counter(), s)
        self._timed = bool(config.timing_path)
        self.ipocs = array.array("q")
        self.arrivals_s = array.array("d")
        self._ipoc: int | None = None  # the last state packet's IPOC
        self._controller = controller_address(config.controller) if config.controller else None
        self.controller: tuple[str, int] | None = None  # the address answered (locked)
        # the IPOC's unit, in seconds; None until measured (or configured and confirmed)
        self._ipoc_s: float | None = None
        self._ipoc_check: list[tuple[int, float]] = []  # (IPOC, arrival) of the first packets
        self.ipoc_unit = ""
        self._segment_seen = -math.inf  # time.perf_counter() of the last segment taken
        self._anchor: tuple[int, int] | None = None  # (IPOC, k) at the first segment
        self._stop_requested = False
        self._report_from: tuple[int, int] | None = None  # (IPOC, index) of a lead window

    def request_stop(self, reason: str = "the driver was asked to stop") -> None:
        """Brakes to rest and holds; `run` returns once the robot is at rest."""
        self._stop_requested = True
        self.follower.halt(reason)

    def close(self) -> None:
        """Closes the RSI socket."""
        self._rsi.close()

    def run(self, max_cycles: int | None = None) -> dict:
        """Answers cycles until the robot falls silent, `max_cycles` are done, or a requested
        stop has brought the robot to rest; returns `summary()`.

        Raises:
            RsiRefused: the robot's first state is not the home pose, or its IPOC's unit is
                not the configured one (or neither unit); nothing has moved.
        """
        tags = self.config.tags
        last_packet = at_rest = None
        while max_cycles is None or self.counters["cycles"] < max_cycles:
            if self._stop_requested and self.follower.mode == "stopped":
                # hold at rest a little, so that the controller sees it still before the
                # replies end (and RSI stops the robot where it stands)
                at_rest = at_rest or time.monotonic()
                if last_packet is None or time.monotonic() - at_rest > HOLD_AFTER_STOP_S:
                    break
            try:
                packet, ancillary, _, robot = self._rsi.recvmsg(MAX_RSI_BYTES + 1, 64)
            except TimeoutError:
                if last_packet is None:
                    continue  # no robot yet: waiting for the controller to start RSI
                if time.monotonic() - last_packet > self.config.robot_silence_s:
                    break  # the controller ended RSI
                continue
            if not self._from_controller(robot):
                self.counters["foreign"] += 1  # never parsed, never answered
                continue
            last_packet = time.monotonic()
            arrival = arrival_time(ancillary)
            try:
                state = parse_state(packet, tags, self.axes.external)
            except BadRsiPacket as error:
                self.counters["bad_state"] += 1
                self.follower.halt(f"malformed state packet: {error}")
                continue
            dt = self._cycle_time(state, arrival)
            if dt is None:
                continue
            self._ipoc = state.ipoc
            q = self._commanded(state.ipoc, dt)
            corrections, external = self.axes.corrections(q)
            self._rsi.sendto(format_reply(state.ipoc, corrections, tags, external), robot)
            latency = time.perf_counter() - arrival
            self.latencies_s.append(latency)
            if self._timed:
                self.ipocs.append(state.ipoc)
                self.arrivals_s.append(arrival)
            self.counters["cycles"] += 1
            if latency > self.config.motion.cycle_s:
                self.counters["late_replies"] += 1
        return self.summary()

    def _from_controller(self, sender: tuple[str, int]) -> bool:
        """Whether a datagram from `sender` is the controller's: the configured address, or
        the first one that sent (locked in)."""
        if self.controller is not None:
            return tuple(sender) == self.controller
        if self._controller is not None:
            host, port = self._controller
            if sender[0] != host or (port is not None and sender[1] != port):
                return False
        self.controller = (sender[0], sender[1])
        return True

    def _cycle_time(self, state, arrival: float) -> float | None:
        """This cycle's length on the robot's clock (s), or None for a packet the driver
        does not follow (an IPOC that did not advance: counted, and the robot brakes). The
        first packets check the home pose and measure the IPOC's unit."""
        cycle_s = self.config.motion.cycle_s
        if self._ipoc is None:
            self._check_home(state)
            self._ipoc_check.append((state.ipoc, arrival))
            return cycle_s
        elapsed = state.ipoc - self._ipoc
        if elapsed <= 0:
            self.counters["bad_state"] += 1
            self.follower.halt(f"IPOC went from {self._ipoc} to {state.ipoc}")
            return None
        if self._ipoc_s is None:
            self._ipoc_check.append((state.ipoc, arrival))
            if len(self._ipoc_check) >= IPOC_CHECK_PACKETS:
                self._settle_ipoc_unit()
                self._tell_loop(ROBOT_READY)
            return cycle_s  # holding home until the unit is known
        self.counters["missed_cycles"] += max(0, round(elapsed * self._ipoc_s / cycle_s) - 1)
        return elapsed * self._ipoc_s

    def _settle_ipoc_unit(self) -> None:
        """Sets the IPOC's unit from its rate on the local clock over the first packets."""
        (ipoc0, t0), (ipoc1, t1) = self._ipoc_check[0], self._ipoc_check[-1]
        rate = (ipoc1 - ipoc0) / max(t1 - t0, 1e-9)
        cycle_s = self.config.motion.cycle_s
        measured = ipoc_unit_of(rate, cycle_s)
        configured = self.config.ipoc_unit
        if measured is None or configured not in ("auto", measured):
            says = f"counts {measured}" if measured else "is neither milliseconds nor cycles"
            raise RsiRefused(
                f"the controller's IPOC advanced {rate:.1f} a second over its first "
                f"{len(self._ipoc_check)} packets: it {says}, at a {cycle_s * 1e3:g} ms cycle; "
                f"rsi.ipoc_unit is {configured!r} (ms, cycles or auto) and rsi_cycle_ms "
                f"{cycle_s * 1e3:g}: set them to the controller's; nothing has moved"
            )
        self.ipoc_unit = measured
        self._ipoc_s = 1e-3 if measured == "ms" else cycle_s

    def _commanded(self, ipoc: int, dt: float) -> list[float]:
        """The positions to command this cycle (rad): home until the loop's first segment,
        then the followed trajectory; a lead out of its bounds brakes with its reason."""
        if self._ipoc_s is None:
            return self.follower.q  # at home while the IPOC's unit is measured
        self._take_segments()
        if self._anchor is None:
            return self.follower.q  # at home, for the loop's first segment
        ipoc0, k0 = self._anchor
        s = k0 * self.config.period_s + (ipoc - ipoc0) * self._ipoc_s
        s -= self.config.motion.delay_s
        if self.follower.mode == "following":
            lead = self.buffer.lead_s(s)
            self._note_lead(lead, ipoc)
            self._check_lead(lead)
        return self.follower.step(s, dt, self.buffer)

    def _check_lead(self, lead_s: float) -> None:
        """Brakes when the robot's clock and the loop's part: a lead beyond delay_s +
        LEAD_MARGIN_S (the robot's clock slower), or none while segments still arrive (its
        clock faster); a lead lost because segments stopped is the follower's to judge."""
        delay = self.config.motion.delay_s
        if lead_s > delay + LEAD_MARGIN_S:
            self.follower.halt(
                f"the robot's clock runs slower than the loop's: the trajectory leads by "
                f"{lead_s:.3f} s, beyond delay_s + {LEAD_MARGIN_S} s (rsi.ipoc_unit, "
                "rsi_cycle_ms?)"
            )
        elif lead_s < 0 and time.perf_counter() - self._segment_seen < 2 * self.config.period_s:
            self.follower.halt(
                f"the robot's clock runs faster than the loop's: the trajectory is {-lead_s:.3f}"
                " s behind while segments still arrive (rsi.ipoc_unit, rsi_cycle_ms?)"
            )

    def summary(self) -> dict:
        """Counters, reply latency (median, p99, max, s; NaN before a cycle), trajectory
        lead (min, median, s), the follower's mode and why it left "following"."""
        out: dict = dict(self.counters)
        out["reply_latency_s"] = step_time_summary(np.asarray(self.latencies_s))
        leads = np.asarray(self.leads_s)
        out["lead_s"] = (
            {"min": float(leads.min()), "median": float(np.median(leads))} if leads.size else {}
        )
        out["mode"] = self.follower.mode
        out["reason"] = self.follower.reason
        out["controller"] = "" if self.controller is None else "{}:{}".format(*self.controller)
        out["ipoc_unit"] = self.ipoc_unit
        return out

    def timing(self) -> dict[str, np.ndarray]:
        """Each answered cycle's timing (with `config.timing_path`; else empty arrays):
        ipoc (n,); arrival_s (n,), when its state packet reached the socket, on the
        time.perf_counter() clock (s; Linux: the monotonic clock every process shares, so a
        robot's send times compare); reply_s (n,), from that arrival to the driver's clock
        read after its reply's `sendto` returned (s)."""
        return {
            "ipoc": np.asarray(self.ipocs, np.int64),
            "arrival_s": np.asarray(self.arrivals_s),
            # every cycle has a latency; timed runs record the rest from the first cycle on
            "reply_s": np.asarray(self.latencies_s if self._timed else []),
        }

    def _check_home(self, state) -> None:
        """Refuses a robot whose first state is not the home pose, naming the axis furthest
        off by its tolerance."""
        axes, config = self.axes, self.config
        reads = axes.chain_order(state.axes_deg, state.external)
        tolerance = {"deg": config.home_tolerance_deg, "mm": config.home_tolerance_mm}
        off = [
            abs(value - home) / tolerance[unit]
            for value, home, unit in zip(reads, axes.home, axes.units, strict=True)
        ]
        worst = max(range(len(off)), key=off.__getitem__)
        if off[worst] > 1.0:
            unit = axes.units[worst]
            raise RsiRefused(
                f"the robot is not at the home pose: {axes.names[worst]} reads "
                f"{reads[worst]:.3f} {unit}, home is {axes.home[worst]:.3f} {unit} "
                f"(tolerance {tolerance[unit]} {unit}); nothing was sent"
            )

    def _note_lead(self, lead_s: float, ipoc: int) -> None:
        """Keeps the lead and, every LEAD_REPORT_EVERY_S of robot time, tells the loop its
        mean (the loop's clock follows the robot's by it)."""
        self.leads_s.append(lead_s)
        if self._report_from is None:
            self._report_from = (ipoc, len(self.leads_s) - 1)
        first_ipoc, first = self._report_from
        if (ipoc - first_ipoc) * self._ipoc_s >= LEAD_REPORT_EVERY_S - 1e-9:
            window = self.leads_s[first:-1]
            self._tell_loop(lead_report(sum(window) / len(window)))
            self._report_from = (ipoc, len(self.leads_s) - 1)

    def _tell_loop(self, message: bytes) -> None:
        if self._commands is not None:
            try:
                self._commands.send(message)
            except OSError:  # the loop is gone or not listening: it will find out
                pass

    def _take_segments(self) -> None:
        if self._commands is None:
            return
        while True:
            try:
                datagram = self._commands.recv(MAX_SEGMENT_BYTES + 1)
            except BlockingIOError:
                break
            except OSError:  # the loop's end of the socket is gone
                break
            try:
                segment = CommandSegment.unpack(datagram, self.follower.joints)
            except BadSegment:
                self.counters["bad_segments"] += 1
                continue
            if self.buffer.add(segment):
                self.counters["segments"] += 1
                self._segment_seen = time.perf_counter()
        if self._anchor is None and self.buffer.newest_k >= 0:
            # the newest segment now is the loop's present: play `delay_s` behind it (a
            # backlog that waited for the robot's first cycle is the past)
            self._anchor = (self._ipoc, self.buffer.newest_k)


# Linux's prctl(PR_SET_PDEATHSIG): a signal the kernel sends when the parent dies.
_PR_SET_PDEATHSIG = 1


def stop_with_parent(parent_pid: int, driver: RsiDriver) -> None:
    """Makes the driver brake and end when the live loop's process dies, however it dies
    (killed, crashed, ended by a signal before the robot connected): the kernel sends
    SIGTERM on the parent's death (Linux); where it cannot, or the parent is already gone,
    the driver stops now rather than run an orphan that holds the RSI port."""
    try:
        # ctypes: the prctl system call, which Python's standard library does not wrap
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):
        pass  # no prctl (not Linux): the parent's own stop is the only way
    if os.getppid() != parent_pid:  # it died before the request took effect
        driver.request_stop("the live loop's process ended")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--job", required=True, help="JSON: config, limits, home, joint_kinds")
    parser.add_argument("--command-fd", type=int, help="the loop's segment socket (inherited)")
    parser.add_argument("--status", help="write the counters here (JSON) at the end")
    parser.add_argument(
        "--parent-pid", type=int, help="the live loop's process: its death stops the driver"
    )
    args = parser.parse_args(argv)
    job = json.loads(Path(args.job).read_text())
    config = RsiDriverConfig.from_dict(job["config"])
    commands = socket.socket(fileno=args.command_fd) if args.command_fd is not None else None
    driver = RsiDriver(config, job["limits"], job["home"], commands, job.get("joint_kinds"))
    realtime = request_realtime_priority(config.realtime_priority)
    # a stop request of either kind brakes the robot to rest before the driver ends
    signal.signal(signal.SIGTERM, lambda *_: driver.request_stop())
    signal.signal(signal.SIGINT, lambda *_: driver.request_stop())
    if args.parent_pid is not None:
        stop_with_parent(args.parent_pid, driver)
    host, port = driver.address
    # what was built leaves the garbage collector's view, as in the live loop: a full
    # collection of it would hold this SCHED_FIFO process past an RSI cycle; its own cycles
    # leave no garbage that lives (numbers in flat arrays)
    gc.collect()
    gc.freeze()
    print(f"rsi driver listening on udp://{host}:{port}", flush=True)
    try:
        summary = driver.run()
    except RsiRefused as error:
        summary = {"refused": str(error)}
        print(f"rsi driver refused: {error}", file=sys.stderr, flush=True)
    finally:
        driver.close()
    summary["realtime_priority"] = config.realtime_priority if realtime else 0
    if config.timing_path:
        atomic_write_npz(config.timing_path, driver.timing())
    if args.status:
        atomic_write_json(args.status, summary)
    return 2 if "refused" in summary else 0


if __name__ == "__main__":
    sys.exit(main())
