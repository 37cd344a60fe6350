"""Live for Speed's OutSim UDP packets: the classic OutSimPack and OutSim 2 (`OutSim Opts`).

Sources: LFS's documentation, `docs/InSim.txt` ("OutSim - MOTION SIMULATOR SUPPORT AND
TELEMETRY OUTPUT", struct OutSimPack and OutSimMain; mirrored at
https://en.lfsmanual.net/wiki/InSim.txt) and `docs/OutSimPack.txt` (OutSimPack2 and the
`OSO_*` option bits), with LFS's "OutSim full packet format" offset table,
https://lfs.net/attachment/217202. Both are little-endian (the x86 memory image of the
structs, no padding). LFS's `cfg.txt` enables the output: `OutSim Mode 1`, `OutSim IP`,
`OutSim Port`, `OutSim Delay` (hundredths of a second between packets), `OutSim ID` and
`OutSim Opts`.

Classic OutSimPack (`OutSim Opts 0`), 64 bytes, or 68 with a non-zero `OutSim ID`:

    offset  field                   type       meaning
    0       Time                    uint32     ms, the sender's clock
    4       AngVel                  3 float32  angular velocity, rad/s, world axes
    16      Heading                 float32    rad, anticlockwise from above (about Z)
    20      Pitch                   float32    rad, anticlockwise from right (about X)
    24      Roll                    float32    rad, anticlockwise from front (about Y)
    28      Accel                   3 float32  acceleration, m/s^2, world axes
    40      Vel                     3 float32  velocity, m/s, world axes
    52      Pos                     3 int32    position, 1 m = 65536
    64      ID                      int32      only with a non-zero OutSim ID

OutSim 2 (`OutSim Opts` > 0, hexadecimal in cfg.txt: `1ff` is every part) sends the parts
its bits select, in this order: header b"LFST" (OSO_HEADER 0x1, 4 bytes), ID (OSO_ID 0x2, 4),
Time (OSO_TIME 0x4, 4), OutSimMain (OSO_MAIN 0x8, 60: AngVel to Pos as above), inputs
(OSO_INPUTS 0x10, 20), drive (OSO_DRIVE 0x20, 12), distance (OSO_DISTANCE 0x40, 8), four
wheels (OSO_WHEELS 0x80, 160) and extra (OSO_EXTRA_1 0x100, 8): 280 bytes for `1ff`. The
decoder needs OSO_MAIN; without OSO_TIME the sample time is the arrival time.

Axes and angles: the world's X and Y are on the ground, Z up; the car's axes are X right,
Y forward, Z up, and at zero heading the car faces world Y. The car's attitude is heading H
about world Z, then pitch P about the car's X, then roll R about the car's Y, each
anticlockwise seen from the positive axis (the right-hand rule):

    R_WC = Rz(H) Rx(P) Ry(R)    (car axes to world axes)

so pitch is positive nose up and roll positive right side down. AngVel and Accel are world
vectors: the decoder rotates them into the car, v_C = R_WC^T v_W, and reorders the car's
(right, forward, up) into head axes (x forward, y left, z up): (v_C.y, -v_C.x, v_C.z).

Gravity: Accel is the car's acceleration, the rate of change of Vel in the same world axes,
and holds no gravity (the documentation lists no gravity term, and a world-axis acceleration
of a car at rest is zero). The specific force is f = R_WC^T (Accel + (0, 0, g)), g = 9.81
m/s^2: a level car at rest reads f = (0, 0, +9.81). The guide's check (a car parked on the
level reads f_z = +9.81, not 0 or 19.6) confirms this once.

Signals (`mca_drake.references.vehicle_signals`) every sample carries: `speed`, the length of
Vel (m/s), `pitch` and `roll` (rad, the conventions above); with OSO_INPUTS also `throttle`
and `brake` (OutSimInputs: Throttle, Brake, InputSteer, Clutch, Handbrake, float32 each,
the pedals 0 ... 1). InputSteer is an angle in radians, not a share of the lock, and is not
passed on. A value that is not finite or outside its range is left out.

Pos and the other OutSim 2 parts are not used. The values are at the car's reference
point (LFS does not document it as the driver's head): give the head's offset in a
`LeverArm`.
"""

# No `from __future__ import annotations`: LiveScenario's YAML loader reads the config's
# field types, which must be type objects.
import dataclasses
import math
import struct

from mca_drake.conventions import GRAVITY
from mca_drake.live.telemetry import BadPacket, Decoder, LeverArm, TelemetrySample
from mca_drake.references.vehicle_signals import within_bounds

OUTSIM_HEADER = b"LFST"
# The classic OutSimPack, without and with its trailing ID.
OUTSIM_PACK_SIZE = 64
OUTSIM_PACK_ID_SIZE = 68
# OutSim 2's option bits and the size of the part each adds, in packet order.
OSO_HEADER = 0x1
OSO_ID = 0x2
OSO_TIME = 0x4
OSO_MAIN = 0x8
OSO_INPUTS = 0x10
OSO_DRIVE = 0x20
OSO_DISTANCE = 0x40
OSO_WHEELS = 0x80
OSO_EXTRA_1 = 0x100
OSO_PARTS = (
    (OSO_HEADER, "header", 4),
    (OSO_ID, "ID", 4),
    (OSO_TIME, "Time", 4),
    (OSO_MAIN, "OutSimMain", 60),
    (OSO_INPUTS, "inputs", 20),
    (OSO_DRIVE, "drive", 12),
    (OSO_DISTANCE, "distance", 8),
    (OSO_WHEELS, "wheels", 160),
    (OSO_EXTRA_1, "extra", 8),
)
OSO_ALL = 0x1FF
# The largest packet LFS sends (OutSim Opts 1ff).
OUTSIM_MAX_SIZE = sum(size for _, _, size in OSO_PARTS)
# OutSimMain: AngVel, Heading, Pitch, Roll, Accel, Vel (floats), Pos (ints).
_MAIN = struct.Struct("<12f3i")
_TIME = struct.Struct("<I")
# Throttle and Brake, the first two floats of OutSimInputs (OSO_INPUTS).
_PEDALS = struct.Struct("<2f")
# Names of the floats of OutSimMain, for messages.
MAIN_FIELDS = (
    "AngVel.x",
    "AngVel.y",
    "AngVel.z",
    "Heading",
    "Pitch",
    "Roll",
    "Accel.x",
    "Accel.y",
    "Accel.z",
    "Vel.x",
    "Vel.y",
    "Vel.z",
)
# Pitch and roll beyond this (rad) are garbage or degrees read as radians.
MAX_ANGLE_RAD = 2 * math.pi


@dataclasses.dataclass
class OutSimConfig:
    """Which OutSim packet LFS sends: its cfg.txt `OutSim Opts`."""

    # cfg.txt's `OutSim Opts` as a number (cfg.txt writes it in hexadecimal: `1ff` is 0x1ff
    # = 511). 0: the classic OutSimPack (64 bytes, 68 with an OutSim ID); otherwise OutSim 2
    # with the parts these OSO_* bits select, OSO_MAIN (0x8) among them.
    opts: int = 0

    def validate(self) -> None:
        """Raises ValueError for options the decoder cannot read, naming them."""
        if isinstance(self.opts, bool) or not isinstance(self.opts, int):
            raise ValueError(f"OutSimConfig.opts must be an integer; got {self.opts!r}")
        if not 0 <= self.opts <= OSO_ALL:
            raise ValueError(
                f"OutSimConfig.opts {self.opts:#x} has bits LFS does not define; valid: 0 "
                f"(classic OutSimPack) or OSO_* bits up to {OSO_ALL:#x}"
            )
        if self.opts and not self.opts & OSO_MAIN:
            raise ValueError(
                f"OutSim Opts {self.opts:x} lacks OSO_MAIN (8): the packets would carry no "
                "motion; add 8 to OutSim Opts in LFS's cfg.txt"
            )


def outsim_packet_size(opts: int) -> int:
    """Bytes of an OutSim 2 packet with option bits `opts` (> 0)."""
    return sum(size for bit, _, size in OSO_PARTS if opts & bit)


def _part_offset(opts: int, wanted: int) -> int:
    """Offset of part `wanted` (an OSO_* bit set in `opts`) in an OutSim 2 packet."""
    return sum(size for bit, _, size in OSO_PARTS if opts & bit and bit < wanted)


def car_from_world(heading: float, pitch: float, roll: float):
    """The function v_W -> v_C for the car attitude (rad): v_C = R_WC^T v_W with
    R_WC = Rz(heading) Rx(pitch) Ry(roll) (module docstring). Car axes: right, forward, up."""
    ch, sh = math.cos(heading), math.sin(heading)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    # Columns of R_WC: the car's right, forward and up axes in world axes.
    right = (ch * cr - sh * sp * sr, sh * cr + ch * sp * sr, -cp * sr)
    forward = (-sh * cp, ch * cp, sp)
    up = (ch * sr + sh * sp * cr, sh * sr - ch * sp * cr, cp * cr)

    def rotate(v):
        return tuple(a[0] * v[0] + a[1] * v[1] + a[2] * v[2] for a in (right, forward, up))

    return rotate


class OutSimDecoder(Decoder):
    """Decodes Live for Speed OutSim packets into head-frame samples (module docstring:
    layouts, axes, gravity). The sample time is the packet's Time (ms), when it has one.

    Args:
        config: which packet LFS sends (`OutSim Opts`; None: the classic OutSimPack).
        lever_arm: where the head is relative to the car's reference point.
    """

    protocol = "outsim"
    vehicle = "car"
    max_datagram_bytes = OUTSIM_MAX_SIZE

    def __init__(
        self, *, config: OutSimConfig | None = None, lever_arm: LeverArm | None = None
    ) -> None:
        self.config = config or OutSimConfig()
        self.config.validate()
        opts = self.config.opts
        if opts:
            self._sizes = (outsim_packet_size(opts),)
            self._main_at = _part_offset(opts, OSO_MAIN)
            self._time_at = _part_offset(opts, OSO_TIME) if opts & OSO_TIME else None
            self._inputs_at = _part_offset(opts, OSO_INPUTS) if opts & OSO_INPUTS else None
        else:
            self._inputs_at = None
            self._sizes = (OUTSIM_PACK_SIZE, OUTSIM_PACK_ID_SIZE)
            self._main_at, self._time_at = 4, 0
        super().__init__(lever_arm=lever_arm)

    def _decode_at_source(self, packet: bytes, received_s: float) -> TelemetrySample:
        opts = self.config.opts
        if len(packet) not in self._sizes:
            sizes = " or ".join(map(str, self._sizes))
            raise BadPacket(
                f"outsim packet of {len(packet)} bytes; OutSim Opts {opts:x} sends {sizes} "
                "(does the decoder's OutSimConfig.opts match LFS's cfg.txt?)"
            )
        if opts & OSO_HEADER and packet[:4] != OUTSIM_HEADER:
            raise BadPacket(
                f"outsim packet starts {bytes(packet[:4])!r}, not {OUTSIM_HEADER!r} (OSO_HEADER)"
            )
        values = _MAIN.unpack_from(packet, self._main_at)
        floats = values[:12]
        if not all(map(math.isfinite, floats)):
            listed = ", ".join(
                f"{name} = {value}"
                for name, value in zip(MAIN_FIELDS, floats, strict=True)
                if not math.isfinite(value)
            )
            raise BadPacket(f"outsim packet has non-finite values: {listed}")
        heading, pitch, roll = floats[3:6]
        if max(abs(heading), abs(pitch), abs(roll)) > MAX_ANGLE_RAD:
            raise BadPacket(
                f"outsim packet has Heading {heading}, Pitch {pitch}, Roll {roll}: beyond 2 pi "
                "rad (degrees?)"
            )
        to_car = car_from_world(heading, pitch, roll)
        w_right, w_forward, w_up = to_car(floats[0:3])
        a_x, a_y, a_z = floats[6:9]
        f_right, f_forward, f_up = to_car((a_x, a_y, a_z + GRAVITY))
        omega = (w_forward, -w_right, w_up)
        f = (f_forward, -f_right, f_up)
        signals = self._signals(packet, floats)
        if self._time_at is None:
            return TelemetrySample(received_s, omega, f, time_source="arrival", signals=signals)
        (time_ms,) = _TIME.unpack_from(packet, self._time_at)
        return TelemetrySample(time_ms * 1e-3, omega, f, time_source="sender", signals=signals)

    def _signals(self, packet: bytes, main: tuple) -> dict[str, float]:
        """The sample's signals (module docstring) from the packet and its OutSimMain
        floats `main` (finite, checked)."""
        signals = {"speed": math.hypot(*main[9:12]), "pitch": main[4], "roll": main[5]}
        if self._inputs_at is not None:
            throttle, brake = _PEDALS.unpack_from(packet, self._inputs_at)
            for name, value in (("throttle", throttle), ("brake", brake)):
                if math.isfinite(value) and within_bounds(name, value):
                    signals[name] = value
        return signals
