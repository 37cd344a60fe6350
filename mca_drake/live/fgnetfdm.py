"""FlightGear's native FDM packet (FGNetFDM, version 24) as JSBSim sends it over UDP.

JSBSim emits it for an output directive of type FLIGHTGEAR (`jsbsim_output_directive` writes
one). The layout is JSBSim's `src/input_output/net_fdm.hxx` (FlightGear's `FGNetFDM`, version
24; JSBSim 1.3.0 and later send no other version) and the values are those its
`FGOutputFG::SocketDataFill` fills:

- 408 bytes, big-endian (network order), no padding between fields; `version` = 24, the
  `padding` word and unused engine, tank and wheel slots zero;
- `phi`, `theta`, `psi`: Euler angles, rad (roll positive right wing down);
- `phidot`, `thetadot`, `psidot`: Euler-angle rates, rad/s (JSBSim's FGAuxiliary computes
  them from the body rates p, q, r); the packet has no body-rate fields, so the decoder
  inverts the kinematics (singular only at theta = +-90 deg, where JSBSim stops updating
  psidot and phidot):

      p = phidot - psidot sin(theta)
      q = thetadot cos(phi) + psidot cos(theta) sin(phi)
      r = -thetadot sin(phi) + psidot cos(theta) cos(phi);

- `A_X_pilot`, `A_Y_pilot`, `A_Z_pilot`: JSBSim's `accelerations/a-pilot-{x,y,z}-ft_sec2`,
  the specific force at the pilot's eye point (non-gravitational force over mass plus the
  rigid-body terms of the eye point's offset from the centre of gravity), ft/s^2, body axes
  x forward, y right, z down: level flight reads (0, 0, -g);
- `cur_time`: the simulation time in units of the directive's `<time type="simulation"
  resolution="...">` (truncated to an integer, so up to one unit early), else the constant
  1234567890 (`JSBSIM_PLACEHOLDER_TIME`). A value that would be more than
  `MAX_SIMULATION_TIME_S` of simulation is not one (JSBSim's placeholder, FlightGear's Unix
  time): such a packet is timed by its arrival, so a decoder set for the directive also
  reads JSBSim's and FlightGear's default streams.

Head axes (x forward, y left, z up) flip y and z of JSBSim's body axes, exactly as
`mca_drake.references.jsbsim` builds its recordings: omega = (p, -q, -r) and
f = 0.3048 (A_X, -A_Y, -A_Z) m/s^2. The accelerations are at the eye point, so the default
`LeverArm` (zero offset) takes JSBSim's eye point as the head.

FlightGear's own native-fdm output uses the same layout; it fills `cur_time` with Unix time in
whole seconds, so decode it with `time_resolution_s=None` (arrival times).

A sample also carries what the packet says of the controls and the aircraft's state, as
`vehicle_signals` counts them: the surface positions JSBSim sends (normalised; its
`left_aileron` positive rolls right, its `elevator` positive pitches the nose down and its
`rudder` positive yaws the nose left, so both are negated), `vcas` (kt) as the speed, `phi`
and `theta` as roll and pitch, `agl` (m) as the height and any `wow` as on the ground.
"""

from __future__ import annotations

import math
import operator
import struct

from mca_drake.live.telemetry import BadPacket, Decoder, LeverArm, TelemetrySample
from mca_drake.references.vehicle_signals import signal_factor, within_bounds

FGNETFDM_VERSION = 24
# sizeof(FGNetFDM) for version 24: 8 (version, padding) + 3 doubles + 90 four-byte fields.
FGNETFDM_SIZE = 408
# JSBSim's `cur_time` when the directive asks for no simulation time.
JSBSIM_PLACEHOLDER_TIME = 1234567890
# A `cur_time` beyond this much simulation (s, 11.6 days) is a wall clock or a placeholder.
MAX_SIMULATION_TIME_S = 1e6
# Metres per (international) foot, exact.
M_PER_FT = 0.3048

# The fields of FGNetFDM version 24 in packet order: (name, struct code, count). uint32 "I",
# int32 "i", float "f", double "d"; all big-endian.
FGNETFDM_LAYOUT: tuple[tuple[str, str, int], ...] = (
    ("version", "I", 1),
    ("padding", "I", 1),
    ("longitude", "d", 1),  # geodetic, rad
    ("latitude", "d", 1),  # geodetic, rad
    ("altitude", "d", 1),  # above sea level, m
    ("agl", "f", 1),  # above ground, m
    ("phi", "f", 1),  # roll, rad
    ("theta", "f", 1),  # pitch, rad
    ("psi", "f", 1),  # true heading, rad
    ("alpha", "f", 1),  # angle of attack, rad
    ("beta", "f", 1),  # sideslip, rad
    ("phidot", "f", 1),  # Euler-angle rates, rad/s
    ("thetadot", "f", 1),
    ("psidot", "f", 1),
    ("vcas", "f", 1),  # calibrated airspeed, kt
    ("climb_rate", "f", 1),  # ft/s
    ("v_north", "f", 1),  # NED velocity, ft/s
    ("v_east", "f", 1),
    ("v_down", "f", 1),
    ("v_body_u", "f", 1),  # body-axis velocity, ft/s
    ("v_body_v", "f", 1),
    ("v_body_w", "f", 1),
    ("A_X_pilot", "f", 1),  # specific force at the eye point, body axes, ft/s^2
    ("A_Y_pilot", "f", 1),
    ("A_Z_pilot", "f", 1),
    ("stall_warning", "f", 1),
    ("slip_deg", "f", 1),
    ("num_engines", "I", 1),
    ("eng_state", "I", 4),
    ("rpm", "f", 4),
    ("fuel_flow", "f", 4),
    ("fuel_px", "f", 4),
    ("egt", "f", 4),
    ("cht", "f", 4),
    ("mp_osi", "f", 4),
    ("tit", "f", 4),
    ("oil_temp", "f", 4),
    ("oil_px", "f", 4),
    ("num_tanks", "I", 1),
    ("fuel_quantity", "f", 4),
    ("num_wheels", "I", 1),
    ("wow", "I", 3),
    ("gear_pos", "f", 3),
    ("gear_steer", "f", 3),
    ("gear_compression", "f", 3),
    ("cur_time", "I", 1),
    ("warp", "i", 1),
    ("visibility", "f", 1),
    ("elevator", "f", 1),
    ("elevator_trim_tab", "f", 1),
    ("left_flap", "f", 1),
    ("right_flap", "f", 1),
    ("left_aileron", "f", 1),
    ("right_aileron", "f", 1),
    ("rudder", "f", 1),
    ("nose_wheel", "f", 1),
    ("speedbrake", "f", 1),
    ("spoilers", "f", 1),
)

_STRUCT = struct.Struct(">" + "".join(f"{count}{code}" for _, code, count in FGNETFDM_LAYOUT))
# Every double sits at a multiple of 8 and the total is one, so the C struct has no padding and
# the packed big-endian layout is the struct's memory image.
assert _STRUCT.size == FGNETFDM_SIZE, _STRUCT.size


def _offsets() -> dict[str, int]:
    offsets, at = {}, 0
    for name, code, count in FGNETFDM_LAYOUT:
        offsets[name] = at
        at += struct.calcsize(">" + code) * count
    return offsets


# Byte offset of each field in the packet.
FGNETFDM_OFFSETS: dict[str, int] = _offsets()

# The fields the decoder uses; each must be finite.
_USED = ("phi", "theta", "phidot", "thetadot", "psidot", "A_X_pilot", "A_Y_pilot", "A_Z_pilot")


def unpack_fgnetfdm(packet: bytes) -> dict[str, float | int | tuple]:
    """Every field of an FGNetFDM version-24 packet, by its `FGNETFDM_LAYOUT` name (arrays
    as tuples), in the packet's units.

    Raises:
        BadPacket: too short for the version word, a version other than 24 (with a hint for
            a byte-swapped or version-25 sender), or not 408 bytes.
    """
    values = _unpack_checked(packet)
    fields: dict[str, float | int | tuple] = {}
    at = 0
    for name, _, count in FGNETFDM_LAYOUT:
        fields[name] = values[at] if count == 1 else tuple(values[at : at + count])
        at += count
    return fields


def _flat_start(field: str) -> int:
    """Where `field` (its first element, for an array) sits in the unpacked values."""
    at = 0
    for name, _, count in FGNETFDM_LAYOUT:
        if name == field:
            return at
        at += count
    raise KeyError(field)


def _index_of_scalars() -> dict[str, int]:
    index, at = {}, 0
    for name, _, count in FGNETFDM_LAYOUT:
        if count == 1:
            index[name] = at
        at += count
    return index


# What the decoder reads, as positions in the unpacked tuple: picked in one C call, without
# the dict of all 100 values (the live loop decodes between a packet and its command).
_PICK_USED = operator.itemgetter(*(_index_of_scalars()[name] for name in (*_USED, "cur_time")))
# The controls and state passed on as the sample's signals: the scalar fields, then the
# first wheel's weight on wheels (the layout's `wow` array starts there).
_SIGNAL_FIELDS = ("left_aileron", "elevator", "rudder", "vcas", "agl")
_PICK_SIGNALS = operator.itemgetter(*(_index_of_scalars()[name] for name in _SIGNAL_FIELDS))
_WOW_AT = _flat_start("wow")
_KT = signal_factor("speed", "kt")


def _unpack_checked(packet: bytes) -> tuple:
    """The packet's values in layout order (see unpack_fgnetfdm for what it raises)."""
    if len(packet) < 4:
        raise BadPacket(
            f"fgnetfdm packet of {len(packet)} bytes is too short for its version word "
            f"(version {FGNETFDM_VERSION} packets are {FGNETFDM_SIZE} bytes)"
        )
    (version,) = struct.unpack_from(">I", packet, 0)
    if version != FGNETFDM_VERSION:
        hint = ""
        if struct.unpack_from("<I", packet, 0)[0] == FGNETFDM_VERSION:
            hint = " (it reads 24 little-endian: the sender did not byte-swap to network order)"
        elif version == 25:
            hint = ' (FlightGear\'s version 25, sent by JSBSim before 1.3.0 with version="25")'
        raise BadPacket(
            f"fgnetfdm packet has version {version}; this decoder reads version "
            f"{FGNETFDM_VERSION}{hint}"
        )
    if len(packet) != FGNETFDM_SIZE:
        raise BadPacket(
            f"fgnetfdm packet of {len(packet)} bytes; version {FGNETFDM_VERSION} packets are "
            f"{FGNETFDM_SIZE} bytes (truncated or padded datagram)"
        )
    return _STRUCT.unpack(packet)


def body_rates_from_euler_rates(
    phi: float, theta: float, phidot: float, thetadot: float, psidot: float
) -> tuple[float, float, float]:
    """Body rates p, q, r (rad/s; x forward, y right, z down) from roll and pitch (rad) and
    the Euler-angle rates (rad/s) of the z-y-x (yaw, pitch, roll) sequence."""
    sin_phi, cos_phi = math.sin(phi), math.cos(phi)
    sin_theta, cos_theta = math.sin(theta), math.cos(theta)
    p = phidot - psidot * sin_theta
    q = thetadot * cos_phi + psidot * cos_theta * sin_phi
    r = -thetadot * sin_phi + psidot * cos_theta * cos_phi
    return p, q, r


def jsbsim_output_directive(
    port: int,
    *,
    host: str = "127.0.0.1",
    rate_hz: float = 100.0,
    time_resolution_s: float | None = 0.001,
) -> str:
    """The XML of a JSBSim output directive that sends FGNetFDM packets over UDP.

    Load it with `FGFDMExec.set_output_directive(path)` (after the model, before
    `run_ic`) or reference it from a script.

    Args:
        port: the receiver's UDP port.
        host: the receiver's address.
        rate_hz: packets per simulated second (JSBSim sends at most one per time step).
        time_resolution_s: unit of `cur_time` (1e-9 ... 1 s); decode with the same
            `FgNetFdmDecoder(time_resolution_s=...)`. None: JSBSim sends its placeholder.
    """
    if not (isinstance(port, int) and 0 < port < 65536):
        raise ValueError(f"port must be an int in 1 ... 65535; got {port!r}")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be positive; got {rate_hz}")
    time_element = ""
    if time_resolution_s is not None:
        _check_resolution(time_resolution_s)
        time_element = f'  <time type="simulation" resolution="{time_resolution_s!r}"/>\n'
    return (
        '<?xml version="1.0"?>\n'
        f'<output name="{host}" type="FLIGHTGEAR" protocol="UDP" port="{port}" '
        f'rate="{rate_hz!r}">\n{time_element}</output>\n'
    )


def _check_resolution(time_resolution_s: float) -> None:
    # JSBSim rejects a directive whose resolution is outside [1e-9, 1].
    if not (math.isfinite(time_resolution_s) and 1e-9 <= time_resolution_s <= 1.0):
        raise ValueError(f"time_resolution_s must be in [1e-9, 1] s; got {time_resolution_s}")


class FgNetFdmDecoder(Decoder):
    """Decodes FGNetFDM version-24 packets (JSBSim's FLIGHTGEAR output) into head-frame samples.

    Args:
        time_resolution_s: the unit of the packet's `cur_time`, s, as the JSBSim directive's
            `<time type="simulation" resolution="...">` sets it: the sample time is then the
            sender's simulation time (up to one unit early: JSBSim truncates); a packet
            with JSBSim's placeholder instead (its default output, without the directive)
            is timed by its arrival, so that a scenario set for the directive still cues
            JSBSim's default stream, and so is one whose time would be more than
            MAX_SIMULATION_TIME_S of simulation (FlightGear's Unix time). None: the
            packet has no usable time, the sample time is the arrival time.
        lever_arm: where the head is relative to JSBSim's eye point (None: at it).
    """

    protocol = "fgnetfdm"
    max_datagram_bytes = FGNETFDM_SIZE

    def __init__(
        self, *, time_resolution_s: float | None = None, lever_arm: LeverArm | None = None
    ) -> None:
        if time_resolution_s is not None:
            _check_resolution(time_resolution_s)
        self.time_resolution_s = time_resolution_s
        super().__init__(lever_arm=lever_arm)

    def _decode_at_source(self, packet: bytes, received_s: float) -> TelemetrySample:
        values = _unpack_checked(packet)
        *used, cur_time = _PICK_USED(values)
        if not all(map(math.isfinite, used)):
            listed = ", ".join(
                f"{name} = {value}"
                for name, value in zip(_USED, used, strict=True)
                if not math.isfinite(value)
            )
            raise BadPacket(f"fgnetfdm packet has non-finite values: {listed}")
        phi, theta, phidot, thetadot, psidot, a_x, a_y, a_z = used
        p, q, r = body_rates_from_euler_rates(phi, theta, phidot, thetadot, psidot)
        omega = (p, -q, -r)
        f = (M_PER_FT * a_x, -M_PER_FT * a_y, -M_PER_FT * a_z)
        signals = _signals(values, phi, theta)
        t_s = math.inf if self.time_resolution_s is None else cur_time * self.time_resolution_s
        if t_s > MAX_SIMULATION_TIME_S:
            # no simulation time (JSBSim's placeholder, FlightGear's Unix time): the arrival's
            return TelemetrySample(received_s, omega, f, time_source="arrival", signals=signals)
        return TelemetrySample(t_s, omega, f, time_source="sender", signals=signals)


def _signals(values: tuple, phi: float, theta: float) -> dict[str, float]:
    """The sample's signals from the packet's values (module docstring); a field that is not
    finite, or a surface position beyond full deflection (`within_bounds`), is left out."""
    aileron, elevator, rudder, vcas, agl = _PICK_SIGNALS(values)
    found = {
        "aileron": aileron,
        "elevator": -elevator,
        "rudder": -rudder,
        "speed": vcas * _KT,
        "roll": phi,
        "pitch": theta,
        "height": agl,
        "on_ground": float(any(values[_WOW_AT : _WOW_AT + 3])),
    }
    return {
        name: value
        for name, value in found.items()
        if math.isfinite(value) and within_bounds(name, value)
    }
