"""X-Plane's UDP "DATA" packets (the Data Output screen's "Network via UDP" rows).

Packet: the 4 ASCII bytes "DATA", one byte X-Plane uses internally (not checked), then one
36-byte record per selected row: the row ("group") index as a little-endian int32 and its
eight values as little-endian float32 (-999 in unused slots). X-Plane 11 and 12 send this
layout; the decoder reads two rows and ignores any others:

- row 4, "Mach, VVI, g-load": slots (0-based) 4, 5, 6 hold the normal, axial and side load
  factors in g. Normal is +1 in level flight. The signs of the other two follow the aircraft
  axes in which X-Plane reports its total forces (datarefs `sim/flightmodel/forces/
  fside_total`, `fnrml_total`, `faxil_total`: x right, y up, z aft): axial positive aft,
  side positive right; `XPlaneLayout` makes both switchable.
- row 16, "angular velocities": X-Plane 11 sends Q, P, R (pitch, roll, yaw) in rad/s;
  X-Plane 12 sends P, Q, R in deg/s. Roll positive right wing down, pitch positive nose up,
  yaw positive nose right (aircraft body axes). The version is a required parameter
  because nothing in the packet tells them apart.

Head axes (x forward, y left, z up), with g = 9.81 m/s^2 (`mca_drake.conventions.GRAVITY`):
f = g (-axial, -side, normal) and omega = (P, -Q, -R), in rad/s. Level flight, normal load
1 g: f = (0, 0, +9.81). The load factors are X-Plane's at the centre of gravity: give the
head's offset from it in a `LeverArm`.

The packet has no sender time: the sample time is the arrival time.

Rows the decoder also reads where they are ticked, as the sample's `signals`
(`mca_drake.references.vehicle_signals`): row 3, "speeds", slot 0 the indicated airspeed in
knots (`speed`); row 17, "pitch, roll, headings", slots 0 and 1 the pitch and roll in degrees
(`pitch`, `roll`); row 20, "lat, lon, altitude", slot 3 the height above ground in feet
(`height`); row 8, "joystick ail/elv/rud", slots 0, 1 and 2 the pilot's yoke ratios
(`elevator`, `aileron`, `rudder`, -1 ... 1, positive pulling, rolling right and yawing right,
X-Plane's `sim/joystick/yoke_*_ratio`); row 25, "throttle (commanded)", slot 0 the first
engine's throttle ratio 0 ... 1 (`throttle`). A value there that is not finite, or a control
outside its range, is left out.
"""

from __future__ import annotations

import dataclasses
import math
import struct

from mca_drake.conventions import GRAVITY
from mca_drake.input_checks import check_config_numbers
from mca_drake.live.telemetry import BadPacket, Decoder, LeverArm, TelemetrySample
from mca_drake.references.vehicle_signals import signal_factor, within_bounds

XPLANE_HEADER = b"DATA"
# Header: "DATA" and X-Plane's internal byte.
HEADER_SIZE = 5
RECORD_SIZE = 36
# X-Plane's Data Output screen numbers its rows below 200: a datagram with more records
# than that (each row at most once) is not one X-Plane sent.
MAX_RECORDS = 200
_RECORD = struct.Struct("<i8f")

RATE_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}

# Names of the rows the decoder reads, for messages.
GROUP_NAMES = {4: "Mach, VVI, g-load", 16: "angular velocities"}
# The optional rows passed on as signals: signal -> (row, slot, factor to SI).
SIGNAL_SLOTS = {
    "speed": (3, 0, signal_factor("speed", "kt")),  # indicated airspeed
    "pitch": (17, 0, signal_factor("pitch", "deg")),
    "roll": (17, 1, signal_factor("roll", "deg")),
    "height": (20, 3, signal_factor("height", "ft")),  # above ground
    "elevator": (8, 0, 1.0),  # the yoke's ratios, pilot's signs
    "aileron": (8, 1, 1.0),
    "rudder": (8, 2, 1.0),
    "throttle": (25, 0, 1.0),  # the first engine's commanded ratio
}


@dataclasses.dataclass(frozen=True)
class XPlaneLayout:
    """Where the decoder finds the load factors and the body rates in X-Plane's DATA rows."""

    # Data Output row with the load factors ("Mach, VVI, g-load").
    load_group: int = 4
    # Slots (0-based) of the normal, axial and side load factors, g, in that row.
    normal_slot: int = 4
    axial_slot: int = 5
    side_slot: int = 6
    # Sign conventions of the axial and side load factors (X-Plane's aircraft axes: aft, right).
    axial_positive_aft: bool = True
    side_positive_right: bool = True
    # Data Output row with the body rates ("angular velocities").
    rates_group: int = 16
    # Slots (0-based) of P (roll), Q (pitch) and R (yaw) in that row.
    rate_slots: tuple[int, int, int] = (0, 1, 2)
    # Unit of those rates: "rad/s" or "deg/s".
    rate_unit: str = "deg/s"

    def validate(self) -> None:
        """Raises ValueError for a layout that cannot be read, naming the field."""
        check_config_numbers(self)
        slots = (self.normal_slot, self.axial_slot, self.side_slot, *self.rate_slots)
        if len(self.rate_slots) != 3 or any(not 0 <= s <= 7 for s in slots):
            raise ValueError(f"XPlaneLayout slots must be three per row, each 0 ... 7: {self}")
        if len({self.normal_slot, self.axial_slot, self.side_slot}) != 3:
            raise ValueError(f"XPlaneLayout load-factor slots must differ: {self}")
        if len(set(self.rate_slots)) != 3:
            raise ValueError(f"XPlaneLayout rate slots must differ: {self.rate_slots}")
        if self.load_group == self.rates_group:
            raise ValueError(f"XPlaneLayout needs two different rows; got {self.load_group}")
        if self.rate_unit not in RATE_UNITS:
            raise ValueError(
                f"unknown XPlaneLayout.rate_unit '{self.rate_unit}'; valid: {', '.join(RATE_UNITS)}"
            )


# The layouts of the X-Plane versions this module knows, by major version.
XPLANE_LAYOUTS = {
    11: XPlaneLayout(rate_slots=(1, 0, 2), rate_unit="rad/s"),
    12: XPlaneLayout(rate_slots=(0, 1, 2), rate_unit="deg/s"),
}


def xplane_layout(version: int) -> XPlaneLayout:
    """The DATA layout of X-Plane `version` (11 or 12); ValueError listing the valid ones."""
    if version not in XPLANE_LAYOUTS:
        valid = ", ".join(str(v) for v in XPLANE_LAYOUTS)
        raise ValueError(f"unknown X-Plane version {version!r}; valid: {valid}")
    return XPLANE_LAYOUTS[version]


def parse_data_packet(packet: bytes) -> dict[int, tuple[float, ...]]:
    """The rows of an X-Plane DATA packet: group index -> its eight values.

    Raises:
        BadPacket: no "DATA" header, a length that is not the header plus whole 36-byte
            records, no record, or a row sent twice.
    """
    if len(packet) < HEADER_SIZE or packet[:4] != XPLANE_HEADER:
        raise BadPacket(
            f"xplane packet starts with {bytes(packet[:HEADER_SIZE])!r}, not b'DATA' and X-Plane's "
            "internal byte (not an X-Plane DATA packet)"
        )
    body = len(packet) - HEADER_SIZE
    if body == 0 or body % RECORD_SIZE:
        raise BadPacket(
            f"xplane DATA packet of {len(packet)} bytes: after the {HEADER_SIZE}-byte header "
            f"it needs one or more {RECORD_SIZE}-byte records, got {body} bytes (truncated?)"
        )
    rows: dict[int, tuple[float, ...]] = {}
    for group, *values in _RECORD.iter_unpack(packet[HEADER_SIZE:]):
        if group in rows:
            raise BadPacket(f"xplane DATA packet sends row {group} twice")
        rows[group] = tuple(values)
    return rows


class XPlaneDecoder(Decoder):
    """Decodes X-Plane DATA packets into head-frame samples (module docstring: rows, units).

    Args:
        version: X-Plane's major version, 11 or 12: it sets the order and unit of the body
            rates. Exactly one of `version` and `layout` is required.
        layout: where the values are (instead of a version's default layout).
        lever_arm: where the head is relative to the aircraft's centre of gravity.
    """

    protocol = "xplane"
    max_datagram_bytes = HEADER_SIZE + MAX_RECORDS * RECORD_SIZE

    def __init__(
        self,
        *,
        version: int | None = None,
        layout: XPlaneLayout | None = None,
        lever_arm: LeverArm | None = None,
    ) -> None:
        if (version is None) == (layout is None):
            raise ValueError(
                "XPlaneDecoder needs exactly one of version (11 or 12) and layout: the body "
                "rates are rad/s in X-Plane 11 and deg/s in X-Plane 12"
            )
        self.layout = layout if layout is not None else xplane_layout(version)
        self.layout.validate()
        super().__init__(lever_arm=lever_arm)

    def _decode_at_source(self, packet: bytes, received_s: float) -> TelemetrySample:
        rows = parse_data_packet(packet)
        layout = self.layout
        missing = [g for g in (layout.load_group, layout.rates_group) if g not in rows]
        if missing:
            listed = ", ".join(f"{g} ({GROUP_NAMES.get(g, 'row')})" for g in missing)
            raise BadPacket(
                f"xplane DATA packet lacks row {listed}: tick 'Network via UDP' for it in "
                "X-Plane's Data Output screen"
            )
        load, rates = rows[layout.load_group], rows[layout.rates_group]
        used = {
            "normal load": (layout.load_group, layout.normal_slot),
            "axial load": (layout.load_group, layout.axial_slot),
            "side load": (layout.load_group, layout.side_slot),
            "P": (layout.rates_group, layout.rate_slots[0]),
            "Q": (layout.rates_group, layout.rate_slots[1]),
            "R": (layout.rates_group, layout.rate_slots[2]),
        }
        bad = [
            f"{name} (row {g} slot {s}) = {rows[g][s]}"
            for name, (g, s) in used.items()
            if not math.isfinite(rows[g][s])
        ]
        if bad:
            raise BadPacket(f"xplane DATA packet has non-finite values: {', '.join(bad)}")
        normal, axial, side = (
            load[layout.normal_slot],
            load[layout.axial_slot],
            load[layout.side_slot],
        )
        forward = -axial if layout.axial_positive_aft else axial
        left = -side if layout.side_positive_right else side
        # + 0.0: no -0.0 from -axial
        f = (GRAVITY * forward + 0.0, GRAVITY * left + 0.0, GRAVITY * normal + 0.0)
        scale = RATE_UNITS[layout.rate_unit]
        p, q, r = (scale * rates[s] for s in layout.rate_slots)
        omega = (p, -q, -r)
        signals = {
            name: rows[row][slot] * factor
            for name, (row, slot, factor) in SIGNAL_SLOTS.items()
            if row in rows
            and math.isfinite(rows[row][slot])
            and within_bounds(name, rows[row][slot] * factor)
        }
        return TelemetrySample(received_s, omega, f, time_source="arrival", signals=signals)
