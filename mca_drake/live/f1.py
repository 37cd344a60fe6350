"""The EA Sports / Codemasters F1 games' UDP telemetry: the Motion and Motion Ex packets of
the F1 23 and F1 24 formats.

Sources: EA's "F1 24 UDP Specification" (https://answers.ea.com/t5/General-Discussion/
F1-24-UDP-Specification/td-p/13745220) and "F1 23 UDP Specification"
(https://answers.ea.com/t5/General-Discussion/F1-23-UDP-Specification/td-p/12632888), as
reproduced with their coordinate-system figures in GitHub MacManley/f1-24-udp, README.md.
All values little-endian, packed (no padding).

Header, 29 bytes, on every packet:

    offset  field                       type
    0       m_packetFormat              uint16   2023 or 2024 (the game's "UDP Format")
    2       m_gameYear                  uint8
    3       m_gameMajorVersion          uint8
    4       m_gameMinorVersion          uint8
    5       m_packetVersion             uint8    1 for both packets read here
    6       m_packetId                  uint8    0 Motion, 13 Motion Ex (others: refused)
    7       m_sessionUID                uint64
    15      m_sessionTime               float32  s, the sample's time
    19      m_frameIdentifier           uint32
    23      m_overallFrameIdentifier    uint32
    27      m_playerCarIndex            uint8    0 ... 21
    28      m_secondaryPlayerCarIndex   uint8

Motion (id 0), 1349 bytes: the header, then 22 CarMotionData of 60 bytes; the player's is at
29 + 60 * m_playerCarIndex:

    +0   m_worldPosition{X,Y,Z}        3 float32  m
    +12  m_worldVelocity{X,Y,Z}        3 float32  m/s
    +24  m_worldForwardDir{X,Y,Z}      3 int16    / 32767
    +30  m_worldRightDir{X,Y,Z}        3 int16    / 32767
    +36  m_gForceLateral               float32    g
    +40  m_gForceLongitudinal          float32    g
    +44  m_gForceVertical              float32    g
    +48  m_yaw, m_pitch, m_roll        3 float32  rad

Motion Ex (id 13), player car only, 217 bytes (F1 23) or 237 (F1 24): after the header,
eight wheel arrays of 4 float32 (128 bytes) and m_heightOfCOGAboveGround, then
m_localVelocity{X,Y,Z} (offset 161), m_angularVelocity{X,Y,Z} (offset 173, rad/s, local
axes), m_angularAcceleration{X,Y,Z}, m_frontWheelsAngle, m_wheelVertForce[4]; F1 24 adds the
plank heights, suspension roll angles and chassis yaw.

The Motion packet carries no angular velocity in these formats, the Motion Ex packet no
specific force: the decoder keeps the newest of each and returns a sample for either packet
once it holds the other part, from the same session and within `F1Config.pairing_window_s`
of session time (the game sends both on the same frame). Until then a packet is refused.

Conversion to head axes (x forward, y left, z up), g = 9.81 m/s^2. The specification names
the components but gives no sign for them; the defaults (each switchable in `F1Config`):

- the g-forces are the specific force in g: longitudinal positive accelerating, lateral
  positive towards the left (a left turn), vertical positive up, +1 g at rest:
  f = g (longitudinal, lateral, vertical). A level car at rest reads f = (0, 0, +9.81);
- the local axes of the angular velocity follow the specification's figures: y up (yaw),
  z forward (roll), x the pitch axis; with the world's axes (x, y up, z) drawn right-handed,
  x is left and the rates follow the right-hand rule: omega = (w_z, w_x, w_y). For
  left-handed local axes (x right) the roll and yaw rates change sign.

Car Telemetry (id 6), 1352 bytes in both formats: the header, 22 CarTelemetryData of 60
bytes (the player's at 29 + 60 * m_playerCarIndex), then three bytes of MFD state. The
decoder reads the first four fields of the player's:

    +0   m_speed                       uint16     km/h
    +2   m_throttle                    float32    0 ... 1
    +6   m_steer                       float32    -1 (full lock left) ... 1 (full lock right)
    +10  m_brake                       float32    0 ... 1

and holds them as the signals (`mca_drake.references.vehicle_signals`: `speed` in m/s,
`throttle`, `brake`, `steering` = -m_steer, positive left) of the samples that follow from
the same session within `pairing_window_s`; the packet itself gives no sample (it counts as
refused). A value that is not finite or outside its range is left out.

The guide (docs/guides/driving.md, "Racing simulators") says how to check the signs once.
Positions, velocities, direction vectors and angles are not used. The values are at the
car's reference point: give the head's offset in a `LeverArm`.
"""

# No `from __future__ import annotations`: LiveScenario's YAML loader reads the config's
# field types, which must be type objects.
import dataclasses
import math
import struct

from mca_drake.conventions import GRAVITY
from mca_drake.live.telemetry import (
    MAX_ANGULAR_RATE,
    BadPacket,
    Decoder,
    LeverArm,
    TelemetrySample,
)
from mca_drake.references.recording import MAX_SPECIFIC_FORCE
from mca_drake.references.vehicle_signals import signal_factor, within_bounds

F1_PACKET_FORMATS = (2023, 2024)
F1_HEADER = struct.Struct("<HBBBBBQfIIBB")
assert F1_HEADER.size == 29
MOTION_ID = 0
MOTION_EX_ID = 13
F1_PACKET_VERSION = 1
F1_CARS = 22
CAR_MOTION = struct.Struct("<6f6h6f")
assert CAR_MOTION.size == 60
MOTION_SIZE = F1_HEADER.size + F1_CARS * CAR_MOTION.size  # 1349
MOTION_EX_SIZES = {2023: 217, 2024: 237}
CAR_TELEMETRY_ID = 6
# m_speed, m_throttle, m_steer, m_brake: the start of the 60-byte CarTelemetryData
CAR_CONTROLS = struct.Struct("<H3f")
CAR_TELEMETRY_DATA_SIZE = 60
CAR_TELEMETRY_SIZE = F1_HEADER.size + F1_CARS * CAR_TELEMETRY_DATA_SIZE + 3  # 1352
# Offset of m_angularVelocityX in the Motion Ex packet: header, 8 x 4 wheel floats,
# m_heightOfCOGAboveGround, m_localVelocity[3].
ANGULAR_VELOCITY_AT = F1_HEADER.size + 4 * (32 + 1 + 3)
_VECTOR = struct.Struct("<3f")
# Names of the packet ids the games send, for messages.
PACKET_NAMES = {
    0: "Motion",
    1: "Session",
    2: "Lap Data",
    3: "Event",
    4: "Participants",
    5: "Car Setups",
    6: "Car Telemetry",
    7: "Car Status",
    8: "Final Classification",
    9: "Lobby Info",
    10: "Car Damage",
    11: "Session History",
    12: "Tyre Sets",
    13: "Motion Ex",
    14: "Time Trial",
}
# Larger than any packet the games send (Session History is 1460 bytes in F1 24): the
# others are refused by their id, with a message that names them.
F1_MAX_DATAGRAM = 2048


@dataclasses.dataclass
class F1Config:
    """The F1 game's UDP format and the sign conventions of its motion values."""

    # The game's "UDP Format" setting: 2023 (F1 23, or F1 24 set to it) or 2024 (F1 24).
    packet_format: int = 2024
    # m_gForceLateral is positive towards the car's left (else its right).
    lateral_positive_left: bool = True
    # m_gForceLongitudinal is positive accelerating forward (else braking).
    longitudinal_positive_forward: bool = True
    # m_gForceVertical is positive up, +1 g at rest (else down, -1 g at rest).
    vertical_positive_up: bool = True
    # Motion Ex's local axes are right-handed (x left, y up, z forward; rates by the
    # right-hand rule); false: left-handed (x right), which flips the roll and yaw rates.
    local_axes_right_handed: bool = True
    # The Motion and Motion Ex parts of a sample must be this close in session time, s.
    pairing_window_s: float = 0.1

    def validate(self) -> None:
        """Raises ValueError for a setting the decoder cannot use, naming it."""
        if self.packet_format not in F1_PACKET_FORMATS:
            raise ValueError(
                f"unknown F1Config.packet_format {self.packet_format!r}; valid: "
                f"{', '.join(map(str, F1_PACKET_FORMATS))} (the game's UDP Format setting)"
            )
        for name in (
            "lateral_positive_left",
            "longitudinal_positive_forward",
            "vertical_positive_up",
            "local_axes_right_handed",
        ):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"F1Config.{name} must be true or false; got {getattr(self, name)!r}"
                )
        window = self.pairing_window_s
        if isinstance(window, bool) or not isinstance(window, int | float) or not 0 < window <= 1:
            raise ValueError(f"F1Config.pairing_window_s must be in (0, 1] s; got {window!r}")


def _sign(positive: bool) -> float:
    return 1.0 if positive else -1.0


class F1Decoder(Decoder):
    """Decodes the F1 games' Motion (id 0) and Motion Ex (id 13) packets into head-frame
    samples of the player's car, with the speed and controls of its Car Telemetry (id 6)
    packets as their signals (module docstring: layouts, pairing, signs). The sample time
    is the header's session time.

    Args:
        config: UDP format and signs (None: `F1Config()`, format 2024).
        lever_arm: where the head is relative to the car's reference point.
    """

    protocol = "f1"
    vehicle = "car"
    max_datagram_bytes = F1_MAX_DATAGRAM

    def __init__(
        self, *, config: F1Config | None = None, lever_arm: LeverArm | None = None
    ) -> None:
        self.config = config or F1Config()
        self.config.validate()
        c = self.config
        self._g_signs = (
            GRAVITY * _sign(c.longitudinal_positive_forward),
            GRAVITY * _sign(c.lateral_positive_left),
            GRAVITY * _sign(c.vertical_positive_up),
        )
        self._roll_yaw_sign = _sign(c.local_axes_right_handed)
        self._motion_ex_size = MOTION_EX_SIZES[c.packet_format]
        # The newest part of each kind: (session UID, session time, vector in head axes).
        self._f: tuple[int, float, tuple[float, float, float]] | None = None
        self._omega: tuple[int, float, tuple[float, float, float]] | None = None
        # The newest controls: (session UID, session time, signals).
        self._controls: tuple[int, float, dict[str, float]] | None = None
        super().__init__(lever_arm=lever_arm)

    def reset(self) -> None:
        """Forgets the stream's history: the held parts and the lever arm's last sample."""
        super().reset()
        self._f = self._omega = self._controls = None

    def _decode_at_source(self, packet: bytes, received_s: float) -> TelemetrySample:
        if len(packet) < F1_HEADER.size:
            raise BadPacket(
                f"f1 packet of {len(packet)} bytes is shorter than the {F1_HEADER.size}-byte header"
            )
        packet_format, _, _, _, version, packet_id, session, t_s, _, _, player, _ = (
            F1_HEADER.unpack_from(packet)
        )
        expected = self.config.packet_format
        if packet_format != expected:
            raise BadPacket(
                f"f1 packet has format {packet_format}; the decoder reads {expected}: set the "
                f"game's UDP Format to {expected}, or F1Config.packet_format (--f1-format)"
            )
        if packet_id not in (MOTION_ID, MOTION_EX_ID, CAR_TELEMETRY_ID):
            name = PACKET_NAMES.get(packet_id, "unknown")
            raise BadPacket(
                f"f1 packet id {packet_id} ({name}); the decoder reads Motion (0), Motion Ex "
                "(13) and Car Telemetry (6) only"
            )
        size = {MOTION_ID: MOTION_SIZE, CAR_TELEMETRY_ID: CAR_TELEMETRY_SIZE}.get(
            packet_id, self._motion_ex_size
        )
        if len(packet) != size:
            raise BadPacket(
                f"f1 {PACKET_NAMES[packet_id]} packet of {len(packet)} bytes; format "
                f"{expected} sends {size}"
            )
        if version != F1_PACKET_VERSION:
            raise BadPacket(
                f"f1 {PACKET_NAMES[packet_id]} packet version {version}; the {expected} "
                f"specification's is {F1_PACKET_VERSION}"
            )
        if not math.isfinite(t_s):
            raise BadPacket(f"f1 packet has session time {t_s}")
        if packet_id == CAR_TELEMETRY_ID:
            self._controls = (session, t_s, self._player_controls(packet, player))
            raise BadPacket("f1 Car Telemetry packet: its controls ride on the motion samples")
        if packet_id == MOTION_ID:
            self._f = (session, t_s, self._player_specific_force(packet, player))
        else:
            self._omega = (session, t_s, self._angular_velocity(packet))
        other = self._omega if packet_id == MOTION_ID else self._f
        missing = "Motion Ex (13)" if packet_id == MOTION_ID else "Motion (0)"
        if other is None:
            raise BadPacket(f"f1 packet waits for a {missing} packet to pair with")
        if other[0] != session or abs(other[1] - t_s) > self.config.pairing_window_s:
            raise BadPacket(
                f"f1 packet at session time {t_s:.3f} s has no {missing} packet of its session "
                f"within {self.config.pairing_window_s} s (the newest is at {other[1]:.3f} s): "
                "the game sends both each frame"
            )
        controls = self._controls
        signals = {}
        if controls and controls[0] == session:
            if abs(controls[1] - t_s) <= self.config.pairing_window_s:
                signals = dict(controls[2])
        return TelemetrySample(
            t_s, self._omega[2], self._f[2], time_source="sender", signals=signals
        )

    def _player_controls(self, packet: bytes, player: int) -> dict[str, float]:
        """The player's speed and controls in a Car Telemetry packet, as signals (module
        docstring); a value that is not finite or outside its range is left out."""
        if player >= F1_CARS:
            raise BadPacket(f"f1 Car Telemetry packet has player car index {player}")
        at = F1_HEADER.size + CAR_TELEMETRY_DATA_SIZE * player
        speed, throttle, steer, brake = CAR_CONTROLS.unpack_from(packet, at)
        values = {
            "speed": speed * signal_factor("speed", "km/h"),
            "throttle": throttle,
            "steering": -steer + 0.0,  # ISO 8855: positive turns left; + 0.0: no -0.0
            "brake": brake,
        }
        return {
            name: value
            for name, value in values.items()
            if math.isfinite(value) and within_bounds(name, value)
        }

    def _player_specific_force(self, packet: bytes, player: int) -> tuple[float, float, float]:
        if player >= F1_CARS:
            raise BadPacket(
                f"f1 Motion packet has player car index {player}; the cars are 0 ... "
                f"{F1_CARS - 1} (255: no player car, spectating)"
            )
        car = CAR_MOTION.unpack_from(packet, F1_HEADER.size + CAR_MOTION.size * player)
        lateral, longitudinal, vertical = car[12:15]
        if not all(map(math.isfinite, (lateral, longitudinal, vertical))):
            raise BadPacket(
                f"f1 Motion packet has non-finite g-forces for car {player}: lateral {lateral}, "
                f"longitudinal {longitudinal}, vertical {vertical}"
            )
        s_long, s_lat, s_vert = self._g_signs
        f = (s_long * longitudinal, s_lat * lateral, s_vert * vertical)
        # checked before it is held: a garbage part would spoil the samples it pairs with
        if max(map(abs, f)) > MAX_SPECIFIC_FORCE:
            raise BadPacket(
                f"f1 Motion packet has g-forces {[lateral, longitudinal, vertical]} for car "
                f"{player}: beyond 20 g, garbage"
            )
        return f

    def _angular_velocity(self, packet: bytes) -> tuple[float, float, float]:
        w_x, w_y, w_z = _VECTOR.unpack_from(packet, ANGULAR_VELOCITY_AT)
        if not all(map(math.isfinite, (w_x, w_y, w_z))):
            raise BadPacket(
                f"f1 Motion Ex packet has non-finite angular velocity {(w_x, w_y, w_z)}"
            )
        if max(abs(w_x), abs(w_y), abs(w_z)) > MAX_ANGULAR_RATE:
            raise BadPacket(
                f"f1 Motion Ex packet has angular velocity {[w_x, w_y, w_z]} rad/s: beyond "
                f"{MAX_ANGULAR_RATE:g} rad/s, garbage"
            )
        s = self._roll_yaw_sign
        # head axes: roll about forward (local z), pitch about left, yaw about up (local y)
        return (s * w_z, w_x, s * w_y)
