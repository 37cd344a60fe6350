"""TelemetryReceiver: live vehicle motion from a UDP socket, as a Drake system.

Every control instant the receiver drains its non-blocking socket: each datagram is decoded
(`mca_drake.live` decoders, which also move it to the head point) and the newest sample is
held (zero-order hold: the latest sample resampled to the control period). Bad datagrams,
samples older than the one held (out of order) and gaps in the sender's sequence (dropped)
are counted, never raised; so are control periods that brought nothing new (stale periods)
and the datagrams the kernel dropped for want of room in the socket (`kernel_dropped`).

Who may move the robot is the scenario's to say: only datagrams from the senders it allows
(`ReceiverConfig.allowed_senders`, addresses with an optional port) are read; with none
named, the first sender is locked in (its address and port: `sender_ip`, `sender_port`),
whatever address the socket listens on. Datagrams from anyone else are counted (`foreign`)
and dropped unread. A locked sender silent for `sender_timeout_s` may be succeeded by
another port of the same host (a restarted simulator), counted in `sender_changes`.

The sender's clock is checked against the wall clock: a sample more than `max_time_jump_s`
ahead of where the held one's clock should be now is a fault of that packet (`time_jumps`),
never a new clock; a run of `restart_samples` consecutive samples older than the held one,
each newer than the last, is the sender's clock restarted (or a bad first sample held): the
receiver follows it (`restarts`), and the supervisor recovers as the stream is fresh again.
The held sample leaves as the reference through the same scaling as recordings
(`scaled_reference_sample`, computed once per sample at the poll and held as state, so
that reading the reference costs the MCA nothing).

The held sample's controls and vehicle state (`TelemetrySample.signals`, what the protocol
carries) leave on the `signals` port, one value per `vehicle_signals.SIGNALS` name in its
order, NaN for a signal the newest sample lacks; the live loop records them.

The poll is an unrestricted update at the control instant t_k. Drake runs an instant's
unrestricted updates before its discrete ones, so an MCA whose step is a discrete update
(`AddMca(..., update_event="discrete")`, as the live loop builds it) computes its command
from the sample polled at its own instant, in the same simulator step: nothing waits between
the poll and the MCA. An MCA with the offline default (an unrestricted step) would see the
sample one period late.
"""

from __future__ import annotations

import dataclasses
import functools
import ipaddress
import math
import socket
import time

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State

from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.input_checks import check_config_numbers
from mca_drake.live.endpoints import parse_endpoint
from mca_drake.live.socket_stamps import (
    arrival_time,
    enable_drop_counter,
    enable_kernel_timestamps,
    kernel_drops,
)
from mca_drake.live.telemetry import BadPacket, Decoder
from mca_drake.references.reference import ReferenceScaling, scaled_reference_sample
from mca_drake.references.vehicle_signals import SIGNALS

# The `signals` output of a sample that carries none.
_NO_SIGNALS = [math.nan] * len(SIGNALS)
# The `telemetry` output port, in this order.
TELEMETRY_FIELDS = (
    "age_s",  # wall-clock time since the held sample reached the socket, s (inf: none yet)
    "fresh",  # 1 while age_s <= stale_after_s, else 0
    "packets",  # datagrams received
    "bad",  # datagrams that did not decode (BadPacket)
    "out_of_order",  # samples older than the one held, ignored
    "dropped",  # samples missing from the sender's sequence (protocols with a counter)
    "stale_periods",  # control periods that brought no new sample
    "arrival_s",  # time.perf_counter() when the held sample reached the socket (NaN: none)
    "poll_s",  # time.perf_counter() of the poll that took the held sample (NaN: none)
    "foreign",  # datagrams from senders the scenario does not allow (or not the locked one)
    "time_jumps",  # samples too far ahead of the sender's clock, ignored
    "restarts",  # times the sender's clock was followed back (restart, bad first sample)
    "kernel_dropped",  # datagrams the kernel dropped: the socket's buffer was full
    "sender_ip",  # the sender read (IPv4 address as an integer; NaN: none yet)
    "sender_port",  # its UDP port (NaN: none yet)
    "sender_changes",  # a silent locked sender succeeded by another port of the same host
)
# Discrete state: the held sample, the counters and the sender's bookkeeping.
_OMEGA, _F = slice(0, 3), slice(3, 6)
_T_S, _ARRIVAL, _SEQUENCE, _PACKETS, _BAD, _OUT_OF_ORDER, _DROPPED, _STALE, _POLL = range(6, 15)
(
    _FOREIGN,
    _TIME_JUMPS,
    _RESTARTS,
    _KERNEL_DROPPED,
    _SENDER_IP,
    _SENDER_PORT,
    _SENDER_CHANGES,
    _SENDER_SEEN,  # perf_counter of the locked sender's last datagram
    _CANDIDATE_T,  # the newest of a run of samples older than the held one
    _CANDIDATES,  # how many such samples in a row
) = range(15, 25)
_STATE_SIZE = 25


# The refusal of a sample off the sender's clock (`TelemetryReceiver.last_refusal`).
_OFF_THE_CLOCK = object()


@dataclasses.dataclass
class ReceiverConfig:
    """Where to listen and how to judge the stream."""

    # Address to bind (loopback by default; "0.0.0.0" listens on every interface).
    host: str = "127.0.0.1"
    # UDP port (0: any free port, see `TelemetryReceiver.address`).
    port: int = 5500
    # No new sample for this long (s) and the telemetry counts as stale.
    stale_after_s: float = 0.1
    # At most this many datagrams are read per poll (bounds a poll's time under a flood).
    max_datagrams_per_poll: int = 256
    # The socket's receive buffer, bytes (0: the system's default). What overflows it is
    # dropped by the kernel and counted (`kernel_dropped`).
    receive_buffer_bytes: int = 0
    # Control period, s.
    time_step: float = CONTROL_PERIOD_S
    # The senders whose datagrams are read: "HOST" (any port) or "HOST:PORT", IPv4. Empty:
    # the first sender is locked in. Anyone else is counted as foreign and ignored.
    allowed_senders: list[str] = dataclasses.field(default_factory=list)
    # A locked sender silent this long (s) may be succeeded by another port of its host.
    sender_timeout_s: float = 2.0
    # A sample this far (s) ahead of where the held sample's clock should be is refused.
    max_time_jump_s: float = 1.0
    # This many consecutive, increasing samples older than the held one: the clock restarted.
    restart_samples: int = 10

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        allowed_senders(self.allowed_senders)
        if not (self.sender_timeout_s > 0 and self.max_time_jump_s > 0):
            raise ValueError("ReceiverConfig.sender_timeout_s and max_time_jump_s must be positive")
        if self.receive_buffer_bytes < 0:
            raise ValueError("ReceiverConfig.receive_buffer_bytes must be >= 0 (0: default)")
        if self.restart_samples < 2:
            raise ValueError("ReceiverConfig.restart_samples must be at least 2")
        if not 0 <= self.port <= 65535:
            raise ValueError(f"ReceiverConfig.port must be in [0, 65535]; got {self.port}")
        if not self.time_step > 0 or not self.stale_after_s > 0:
            raise ValueError("ReceiverConfig.time_step and stale_after_s must be positive")
        if self.max_datagrams_per_poll < 1:
            raise ValueError("ReceiverConfig.max_datagrams_per_poll must be at least 1")


@functools.lru_cache(maxsize=256)
def _ipv4_number(host: str) -> int | None:
    """A datagram's sender address as an integer (None: not IPv4). Cached: it is asked for
    every datagram, between the sample and its command, and parsing costs 2 us a time."""
    try:
        return int(ipaddress.IPv4Address(host))
    except ValueError:
        return None


def allowed_senders(items: list[str]) -> list[tuple[int, int | None]]:
    """[(IPv4 address as an integer, port or None)] of "HOST" / "HOST:PORT" items.

    Raises:
        ValueError: naming the item that is not an IPv4 address with an optional port.
    """
    senders = []
    for item in items:
        host, port = parse_endpoint(item, "allowed sender")
        senders.append((int(ipaddress.IPv4Address(host)), port))
    return senders


class TelemetryReceiver(LeafSystem):
    """Live telemetry as a reference (see the module docstring).

    .. pydrake_system::

        name: TelemetryReceiver
        output_ports:
        - reference
        - telemetry
        - signals

    `reference` (6): y_ref of the held sample (zero, the neutral pose, until the first one).
    `telemetry` (len(TELEMETRY_FIELDS)): the stream's health and counters.
    `signals` (len(SIGNALS)): the held sample's controls and vehicle state, SI, NaN where
    it carries none (all NaN until the first sample).

    Args:
        decoder: the protocol's decoder (it also moves samples to the head: its `LeverArm`).
        config: address, staleness and timing.

    Raises:
        ValueError: a bad setting. OSError: the address cannot be bound (in use, say).
    """

    def __init__(
        self,
        decoder: Decoder,
        config: ReceiverConfig | None = None,
    ):
        super().__init__()
        self._config = config or ReceiverConfig()
        self._config.validate()
        # the default scaling, what runs are scored against; a scenario's own scaling is
        # cued behind the guard (`systems.reference_scaling`)
        self._scaling = ReferenceScaling()
        self._decoder = decoder
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._socket.setblocking(False)
        if self._config.receive_buffer_bytes:
            self._socket.setsockopt(
                socket.SOL_SOCKET, socket.SO_RCVBUF, self._config.receive_buffer_bytes
            )
        self._socket.bind((self._config.host, self._config.port))
        self._address = self._socket.getsockname()
        # the time a datagram waited in the socket for the next poll counts in its age
        enable_kernel_timestamps(self._socket)
        enable_drop_counter(self._socket)
        self._allowed = allowed_senders(self._config.allowed_senders)
        # why the last datagram refused was refused, as the refusal path left it (worded by
        # `last_refusal` only when asked: a flood of refusals costs an assignment each)
        self._refusal: object = ""
        initial = np.zeros(_STATE_SIZE)
        initial[_F] = (0.0, 0.0, 9.81)  # level flight until a sample arrives: y_ref = 0
        initial[
            [_T_S, _ARRIVAL, _SEQUENCE, _POLL, _SENDER_IP, _SENDER_PORT, _SENDER_SEEN, _CANDIDATE_T]
        ] = np.nan
        self._state_index = self.DeclareDiscreteState(initial)
        self._reference_index = self.DeclareDiscreteState(
            scaled_reference_sample(initial[_OMEGA], initial[_F], self._scaling)
        )
        self._signals_index = self.DeclareDiscreteState(np.full(len(SIGNALS), np.nan))
        period = self._config.time_step
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._poll)
        self.DeclareStateOutputPort("reference", self._reference_index)
        # age depends on the wall clock: recomputed whenever time advances
        self.DeclareVectorOutputPort(
            "telemetry",
            len(TELEMETRY_FIELDS),
            self._calc_telemetry,
            {self.xd_ticket(), self.time_ticket()},
        )
        self.DeclareStateOutputPort("signals", self._signals_index)

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) the socket is bound to (the real port when config.port is 0)."""
        return self._address

    @property
    def allowed_senders(self) -> list[str]:
        """The senders the scenario allows ("HOST" or "HOST:PORT"); empty: the first one."""
        return list(self._config.allowed_senders)

    def fileno(self) -> int:
        """The socket's file descriptor (-1 once closed), for `select`: the live loop's pacer
        watches it to poll as soon as a datagram arrives (`mca_drake.live.pacing`)."""
        return self._socket.fileno()

    @property
    def last_refusal(self) -> str:
        """Why the last refused datagram was refused ("" if none was): the decoder's
        message, a sender not allowed, or a sample off the sender's clock; for the loop to
        tell a user whose every datagram is refused (`live.loop.first_look`)."""
        why = self._refusal
        if isinstance(why, tuple):  # (host, port) of a sender not allowed
            return (
                f"datagrams from {why[0]}:{why[1]}, not a sender the scenario allows or the "
                "one locked in"
            )
        if why is _OFF_THE_CLOCK:
            return "samples ahead of, or older than, the sender's clock (max_time_jump_s)"
        return str(why)

    @property
    def protocol(self) -> str:
        """The protocol its decoder reads (`Decoder.protocol`)."""
        return self._decoder.protocol

    def close(self) -> None:
        """Closes the socket (a closed receiver counts every later period as stale)."""
        self._socket.close()

    def counters(self, context: Context) -> dict[str, float]:
        """The `telemetry` output in `context`, by name."""
        values = self.get_output_port(1).Eval(context)
        return dict(zip(TELEMETRY_FIELDS, (float(v) for v in values), strict=True))

    def _poll(self, context: Context, state: State) -> None:
        # Python floats, one list in and one array out: numpy scalar arithmetic and checks
        # cost microseconds each, and this runs between a datagram and its command.
        x = context.get_discrete_state(self._state_index).value().tolist()
        polled = time.perf_counter()
        new_sample = False
        signals = None
        receive, decode = self._socket.recvmsg, self._decoder.decode
        for _ in range(self._config.max_datagrams_per_poll):
            try:
                packet, ancillary, _, sender = receive(65536, 128)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # closed socket
                break
            arrival = arrival_time(ancillary)
            x[_PACKETS] += 1
            drops = kernel_drops(ancillary)
            if drops is not None:
                x[_KERNEL_DROPPED] = max(x[_KERNEL_DROPPED], drops)
            if not self._from_allowed_sender(x, sender, arrival):
                x[_FOREIGN] += 1
                self._refusal = sender
                continue
            try:
                sample = decode(packet, arrival)
            except BadPacket as error:
                x[_BAD] += 1
                self._refusal = str(error)  # not the exception: its traceback holds this frame
                continue
            if not self._on_the_senders_clock(x, sample.t_s, arrival):
                self._refusal = _OFF_THE_CLOCK
                continue
            if sample.sequence is not None and math.isfinite(x[_SEQUENCE]):
                x[_DROPPED] += max(0, sample.sequence - int(x[_SEQUENCE]) - 1)
            x[_OMEGA] = sample.omega
            x[_F] = sample.f
            x[_T_S], x[_ARRIVAL], x[_POLL] = sample.t_s, arrival, polled
            x[_SEQUENCE] = math.nan if sample.sequence is None else sample.sequence
            new_sample = True
            signals = sample.signals
        discrete = state.get_mutable_discrete_state()
        if new_sample:
            y_ref = scaled_reference_sample(x[_OMEGA], x[_F], self._scaling)
            discrete.set_value(self._reference_index, np.array(y_ref))
            held = [signals.get(name, math.nan) for name in SIGNALS] if signals else _NO_SIGNALS
            discrete.set_value(self._signals_index, np.array(held))
        else:
            x[_STALE] += 1
        discrete.set_value(self._state_index, np.array(x))

    def _from_allowed_sender(self, x: list, sender: tuple, arrival: float) -> bool:
        """Whether a datagram from `sender` (host, port) is read; locks the first sender in
        when the scenario names none (state `x` updated)."""
        ip = _ipv4_number(sender[0])
        if ip is None:
            return False
        port = sender[1]
        if self._allowed:
            return any(ip == a and (p is None or p == port) for a, p in self._allowed)
        if math.isnan(x[_SENDER_IP]):  # the first sender: locked in
            x[_SENDER_IP], x[_SENDER_PORT], x[_SENDER_SEEN] = ip, port, arrival
            return True
        if ip != x[_SENDER_IP]:
            return False
        if port != x[_SENDER_PORT]:
            if arrival - x[_SENDER_SEEN] < self._config.sender_timeout_s:
                return False
            # the locked sender has been silent: its host restarted it on another port
            x[_SENDER_PORT] = port
            x[_SENDER_CHANGES] += 1
        x[_SENDER_SEEN] = arrival
        return True

    def _on_the_senders_clock(self, x: list, t_s: float, arrival: float) -> bool:
        """Whether a sample at the sender's time `t_s` is newer than the held one and on its
        clock; counts time jumps, out-of-order samples and clock restarts (state `x`)."""
        if math.isnan(x[_T_S]):
            return True
        if t_s >= x[_T_S]:
            expected = x[_T_S] + max(arrival - x[_ARRIVAL], 0.0)
            if t_s - expected > self._config.max_time_jump_s:
                x[_TIME_JUMPS] += 1
                return False
            x[_CANDIDATES], x[_CANDIDATE_T] = 0, math.nan
            return True
        # older than the held sample: out of order, or the start of a restarted clock
        if x[_CANDIDATES] and t_s > x[_CANDIDATE_T]:
            x[_CANDIDATES] += 1
        else:
            x[_CANDIDATES] = 1
        x[_CANDIDATE_T] = t_s
        if x[_CANDIDATES] >= self._config.restart_samples:
            x[_RESTARTS] += 1
            x[_CANDIDATES], x[_CANDIDATE_T] = 0, math.nan
            return True
        x[_OUT_OF_ORDER] += 1
        return False

    def _calc_telemetry(self, context: Context, output: BasicVector) -> None:
        x = context.get_discrete_state(self._state_index).value()
        arrival = x[_ARRIVAL]
        age = time.perf_counter() - arrival if np.isfinite(arrival) else np.inf
        fresh = float(age <= self._config.stale_after_s)
        output.SetFromVector(
            [
                age,
                fresh,
                x[_PACKETS],
                x[_BAD],
                x[_OUT_OF_ORDER],
                x[_DROPPED],
                x[_STALE],
                arrival,
                x[_POLL],
                x[_FOREIGN],
                x[_TIME_JUMPS],
                x[_RESTARTS],
                x[_KERNEL_DROPPED],
                x[_SENDER_IP],
                x[_SENDER_PORT],
                x[_SENDER_CHANGES],
            ]
        )
