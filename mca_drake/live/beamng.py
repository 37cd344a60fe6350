"""BeamNG.drive's "MotionSim" UDP packets (Options > Other > Protocols).

Sources:

- the packet: BeamNG's protocol documentation, https://documentation.beamng.com/modding/protocols/
  ("MotionSim"), whose struct is the one BeamNG's vehicle Lua declares and fills:
  `lua/vehicle/protocols/motionSim.lua` and `lua/vehicle/protocols.lua` (BeamNG.drive 0.32
  and later; read in the public mirror of the game's Lua, GitHub wlkmanist/BeamNG_lua);
- the axes of the acceleration: the Lua fills `accX, accY, accZ` with minus the vehicle's
  acceleration sensor (`sensorX`, `sensorY`, `sensorZ`, the variant without gravity), whose
  axes BeamNG documents with its GForces sensor,
  https://documentation.beamng.com/beamng_tech/sensors/gforces/: vehicle axes, +X left,
  +Y backward, +Z up. The sensor reads acceleration, not its reaction: BeamNG's own ESC
  (`lua/vehicle/controller/esc.lua`) integrates `-sensorY` into the forward speed.

Packet: 88 bytes, little-endian, no padding (the x86 memory image of the C struct):

    offset  fields                      type       meaning
    0       format                      char[4]    b"BNG1"
    4       posX, posY, posZ            3 float32  world position, m
    16      velX, velY, velZ            3 float32  world velocity, m/s
    28      accX, accY, accZ            3 float32  acceleration, m/s^2, gravity not included
    40      upX, upY, upZ               3 float32  the vehicle's up axis in world axes
    52      rollPos, pitchPos, yawPos   3 float32  attitude, rad
    64      rollVel, pitchVel, yawVel   3 float32  angular velocity, rad/s
    76      rollAcc, pitchAcc, yawAcc   3 float32  angular acceleration, rad/s^2

Conversion to head axes (x forward, y left, z up), g = 9.81 m/s^2:

- `(accX, accY, accZ)` is the vehicle's acceleration along its right, forward and down axes
  (minus the sensor's left, backward, up components), so the kinematic acceleration in head
  axes is a = (accY, -accX, -accZ);
- gravity is not in it: the specific force adds the reaction to gravity in vehicle axes,
  f = a + g (sin(theta), cos(theta) sin(phi), cos(theta) cos(phi)), with theta the pitch
  (nose up positive) and phi the roll (right side down positive) from `pitchPos` and
  `rollPos`. A level car at rest reads f = (0, 0, +9.81);
- omega = (roll rate, -pitch rate, -yaw rate) with the rates in the aircraft sense: roll
  right side down, pitch nose up, yaw nose right. The yaw sign is BeamNG's: its ESC reads
  `-obj:getYawAngularVelocity()` as positive when turning left.

The published struct gives no sign convention for the angles and the angular rates. The
yaw-rate default is BeamNG's (above); roll and pitch default to the same aircraft senses,
those that BeamNG's earlier MotionSim Lua (`lua/vehicle/motionSim.lua`, computing `rollPos`
and `pitchPos` from the vehicle's direction vectors) gives the angles. `BeamNGConfig` switches
each sign, and the guide (docs/guides/driving.md, "Racing simulators") says how to check them
once on the road. BeamNG smooths every field as its protocol smoothing settings ask: set
them to 0 for the raw motion.

Signals (`mca_drake.references.vehicle_signals`) every sample carries: `speed`, the length
of the world velocity (m/s), and `roll` and `pitch`, the angles phi and theta above (rad).
The packet carries no controls (OutGauge, BeamNG's other protocol, sends the pedals on a port
of its own).

The position, up vector, yaw angle and angular accelerations are not used. The
packet has no time: the sample time is the arrival time. The values are at BeamNG's
reference node, not the driver's head: give the head's offset in a `LeverArm`.
"""

# No `from __future__ import annotations`: LiveScenario's YAML loader reads the config's
# field types, which must be type objects.
import dataclasses
import math
import struct

from mca_drake.conventions import GRAVITY
from mca_drake.live.telemetry import BadPacket, Decoder, LeverArm, TelemetrySample

BEAMNG_FORMAT = b"BNG1"
BEAMNG_SIZE = 88
# The 21 floats after the format, in packet order.
BEAMNG_FIELDS = (
    "posX",
    "posY",
    "posZ",
    "velX",
    "velY",
    "velZ",
    "accX",
    "accY",
    "accZ",
    "upX",
    "upY",
    "upZ",
    "rollPos",
    "pitchPos",
    "yawPos",
    "rollVel",
    "pitchVel",
    "yawVel",
    "rollAcc",
    "pitchAcc",
    "yawAcc",
)
_FLOATS = struct.Struct("<21f")
assert 4 + _FLOATS.size == BEAMNG_SIZE
_ACC, _ANGLES, _RATES = slice(6, 9), slice(12, 15), slice(15, 18)
# Attitude angles beyond this (rad) are garbage or degrees read as radians.
MAX_ANGLE_RAD = 2 * math.pi


@dataclasses.dataclass
class BeamNGConfig:
    """The sign conventions of the MotionSim packet's angles and angular rates."""

    # `rollPos` is positive with the right side down (else left side down).
    roll_angle_positive_right_down: bool = True
    # `pitchPos` is positive nose up (else nose down).
    pitch_angle_positive_nose_up: bool = True
    # `rollVel` is positive rolling right side down.
    roll_rate_positive_right_down: bool = True
    # `pitchVel` is positive pitching nose up.
    pitch_rate_positive_nose_up: bool = True
    # `yawVel` is positive turning right.
    yaw_rate_positive_nose_right: bool = True

    def validate(self) -> None:
        """Raises ValueError for a field that is not a bool, naming it."""
        for field in dataclasses.fields(self):
            if not isinstance(getattr(self, field.name), bool):
                raise ValueError(
                    f"BeamNGConfig.{field.name} must be true or false; got "
                    f"{getattr(self, field.name)!r}"
                )


def _sign(positive: bool) -> float:
    return 1.0 if positive else -1.0


class BeamNGDecoder(Decoder):
    """Decodes BeamNG.drive MotionSim packets into head-frame samples (module docstring:
    layout, axes, signs).

    Args:
        config: the signs of the angles and rates (None: `BeamNGConfig()`).
        lever_arm: where the head is relative to BeamNG's reference node.
    """

    protocol = "beamng"
    vehicle = "car"
    max_datagram_bytes = BEAMNG_SIZE

    def __init__(
        self, *, config: BeamNGConfig | None = None, lever_arm: LeverArm | None = None
    ) -> None:
        self.config = config or BeamNGConfig()
        self.config.validate()
        c = self.config
        self._roll_angle = _sign(c.roll_angle_positive_right_down)
        self._pitch_angle = _sign(c.pitch_angle_positive_nose_up)
        # head axes: omega_x about forward (right side down), omega_y about left (nose down),
        # omega_z about up (nose left)
        self._rate_signs = (
            _sign(c.roll_rate_positive_right_down),
            -_sign(c.pitch_rate_positive_nose_up),
            -_sign(c.yaw_rate_positive_nose_right),
        )
        super().__init__(lever_arm=lever_arm)

    def _decode_at_source(self, packet: bytes, received_s: float) -> TelemetrySample:
        if len(packet) != BEAMNG_SIZE or packet[:4] != BEAMNG_FORMAT:
            raise BadPacket(
                f"beamng packet of {len(packet)} bytes starting {bytes(packet[:4])!r}; MotionSim "
                f"packets are {BEAMNG_SIZE} bytes starting {BEAMNG_FORMAT!r} (another protocol, "
                "such as OutGauge, on this port?)"
            )
        values = _FLOATS.unpack_from(packet, 4)
        if not all(map(math.isfinite, values)):
            listed = ", ".join(
                f"{name} = {value}"
                for name, value in zip(BEAMNG_FIELDS, values, strict=True)
                if not math.isfinite(value)
            )
            raise BadPacket(f"beamng packet has non-finite values: {listed}")
        acc_x, acc_y, acc_z = values[_ACC]
        roll, pitch, _ = values[_ANGLES]
        if max(abs(roll), abs(pitch)) > MAX_ANGLE_RAD:
            raise BadPacket(
                f"beamng packet has rollPos {roll}, pitchPos {pitch}: beyond 2 pi rad (degrees?)"
            )
        phi, theta = self._roll_angle * roll, self._pitch_angle * pitch
        cos_theta = math.cos(theta)
        f = (
            acc_y + GRAVITY * math.sin(theta),
            -acc_x + GRAVITY * cos_theta * math.sin(phi),
            -acc_z + GRAVITY * cos_theta * math.cos(phi),
        )
        omega = tuple(s * r for s, r in zip(self._rate_signs, values[_RATES], strict=True))
        signals = {"speed": math.hypot(*values[3:6]), "roll": phi, "pitch": theta}
        return TelemetrySample(received_s, omega, f, time_source="arrival", signals=signals)
