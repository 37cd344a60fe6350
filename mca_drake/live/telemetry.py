"""Decoded telemetry: the head-frame sample every protocol decoder returns, and the base they share.

A `TelemetrySample` is one instant of vehicle motion in the recording conventions
(`mca_drake.references.recording`): angular velocity omega (rad/s) and specific force f (m/s^2)
in head axes (x forward, y left, z up), level and unaccelerated flight reading
f = (0, 0, +9.81). A `Decoder` turns one datagram into one sample, or raises `BadPacket` with
a message that says what is wrong: size, version or magic, garbage, non-finite or implausible
values. Whatever the bytes, `decode` raises nothing else.

The point a protocol describes (the vehicle's centre of gravity, or a simulator's pilot point)
need not be the occupant's head. `LeverArm` says where the head is relative to that point, and
the decoder moves the specific force there with the rigid-body relation

    f_H = f_S + alpha x p_SH + omega x (omega x p_SH)

(angular velocity is the same everywhere on a rigid body, so omega needs no transfer). No
decoded protocol carries the angular acceleration alpha: it is the backward finite difference
of successive samples' omega (half a sample late), or zero (`LeverArm.angular_acceleration`).
"""

from __future__ import annotations

import abc
import dataclasses
import math
import time
from typing import ClassVar

import numpy as np

from mca_drake.input_checks import check_config_numbers
from mca_drake.references.recording import MAX_SPECIFIC_FORCE

# Largest plausible angular rate, rad/s (about 2000 deg/s, the full scale of common MEMS
# gyros and far beyond any crewed vehicle): a larger decoded rate is garbage or a unit error.
MAX_ANGULAR_RATE = 35.0

# Where a sample's time comes from.
TIME_SOURCES = ("sender", "arrival")

# How `LeverArm` estimates the angular acceleration that no protocol sends.
ANGULAR_ACCELERATION_ESTIMATES = ("finite_difference", "zero")


class BadPacket(ValueError):  # noqa: N818 (a packet, not an error class: reads as "raise BadPacket")
    """A datagram that does not decode to a usable sample; the message says why."""


Vector3 = tuple[float, float, float]


def _vector3(name: str, value) -> Vector3:
    """`value` as a tuple of three finite Python floats; ValueError naming `name` if not."""
    try:
        vector = tuple(map(float, value))
    except TypeError as error:
        raise ValueError(f"telemetry sample {name} must hold 3 numbers; got {value!r}") from error
    if len(vector) != 3:
        raise ValueError(f"telemetry sample {name} must have shape (3,); got {len(vector)} values")
    if not all(map(math.isfinite, vector)):
        raise ValueError(f"telemetry sample {name} has non-finite values: {vector}")
    return vector


@dataclasses.dataclass(frozen=True, eq=False)
class TelemetrySample:
    """One decoded instant of vehicle motion at the head, head axes, SI units.

    Attributes:
        t_s: time of the sample, s: the sender's clock where the protocol carries one,
            else the receiver's arrival time (`time_source` says which).
        omega: angular velocity, rad/s, 3 floats, head axes (x forward, y left, z up).
        f: specific force, m/s^2, 3 floats, head axes (level flight: (0, 0, +9.81)).
        sequence: the packet's sequence or frame counter, None where the protocol has none.
        time_source: "sender" or "arrival".
        signals: the controls and vehicle state the packet carries, SI, by their
            `mca_drake.references.vehicle_signals` names ({"aileron": 0.1, "speed": 51.4});
            empty where the protocol carries none.

    omega and f are tuples of Python floats (immutable; `np.asarray` makes arrays): a
    sample is built for every datagram between its arrival and the command, where two numpy
    arrays and their checks cost a tenth of the live loop's latency budget on a cold core.
    Raises ValueError for a wrong length or a non-finite value.
    """

    t_s: float
    omega: Vector3
    f: Vector3
    sequence: int | None = None
    time_source: str = "sender"
    signals: dict[str, float] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        t_s = float(self.t_s)
        if not math.isfinite(t_s):
            raise ValueError(f"telemetry sample time must be finite; got {self.t_s}")
        object.__setattr__(self, "t_s", t_s)
        object.__setattr__(self, "omega", _vector3("omega", self.omega))
        object.__setattr__(self, "f", _vector3("f", self.f))
        if self.sequence is not None:
            object.__setattr__(self, "sequence", int(self.sequence))
        if self.time_source not in TIME_SOURCES:
            raise ValueError(
                f"unknown time_source '{self.time_source}'; valid: {', '.join(TIME_SOURCES)}"
            )


def check_plausible(sample: TelemetrySample, where: str) -> None:
    """Raises BadPacket if `sample` holds values no vehicle produces (garbage or wrong units):
    a specific-force component beyond `MAX_SPECIFIC_FORCE` (20 g) or an angular rate beyond
    `MAX_ANGULAR_RATE`. `where` starts the message (protocol and point)."""
    if max(map(abs, sample.f)) > MAX_SPECIFIC_FORCE:
        raise BadPacket(
            f"{where}: specific force {[round(v, 3) for v in sample.f]} m/s^2 exceeds "
            f"{MAX_SPECIFIC_FORCE:g} m/s^2 (20 g): garbage, or a field in the wrong units"
        )
    if max(map(abs, sample.omega)) > MAX_ANGULAR_RATE:
        raise BadPacket(
            f"{where}: angular velocity {[round(v, 3) for v in sample.omega]} rad/s exceeds "
            f"{MAX_ANGULAR_RATE:g} rad/s: garbage, or a rate in deg/s read as rad/s"
        )


@dataclasses.dataclass
class LeverArm:
    """Where the occupant's head is relative to the point the telemetry describes.

    The default (zero offset) takes the protocol's point as the head: right for JSBSim's
    FlightGear output, whose accelerations are at the pilot's eye point. Protocols that
    report centre-of-gravity quantities (X-Plane's load factors) need the head's offset.
    """

    # Position of the head H relative to the telemetry's point S (centre of gravity or pilot
    # point), in head axes (x forward, y left, z up), m.
    p_SH_H: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])
    # Estimate of the angular acceleration in alpha x p_SH: "finite_difference" of successive
    # samples' omega (backward difference: half a sample late, and it amplifies rate noise),
    # or "zero" (steady rotation only: the centripetal term alone).
    angular_acceleration: str = "finite_difference"
    # Samples closer than this (s) arrived bunched: the previous alpha estimate is kept.
    min_difference_dt_s: float = 0.002
    # Samples farther apart than this (s: a drop-out or a restart) give alpha = 0.
    max_difference_dt_s: float = 0.1

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        if len(self.p_SH_H) != 3:
            raise ValueError(f"LeverArm.p_SH_H must hold 3 numbers (m); got {self.p_SH_H}")
        if self.angular_acceleration not in ANGULAR_ACCELERATION_ESTIMATES:
            raise ValueError(
                f"unknown LeverArm.angular_acceleration '{self.angular_acceleration}'; valid: "
                f"{', '.join(ANGULAR_ACCELERATION_ESTIMATES)}"
            )
        if not 0.0 < self.min_difference_dt_s < self.max_difference_dt_s:
            raise ValueError(
                "LeverArm needs 0 < min_difference_dt_s < max_difference_dt_s; got "
                f"{self.min_difference_dt_s} and {self.max_difference_dt_s}"
            )


def specific_force_at(
    f_S: np.ndarray, omega: np.ndarray, alpha: np.ndarray, p_SH: np.ndarray
) -> np.ndarray:
    """Specific force at H of a rigid body, from the one at S: f_S + alpha x p_SH +
    omega x (omega x p_SH). All shape (3,), in one set of body-fixed axes; f in m/s^2, omega
    rad/s, alpha rad/s^2, p_SH m. Gravity is the same at both points, so it cancels."""
    return f_S + np.cross(alpha, p_SH) + np.cross(omega, np.cross(omega, p_SH))


class HeadPointTransfer:
    """Moves decoded samples from the telemetry's point to the head (`LeverArm`), keeping the
    previous sample of the stream for the finite-difference angular acceleration.

    Args:
        lever_arm: the head's offset and the angular-acceleration estimate (validated here).
    """

    def __init__(self, lever_arm: LeverArm) -> None:
        lever_arm.validate()
        self.lever_arm = lever_arm
        self._p_SH = np.array(lever_arm.p_SH_H, dtype=np.float64)
        self._active = bool(np.any(self._p_SH != 0.0))
        self._previous: tuple[float, Vector3] | None = None  # t_s, omega of the last sample
        self._alpha = np.zeros(3)

    def reset(self) -> None:
        """Forgets the stream's history (a new stream or a restart of the sender)."""
        self._previous = None
        self._alpha = np.zeros(3)

    def angular_acceleration(self, sample: TelemetrySample) -> np.ndarray:
        """The alpha estimate at `sample` (rad/s^2, shape (3,)); updates the history."""
        arm = self.lever_arm
        if arm.angular_acceleration == "zero":
            return np.zeros(3)
        if self._previous is None:
            self._alpha = np.zeros(3)
        else:
            t_previous, omega_previous = self._previous
            dt = sample.t_s - t_previous
            if arm.min_difference_dt_s <= dt <= arm.max_difference_dt_s:
                self._alpha = (np.asarray(sample.omega) - omega_previous) / dt
            elif not 0.0 <= dt < arm.min_difference_dt_s:
                # A gap, or time going back (a restart): no rate history to difference.
                self._alpha = np.zeros(3)
            # else: bunched arrivals, keep the last estimate rather than divide by ~0.
        self._previous = (sample.t_s, sample.omega)
        return self._alpha

    def apply(self, sample: TelemetrySample) -> TelemetrySample:
        """`sample` with its specific force moved to the head (unchanged for a zero offset)."""
        if not self._active:
            return sample
        alpha = self.angular_acceleration(sample)
        f_H = specific_force_at(np.asarray(sample.f), np.asarray(sample.omega), alpha, self._p_SH)
        return dataclasses.replace(sample, f=f_H)


class Decoder(abc.ABC):
    """Turns one telemetry datagram into a head-frame `TelemetrySample`.

    A decoder serves one stream: with a lever arm and the finite-difference angular
    acceleration it remembers the previous sample (`reset` forgets it).

    Args:
        lever_arm: where the head is relative to the point the protocol describes
            (None: `LeverArm()`, the protocol's point is the head).
    """

    # The protocol's name as the live summary reports it.
    protocol: ClassVar[str]
    # What kind of vehicle the protocol's senders are: "car" for a racing simulator's, ""
    # where the protocol does not say (flight simulators fly many kinds). The DPC picks its
    # policy by it (`mca_drake.cueing.dpc.vehicle_policy_name`).
    vehicle: ClassVar[str] = ""
    # The largest datagram the protocol sends, bytes: a larger one is refused unread.
    max_datagram_bytes: ClassVar[int]

    def __init__(self, *, lever_arm: LeverArm | None = None) -> None:
        self._transfer = HeadPointTransfer(lever_arm or LeverArm())

    @property
    def lever_arm(self) -> LeverArm:
        """The head's offset from the protocol's point."""
        return self._transfer.lever_arm

    def reset(self) -> None:
        """Forgets the stream's history (the previous sample of the angular acceleration)."""
        self._transfer.reset()

    def decode(self, packet: bytes, received_s: float | None = None) -> TelemetrySample:
        """The head-frame sample in `packet`.

        Args:
            packet: one datagram's bytes.
            received_s: arrival time on the receiver's clock, s; the sample's time for
                protocols without a sender time (None: `time.monotonic()` now).

        Raises:
            BadPacket: wrong size, version or magic, garbage, missing data, non-finite or
                implausible values; the message names the protocol and the cause.
            ValueError: `received_s` is not a finite number (a caller's error, not the
                packet's).
        """
        if not isinstance(packet, bytes | bytearray | memoryview):
            raise BadPacket(f"{self.protocol} packet must be bytes; got {type(packet).__name__}")
        if len(packet) > self.max_datagram_bytes:
            raise BadPacket(
                f"{self.protocol} packet of {len(packet)} bytes; the protocol's are at most "
                f"{self.max_datagram_bytes} bytes"
            )
        if received_s is None:
            received_s = time.monotonic()
        received_s = float(received_s)
        if not math.isfinite(received_s):
            raise ValueError(f"received_s must be a finite time in s; got {received_s}")
        try:
            at_source = self._decode_at_source(bytes(packet), received_s)
        except BadPacket:
            raise
        except (ValueError, ArithmeticError, IndexError, UnicodeError) as error:
            # struct.error is a ValueError too: whatever the bytes, callers see BadPacket only.
            raise BadPacket(f"{self.protocol} packet does not decode: {error}") from error
        check_plausible(at_source, f"{self.protocol} packet")
        sample = self._transfer.apply(at_source)
        if sample is not at_source:
            check_plausible(sample, f"{self.protocol} packet moved to the head")
        return sample

    @abc.abstractmethod
    def _decode_at_source(self, packet: bytes, received_s: float) -> TelemetrySample:
        """The sample at the protocol's own point (head axes, SI), before the lever arm."""
