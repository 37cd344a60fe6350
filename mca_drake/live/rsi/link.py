"""The live loop's side of the RSI link: command segments out, the driver process started.

`RsiCommandSender` is the LeafSystem that, just after every control instant's command
(`AFTER_COMMAND_S`, before the analytical plant's step), sends the segment (k, q_k, qd_k,
u_k) to the driver over a Unix datagram socket (`segment_socket_pair`): a non-blocking send,
off the path from a telemetry sample to its command. `start_rsi_driver` starts
`mca_drake.live.rsi.driver` in a process of its own, with the driver's end of the pair, and
waits until it listens; `RsiLink.stop` stops it (the driver brakes the robot to rest first)
and returns its counters.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import select
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pydrake.systems.framework import Context, EventStatus, LeafSystem

from mca_drake.live.recorder import AFTER_COMMAND_S
from mca_drake.live.rsi.driver import ROBOT_READY, RsiDriverConfig, read_lead_report
from mca_drake.live.rsi.motion import CommandSegment
from mca_drake.platforms.serial import SerialChain


def parse_robot_url(url: str) -> tuple[str, int]:
    """(host, port) of an `rsi://HOST:PORT` address (the driver listens there)."""
    prefix = "rsi://"
    if not url.startswith(prefix):
        raise ValueError(f"robot address must look like rsi://HOST:PORT; got {url!r}")
    host, sep, port = url[len(prefix) :].rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"robot address must look like rsi://HOST:PORT; got {url!r}")
    return host, int(port)


class RsiCommandSender(LeafSystem):
    """Sends every control period's command segment to the RSI driver.

    .. pydrake_system::

        name: RsiCommandSender
        input_ports:
        - state
        - command

    `state` (2n): x_k = [q, qd] of the plant the MCA controls, as the MCA read it;
    `command` (n): the joint acceleration the robot gets over the period (the supervisor's).

    Args:
        commands: the loop's end of the segment socket pair (datagrams).
        period_s: the control period h, s.
        joints: the platform's joint count n.
    """

    def __init__(self, commands: socket.socket, period_s: float, joints: int):
        super().__init__()
        self._commands = commands
        self._commands.setblocking(False)
        self._period = period_s
        self._joints = joints
        self._state = self.DeclareVectorInputPort("state", 2 * joints)
        self._command = self.DeclareVectorInputPort("command", joints)
        self.DeclarePeriodicPublishEvent(period_s, AFTER_COMMAND_S, self._send)
        self.sent = 0
        self.unsent = 0  # segments the socket would not take (the driver gone or stalled)

    def finish(self, context: Context) -> None:
        """Sends the end-of-run segment: the plant's state now, no acceleration; the driver
        brakes to rest from there."""
        x = self._state.Eval(context).tolist()
        k = round(context.get_time() / self._period)
        n = self._joints
        self._emit(CommandSegment(k, x[:n], x[n:], [0.0] * n, True))

    def _send(self, context: Context) -> EventStatus:
        x = self._state.Eval(context).tolist()
        u = self._command.Eval(context).tolist()
        k = round(context.get_time() / self._period)
        self._emit(CommandSegment(k, x[: self._joints], x[self._joints :], u))
        return EventStatus.Succeeded()

    def _emit(self, segment: CommandSegment) -> None:
        try:
            self._commands.send(segment.pack())
            self.sent += 1
        except OSError:  # full (a stalled driver) or closed (a dead one): it brakes by itself
            self.unsent += 1


@dataclasses.dataclass
class RsiLink:
    """A running driver process and the address it listens on for the robot."""

    process: subprocess.Popen
    address: tuple[str, int]
    status_path: Path

    def stop(self, timeout_s: float = 30.0) -> dict:
        """Asks the driver to brake to rest and end (SIGTERM), waits for it and returns its
        counters (`rsi.driver.DRIVER_COUNTERS` and figures; {"refused": why} if it never
        moved the robot)."""
        if self.process.poll() is None:
            self.process.terminate()
        try:
            self.process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        try:
            if self.status_path.exists():
                return json.loads(self.status_path.read_text())
            return {"error": f"the RSI driver ended with code {self.process.returncode}, no status"}
        finally:
            # the job and status files live in a folder of their own: nothing is left behind
            shutil.rmtree(self.status_path.parent, ignore_errors=True)

    def stop_and_say_why(self) -> str:
        """`stop`, and why the driver ended: its refusal, its error, or its counters."""
        status = self.stop()
        return str(status.get("refused") or status.get("error") or status)


class RobotClockServo:
    """Makes the live loop's clock follow the robot controller's.

    The driver plays the loop's trajectory on the controller's clock (IPOC) a fixed delay
    behind the loop's newest segment; the loop's instants follow the PC's clock. Two
    crystals differ by parts per million, so the driver's lead (how far the held trajectory
    reaches beyond the time it plays) drifts: 50 ppm would use up a 25 ms delay in about 8
    minutes and brake the robot. The driver reports its mean lead every 0.6 s
    (`rsi.driver.LEAD_REPORT`); this servo trims the pacer's rate (`RealTimePacer.rate_trim`,
    at most `max_trim`) with a proportional-integral law that holds the lead, less the
    phase lock's own shifts of the loop (`pacer.phase_s`, which move the lead by design),
    where it was at the first report. Trimming the rate moves no trajectory: the plant and
    the driver integrate the same segments; only their wall-clock times change.

    Args:
        loop_end: the loop's end of the segment socket (the driver's reports arrive there).
        pacer: the live loop's `RealTimePacer`.
        time_constant_s: how fast the lead is brought back (s; damping 0.7).
        max_trim: the largest rate trim, dimensionless (1e-3: 1000 ppm).
        clock: the monotonic clock the reports are timed with (s).
    """

    def __init__(
        self,
        loop_end: socket.socket,
        pacer,
        time_constant_s: float = 5.0,
        max_trim: float = 1e-3,
        clock=time.monotonic,
    ):
        if not (time_constant_s > 0 and 0 < max_trim < 0.1):
            raise ValueError("RobotClockServo needs time_constant_s > 0 and 0 < max_trim < 0.1")
        self._socket, self._pacer = loop_end, pacer
        omega = 1.0 / time_constant_s
        self._kp, self._ki = 1.4 * omega, omega * omega  # damping 0.7
        self._max_trim = max_trim
        self._clock = clock
        self._target: float | None = None
        self._integral = 0.0
        self._last: float | None = None  # monotonic time of the last report used
        self.reports: list[tuple[float, float, float]] = []  # (time, lead error s, trim)

    def update(self) -> None:
        """Reads the driver's reports that came since the last call and trims the rate."""
        lead = None
        while True:
            try:
                message = self._socket.recv(256)
            except (BlockingIOError, OSError):
                break
            report = read_lead_report(message)
            if report is not None:
                lead = report  # the newest counts
        if lead is None or not math.isfinite(lead):
            return
        now = self._clock()
        corrected = lead - self._pacer.phase_s
        if self._target is None:
            self._target, self._last = corrected, now
            return
        error = corrected - self._target  # > 0: the robot runs slow against the loop
        dt = now - self._last
        self._last = now
        # the loop slows (trim > 0) when the lead grows: its segments come later
        self._integral = min(
            max(self._integral + self._ki * error * dt, -self._max_trim), self._max_trim
        )
        trim = min(max(self._kp * error + self._integral, -self._max_trim), self._max_trim)
        self._pacer.rate_trim = trim
        self.reports.append((now, error, trim))


def wait_for_robot(loop_end: socket.socket, link: RsiLink, timeout_s: float) -> None:
    """Waits until the driver reports the robot's first state at the home pose
    (`rsi.driver.ROBOT_READY` on the segment socket): the loop starts only then, so the
    robot follows it from its first period. RuntimeError if the driver ends first (it
    refused the robot: the message says why) or `timeout_s` passes."""
    deadline = time.monotonic() + timeout_s
    while (left := deadline - time.monotonic()) > 0:
        if select.select([loop_end], [], [], min(left, 0.2))[0]:
            if loop_end.recv(256) == ROBOT_READY:
                return
        if link.process.poll() is not None:
            raise RuntimeError(
                f"the RSI driver ended before the robot was ready: {link.stop_and_say_why()}"
            )
    raise RuntimeError(
        f"no RSI robot at rsi://{link.address[0]}:{link.address[1]} within {timeout_s:g} s: "
        "start the RSI program on the controller (its state packets must reach this address)"
    )


def segment_socket_pair() -> tuple[socket.socket, socket.socket]:
    """(the loop's end, the driver's end) of a new segment socket pair (Unix datagrams)."""
    return socket.socketpair(socket.AF_UNIX, socket.SOCK_DGRAM)


def start_rsi_driver(
    config: RsiDriverConfig, robot: SerialChain, home, driver_end: socket.socket
) -> RsiLink:
    """Starts `python -m mca_drake.live.rsi.driver` listening on config's address, with
    `driver_end` of a `segment_socket_pair` (closed here once the driver has it), and waits
    until it listens (its `listening` line); raises RuntimeError if it ends first (an
    address in use, a bad setting: its own error output says which). Its error output goes
    to ours, never into a pipe that could fill and stall it."""
    config.validate()
    folder = Path(tempfile.mkdtemp(prefix="mca_drake_rsi_"))
    job = {
        "config": config.to_dict(),
        "limits": [v.tolist() for v in (robot.q_min, robot.q_max, robot.qd_max, robot.qdd_max)],
        "home": [float(v) for v in home],
        "joint_kinds": list(robot.joint_kinds),
    }
    (folder / "job.json").write_text(json.dumps(job))
    status = folder / "status.json"
    theirs = driver_end
    command = [
        sys.executable,
        "-m",
        "mca_drake.live.rsi.driver",
        "--job",
        str(folder / "job.json"),
        "--command-fd",
        str(theirs.fileno()),
        "--status",
        str(status),
        # the driver brakes and ends if this process dies, however it dies
        "--parent-pid",
        str(os.getpid()),
    ]
    process = subprocess.Popen(
        command,
        pass_fds=(theirs.fileno(),),
        stdout=subprocess.PIPE,
        text=True,
        # its own session: a Ctrl-C at the terminal reaches the loop, whose `stop` then
        # asks the driver to brake; a killed loop leaves the driver braking on its own
        start_new_session=True,
    )
    theirs.close()
    line = process.stdout.readline() if process.stdout else ""  # "" when it ended
    if "listening on udp://" not in line:
        process.kill()
        process.wait()
        shutil.rmtree(folder, ignore_errors=True)
        raise RuntimeError(f"the RSI driver did not start (its error output above): {line!r}")
    host, _, port = line.strip().rpartition("udp://")[2].rpartition(":")
    return RsiLink(process, (host, int(port)), status)
