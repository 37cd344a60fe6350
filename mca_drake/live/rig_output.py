"""The rig's own output: every control period, the actuator positions the platform is to
reach, sent to the rig's controller over UDP or a serial port.

The positions are the platform's actuators (`actuator_positions`, in the platform's
`actuator_names` order: a serial robot's joints, rad or m; a hexapod's leg lengths, m) at
the end of the period the command has just gone out for, where the coordinates are
q + h qd + h^2 u / 2: where the platform (the analytical plant, the trajectory an RSI
robot follows) will be at the next control instant. Formats (`RigOutputConfig.format`):

    ascii     one line: the positions in SI units, comma-separated (`number_format`),
              newline-terminated: "0.012300,-0.104500,...\\n"
    template  the user's `template` with {k} replaced by actuator k's value (after
              `scale` and `offset`, written with `number_format`): "X{0}Y{1}\\n"
    binary    the values packed by the struct layout `binary_layout` ("<6i": six
              little-endian int32, rounded; "<6f": float32), for controllers that read
              counts or bits

A template is read as text with {k} placeholders only: nothing in it is evaluated.
"""

import array
import dataclasses
import os
import re
import socket
import struct
import time
from urllib.parse import parse_qs, urlparse

import numpy as np
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from mca_drake.input_checks import check_config_numbers
from mca_drake.live.endpoints import parse_endpoint
from mca_drake.live.recorder import AFTER_COMMAND_S
from mca_drake.simulation.closed_loop import step_time_summary

FORMATS = ("ascii", "template", "binary")
_PLACEHOLDER = re.compile(r"\{(\d+)\}")
# Serial speeds a rig controller may use, baud.
BAUD_RATES = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)


@dataclasses.dataclass
class RigOutputConfig:
    """Where the actuator positions go each control period, and how they are written."""

    # "udp://HOST:PORT" or "serial://PATH?baud=N" (e.g. serial:///dev/ttyUSB0?baud=115200);
    # "": no rig output.
    url: str = ""
    # "ascii", "template" or "binary" (module docstring).
    format: str = "ascii"
    # The template's text with {k} for actuator k (format template).
    template: str = ""
    # Per actuator: value = scale * position + offset (empty: 1 and 0), e.g. counts per m.
    scale: list[float] = dataclasses.field(default_factory=list)
    offset: list[float] = dataclasses.field(default_factory=list)
    # How a number is written in ascii and template: a format spec for a float (".6f";
    # ".0f" for whole counts).
    number_format: str = ".6f"
    # The struct layout of the values (format binary), e.g. "<6i" or ">6f".
    binary_layout: str = ""

    def validate(self, actuators: int) -> None:
        """Raises ValueError for an output that cannot be written for `actuators` actuators,
        naming the field."""
        check_config_numbers(self)
        if self.url:
            where(self.url)
        if self.format not in FORMATS:
            raise ValueError(f"RigOutputConfig.format must be one of {', '.join(FORMATS)}")
        for name in ("scale", "offset"):
            if getattr(self, name) and len(getattr(self, name)) != actuators:
                raise ValueError(f"RigOutputConfig.{name} needs {actuators} values (or none)")
        try:
            format(1.5, self.number_format)
        except ValueError:
            raise ValueError(
                f"RigOutputConfig.number_format {self.number_format!r} is not a format spec "
                "for a float (e.g. '.6f', '.0f')"
            ) from None
        if self.format == "template":
            used = [int(k) for k in _PLACEHOLDER.findall(self.template)]
            if not used:
                raise ValueError("RigOutputConfig.template has no {k} placeholder")
            if max(used) >= actuators:
                raise ValueError(
                    f"RigOutputConfig.template names actuator {max(used)}; the platform has "
                    f"{actuators} (0 to {actuators - 1})"
                )
        if self.format == "binary":
            try:
                fields = struct.unpack(
                    self.binary_layout, bytes(struct.calcsize(self.binary_layout))
                )
            except struct.error as error:
                raise ValueError(
                    f"RigOutputConfig.binary_layout {self.binary_layout!r}: {error}"
                ) from None
            if len(fields) != actuators:
                raise ValueError(
                    f"RigOutputConfig.binary_layout packs {len(fields)} values; the platform "
                    f"has {actuators} actuators"
                )


def where(url: str) -> tuple[str, tuple]:
    """("udp", (host, port)) or ("serial", (path, baud)) of a rig output's URL.

    Raises:
        ValueError: a URL that is neither, naming the forms it may take.
    """
    parsed = urlparse(url)
    if parsed.scheme == "udp":
        host, port = parse_endpoint(parsed.netloc, "rig output")
        if port is None:
            raise ValueError(f"rig output {url!r} needs a port: udp://HOST:PORT")
        return "udp", (host, port)
    if parsed.scheme == "serial" and parsed.path:
        baud = parse_qs(parsed.query).get("baud", ["115200"])[0]
        if not baud.isdigit() or int(baud) not in BAUD_RATES:
            raise ValueError(
                f"rig output {url!r}: baud must be one of {', '.join(map(str, BAUD_RATES))}"
            )
        return "serial", (parsed.path, int(baud))
    raise ValueError(
        f"rig output {url!r} is not udp://HOST:PORT or serial://PATH?baud=N "
        "(e.g. serial:///dev/ttyUSB0?baud=115200)"
    )


def encode(positions, config: RigOutputConfig) -> bytes:
    """The message of one period's actuator `positions` (m or rad) in `config`'s format."""
    n = len(positions)
    scale = config.scale or [1.0] * n
    offset = config.offset or [0.0] * n
    values = [s * x + o for s, x, o in zip(scale, positions, offset, strict=True)]
    if config.format == "binary":
        integers = any(c in "bBhHiIlLqQ" for c in config.binary_layout)
        return struct.pack(config.binary_layout, *(round(v) if integers else v for v in values))
    written = [format(v, config.number_format) for v in values]
    if config.format == "template":
        return _PLACEHOLDER.sub(lambda m: written[int(m.group(1))], config.template).encode()
    return (",".join(written) + "\n").encode()


class RigConnection:
    """The open UDP socket or serial port of a rig output; `send` never blocks (a message
    the port will not take now is counted in `failed`)."""

    def __init__(self, config: RigOutputConfig):
        self.kind, address = where(config.url)
        self.url = config.url
        self.sent = self.failed = 0
        # time.perf_counter() just after each message went out (sent or failed), s
        self.send_times_s = array.array("d")
        if self.kind == "udp":
            self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self._socket.setblocking(False)
            self._address = address
            self._fd = None
        else:
            path, baud = address
            try:
                self._fd = os.open(path, os.O_WRONLY | os.O_NOCTTY | os.O_NONBLOCK)
            except OSError as error:
                raise ValueError(f"cannot open the rig's serial port {path}: {error}") from None
            _set_raw(self._fd, baud)

    def send(self, message: bytes) -> None:
        """Sends one message; counts it sent or failed."""
        try:
            if self._fd is None:
                self._socket.sendto(message, self._address)
            else:
                os.write(self._fd, message)
            self.sent += 1
        except OSError:
            self.failed += 1
        self.send_times_s.append(time.perf_counter())

    def close(self) -> None:
        """Closes the socket or the port."""
        if self._fd is None:
            self._socket.close()
        else:
            os.close(self._fd)


def _set_raw(fd: int, baud: int) -> None:
    """The serial port at `baud`, 8 data bits, no parity, one stop bit, no line editing."""
    # POSIX serial ports only: where a serial output is asked for
    import termios
    import tty

    if not os.isatty(fd):
        return  # a plain file or a pipe: nothing to configure
    tty.setraw(fd)
    attributes = termios.tcgetattr(fd)
    speed = getattr(termios, f"B{baud}")
    attributes[4] = attributes[5] = speed
    termios.tcsetattr(fd, termios.TCSANOW, attributes)


def positions_at_period_end(x, u, h: float) -> np.ndarray:
    """q + h qd + h^2 u / 2 of state x = [q, qd] (2n) under acceleration u (n) for h s:
    where the platform is at the end of the period (the plant's exact step)."""
    n = len(u)
    return np.asarray(x[:n]) + h * np.asarray(x[n:]) + (0.5 * h * h) * np.asarray(u)


class RigOutputSender(LeafSystem):
    """Sends, just after each control instant's command (`AFTER_COMMAND_S`), the actuator
    positions at the period's end (those of q + h qd + h^2 u / 2) through `connection` in
    `config`'s format (module docstring).

    .. pydrake_system::

        name: RigOutputSender
        input_ports:
        - state
        - command

    `state` (2n): [q, qd] of the platform now; `command` (n): the acceleration it gets over
    the period (after the supervisor and any comfort bound). `robot`: the platform, whose
    `actuator_positions` turn coordinates into what the rig's actuators are told.
    """

    def __init__(self, connection: RigConnection, config: RigOutputConfig, period_s: float, robot):
        super().__init__()
        self._connection, self._config = connection, config
        self._h, self._robot = period_s, robot
        joints = robot.num_joints
        self._state = self.DeclareVectorInputPort("state", 2 * joints)
        self._command = self.DeclareVectorInputPort("command", joints)
        self.DeclarePeriodicPublishEvent(period_s, AFTER_COMMAND_S, self._send)

    def _send(self, context: Context) -> EventStatus:
        x, u = self._state.Eval(context), self._command.Eval(context)
        target = self._robot.actuator_positions(positions_at_period_end(x, u, self._h))
        self._connection.send(encode(target.tolist(), self._config))
        return EventStatus.Succeeded()

    def summary(self, arrivals_s=(), sample_instants=()) -> dict:
        """The summary's `rig` block: where, in what format, which actuators in what order,
        messages sent and failed, and (given each new telemetry sample's arrival,
        time.perf_counter() s, and the control instant it was first used at) the latency
        from a sample's arrival to the rig's message computed from it (median, p99, max;
        the message of instant k is the k-th sent)."""
        connection = self._connection
        sends = connection.send_times_s
        latencies = [
            sends[k] - arrival
            for arrival, k in zip(arrivals_s, sample_instants, strict=True)
            if 0 <= k < len(sends)
        ]
        return {
            "url": connection.url,
            "format": self._config.format,
            "actuators": list(self._robot.actuator_names),
            "sent": connection.sent,
            "failed": connection.failed,
            "latency_s": step_time_summary(np.asarray(latencies)) if latencies else None,
        }


__all__ = [
    "BAUD_RATES",
    "FORMATS",
    "RigConnection",
    "RigOutputConfig",
    "RigOutputSender",
    "encode",
    "positions_at_period_end",
    "where",
]
