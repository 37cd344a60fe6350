"""KUKA RobotSensorInterface (RSI) messages: the controller's state and the external reply.

Every interpolation cycle (4 or 12 ms) an RSI controller sends one UDP datagram of XML and
expects, within the cycle, a reply carrying the same cycle counter (IPOC). The layout is that
of ROS-Industrial's `kuka_rsi_hw_interface` (tag names configurable, `RsiTags`):

    controller -> external:   <Rob Type="KUKA">
                                <AIPos A1=".." A2=".." A3=".." A4=".." A5=".." A6=".."/>
                                <IPOC>n</IPOC>
                              </Rob>
    external -> controller:   <Sen Type="ImFree"><AK A1=".." ... A6=".."/><IPOC>n</IPOC></Sen>

AIPos holds the actual axis positions, AK the axis corrections relative to the pose at the
start of the RSI motion; both in degrees (the robot's units: this module converts nothing,
its callers do, at their boundary). A controller with external axes (a linear track is E1)
sends their actual positions in an element of their own, `<EIPos E1=".." ... E6=".."/>`
(KUKA's DEF_EIPos), and reads their corrections from `<EK E1=".."/>` (RSI's AXISCORREXT
object), in mm for a linear axis and degrees for a rotary one; `parse_state` reads the first
`external` of them and the writers write them where given. The state may carry other
elements (RIst, RSol, ASPos, Delay, ...): they are ignored.

Parsing is a scan for the few elements needed, not a general XML parser: it accepts only
bounded datagrams of ASCII text with attribute values in double quotes (as KUKA writes them),
expands no entities and builds no tree, so a malformed or hostile datagram costs
microseconds and raises `BadRsiPacket`, never anything else. The
writers produce well-formed XML (checked in the tests with Python's own parser).
"""

import dataclasses
import functools
import math
import re

# Longest datagram accepted, bytes: a full KUKA state message is under 1 kB.
MAX_RSI_BYTES = 4096
# Resolution of the axis values written, deg (six decimals).
RSI_RESOLUTION_DEG = 1e-6
# IPOC is an unsigned 64-bit counter (milliseconds of the controller's clock).
MAX_IPOC = 2**64 - 1


class BadRsiPacket(ValueError):  # noqa: N818 (named like the telemetry layer's BadPacket)
    """An RSI datagram that does not hold what the driver needs; the message says why."""


# Not frozen: scenarios set it from YAML (`LiveScenario.rsi.tags`), which fills fields in.
@dataclasses.dataclass
class RsiTags:
    """The XML names of the RSI object configuration (ROS-Industrial's defaults)."""

    # Root element of the controller's message, and the Type attribute the emulator writes
    # in it (a state's Type is not checked when read: controllers differ).
    state_root: str = "Rob"
    state_type: str = "KUKA"
    # Element of the actual axis positions, deg.
    actual_positions: str = "AIPos"
    # Root element and Type of the external system's reply.
    reply_root: str = "Sen"
    reply_type: str = "ImFree"
    # Element of the axis corrections, deg.
    corrections: str = "AK"
    # The cycle counter element (in both messages).
    ipoc: str = "IPOC"
    # Attribute names of the six axes.
    axes: list[str] = dataclasses.field(
        default_factory=lambda: ["A1", "A2", "A3", "A4", "A5", "A6"]
    )
    # Elements of the external axes' actual positions and corrections (mm or deg).
    external_positions: str = "EIPos"
    external_corrections: str = "EK"
    # Attribute names of the external axes, in their order (E1 first).
    external_axes: list[str] = dataclasses.field(
        default_factory=lambda: ["E1", "E2", "E3", "E4", "E5", "E6"]
    )

    def validate(self) -> None:
        """Raises ValueError for a name that is not a plain XML name, naming it."""
        names = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        axes = names.pop("axes")
        external = names.pop("external_axes")
        if len(axes) != 6 or len(set(axes)) != 6:
            raise ValueError(f"RsiTags.axes must be six distinct names; got {axes}")
        if not 1 <= len(external) <= 6 or len(set(external)) != len(external):
            raise ValueError(f"RsiTags.external_axes must be 1 to 6 distinct names; got {external}")
        listed = [("axes", a) for a in axes] + [("external_axes", a) for a in external]
        for field, value in list(names.items()) + listed:
            if not _NAME.fullmatch(value):
                raise ValueError(f"RsiTags.{field} must be a plain XML name; got {value!r}")


@dataclasses.dataclass(frozen=True)
class RsiMessage:
    """One parsed message: the cycle counter, six axis values (deg) and the external axes'
    values read (mm or deg; empty where none were asked for)."""

    ipoc: int
    axes_deg: tuple[float, ...]
    external: tuple[float, ...] = ()


_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]*")
_ATTRIBUTE = re.compile(r'([A-Za-z_][A-Za-z0-9_.-]*)\s*=\s*"([^"<&]*)"')
_NUMBER = re.compile(r"\s*[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?\s*")


@dataclasses.dataclass(frozen=True)
class _Patterns:
    root: re.Pattern
    element: re.Pattern
    ipoc: re.Pattern


_PATTERNS: dict[tuple[str, str, str, str], _Patterns] = {}
# Tag sets already validated (a driver checks its tags once, not every 4 ms cycle).
_VALID_TAGS: set[tuple] = set()  # the tags validated so far, by value


# The tags of ROS-Industrial's defaults, the functions' default (read, never changed).
DEFAULT_TAGS = RsiTags()


def _checked(tags: RsiTags) -> RsiTags:
    key = (
        tags.state_root,
        tags.state_type,
        tags.actual_positions,
        tags.reply_root,
        tags.reply_type,
        tags.corrections,
        tags.ipoc,
        *tags.axes,
        tags.external_positions,
        tags.external_corrections,
        *tags.external_axes,
    )
    if key not in _VALID_TAGS:
        tags.validate()
        _VALID_TAGS.add(key)
    return tags


def _patterns(root: str, kind: str, element: str, ipoc: str) -> _Patterns:
    key = (root, kind, element, ipoc)
    if key not in _PATTERNS:
        _PATTERNS[key] = _Patterns(
            root=re.compile(
                rf"\s*(?:<\?xml[^>]*\?>\s*)?<{re.escape(root)}\b([^>]*)>(.*)</{re.escape(root)}>\s*",
                re.DOTALL,
            ),
            element=re.compile(rf"<{re.escape(element)}\b([^>]*?)/?>"),
            ipoc=re.compile(rf"<{re.escape(ipoc)}>\s*(\d{{1,20}})\s*</{re.escape(ipoc)}>"),
        )
    return _PATTERNS[key]


def _parse(
    packet: bytes,
    root: str,
    kind: str,
    element: str,
    tags: RsiTags,
    external: int = 0,
    external_element: str = "",
) -> RsiMessage:
    if not isinstance(packet, bytes | bytearray | memoryview):
        raise BadRsiPacket(f"RSI packet must be bytes; got {type(packet).__name__}")
    if len(packet) > MAX_RSI_BYTES:
        raise BadRsiPacket(f"RSI packet of {len(packet)} bytes; at most {MAX_RSI_BYTES} accepted")
    try:
        text = bytes(packet).decode("ascii")
    except UnicodeDecodeError as error:
        raise BadRsiPacket(f"RSI packet is not ASCII text: {error}") from None
    found = _patterns(root, kind, element, _checked(tags).ipoc)
    whole = found.root.fullmatch(text)
    if whole is None:
        raise BadRsiPacket(f"RSI packet is not one <{root}> element")
    # The root's Type attribute is not read: controllers and simulators write it in any case
    # (ROS-Industrial's simulator sends TYPE="KUKA") or leave it out, and ROS-Industrial's
    # kuka_rsi_hw_interface reads none of it; the root's name and the elements decide.
    body = whole.group(2)
    axes = _axis_values(body, found.element, element, tags.axes)
    extra = ()
    if external:
        names = tags.external_axes[:external]
        extra = _axis_values(body, _element_pattern(external_element), external_element, names)
    counters = found.ipoc.findall(body)
    if len(counters) != 1:
        raise BadRsiPacket(
            f"RSI packet has {len(counters)} <{tags.ipoc}> counters of digits; needs one"
        )
    ipoc = int(counters[0])
    if ipoc > MAX_IPOC:
        raise BadRsiPacket(f"RSI <{tags.ipoc}> {ipoc} exceeds 64 bits")
    return RsiMessage(ipoc=ipoc, axes_deg=axes, external=extra)


@functools.lru_cache(maxsize=16)
def _element_pattern(element: str) -> re.Pattern:
    return re.compile(rf"<{re.escape(element)}\b([^>]*?)/?>")


def _axis_values(body: str, pattern: re.Pattern, element: str, names) -> tuple[float, ...]:
    """The values of the attributes `names` of the one `element` in `body`; BadRsiPacket
    for no or several such elements, a repeated attribute, a missing, non-numeric or
    non-finite value."""
    elements = pattern.findall(body)
    if len(elements) != 1:
        raise BadRsiPacket(f"RSI packet has {len(elements)} <{element}> elements; needs one")
    attributes = _ATTRIBUTE.findall(elements[0])
    values = dict(attributes)
    if len(values) != len(attributes):
        raise BadRsiPacket(f"RSI <{element}> repeats an attribute")
    out = []
    for axis in names:
        raw = values.get(axis)
        if raw is None:
            raise BadRsiPacket(f"RSI <{element}> lacks axis {axis}")
        if not _NUMBER.fullmatch(raw):
            raise BadRsiPacket(f'RSI <{element}> {axis}="{raw}" is not a decimal number')
        value = float(raw)
        if not math.isfinite(value):
            raise BadRsiPacket(f'RSI <{element}> {axis}="{raw}" is not finite')
        out.append(value)
    return tuple(out)


def parse_state(packet: bytes, tags: RsiTags = DEFAULT_TAGS, external: int = 0) -> RsiMessage:
    """The controller's cycle counter and actual axis positions (deg) in `packet`, and the
    first `external` external axes' positions (mm or deg; `RsiMessage.external`).

    Raises:
        BadRsiPacket: too long, not ASCII, not one root element of the right name, no or
            several position elements, a missing, repeated, non-numeric or non-finite axis
            (external ones too), no or several counters, a counter beyond 64 bits.
    """
    return _parse(
        packet,
        tags.state_root,
        tags.state_type,
        tags.actual_positions,
        tags,
        _external_count(external, tags),
        tags.external_positions,
    )


def parse_reply(packet: bytes, tags: RsiTags = DEFAULT_TAGS, external: int = 0) -> RsiMessage:
    """The echoed cycle counter, the axis corrections (deg) and the first `external`
    external axes' corrections of an external reply (what a controller, or the loopback
    emulator, reads). Raises BadRsiPacket as `parse_state`."""
    return _parse(
        packet,
        tags.reply_root,
        tags.reply_type,
        tags.corrections,
        tags,
        _external_count(external, tags),
        tags.external_corrections,
    )


def _external_count(external: int, tags: RsiTags) -> int:
    if isinstance(external, bool) or not isinstance(external, int):
        raise ValueError(f"external must be a whole number of axes; got {external!r}")
    if not 0 <= external <= len(tags.external_axes):
        raise ValueError(f"external must be 0 to {len(tags.external_axes)} axes; got {external}")
    return external


def _attributes(names, values, what: str) -> str:
    values = [float(v) for v in values]
    if len(values) != len(names) or not all(map(math.isfinite, values)):
        raise ValueError(f"{len(names)} finite {what} needed; got {values!r}")
    # fixed point, as KRL reads it, to RSI_RESOLUTION_DEG: coarser rounding shows in the
    # second differences a controller checks (1e-4 deg is 12 deg/s^2 at a 4 ms cycle)
    return " ".join(f'{a}="{v:.6f}"' for a, v in zip(names, values, strict=True))


def _format(
    root: str,
    kind: str,
    element: str,
    ipoc: int,
    axes_deg,
    tags: RsiTags,
    external_element: str,
    external=(),
) -> bytes:
    _checked(tags)
    if not (isinstance(ipoc, int) and 0 <= ipoc <= MAX_IPOC):
        raise ValueError(f"IPOC must be an integer in [0, 2^64); got {ipoc!r}")
    values = [float(v) for v in axes_deg]
    if len(values) != 6 or not all(map(math.isfinite, values)):
        raise ValueError(f"six finite axis values (deg) needed; got {axes_deg!r}")
    parts = f"<{element} {_attributes(tags.axes, axes_deg, 'axis values (deg)')}/>"
    external = tuple(external)
    if external:
        names = tags.external_axes[: _external_count(len(external), tags)]
        parts += f"<{external_element} {_attributes(names, external, 'external axis values')}/>"
    return (f'<{root} Type="{kind}">{parts}<{tags.ipoc}>{ipoc}</{tags.ipoc}></{root}>').encode(
        "ascii"
    )


def format_reply(ipoc: int, corrections_deg, tags: RsiTags = DEFAULT_TAGS, external=()) -> bytes:
    """The external system's reply: the echoed `ipoc`, six axis corrections (deg) and, where
    given, the external axes' corrections (mm or deg, E1 first).

    Raises:
        ValueError: a counter outside [0, 2^64), corrections that are not six finite
            numbers, or external ones that are not finite or too many (the driver never
            sends what it could not check).
    """
    return _format(
        tags.reply_root,
        tags.reply_type,
        tags.corrections,
        ipoc,
        corrections_deg,
        tags,
        tags.external_corrections,
        external,
    )


def format_state(ipoc: int, positions_deg, tags: RsiTags = DEFAULT_TAGS, external=()) -> bytes:
    """A controller's state message (what the loopback emulator sends): `ipoc`, the six
    actual axis positions (deg) and, where given, the external axes' positions (mm or deg,
    E1 first). Raises ValueError as `format_reply`."""
    return _format(
        tags.state_root,
        tags.state_type,
        tags.actual_positions,
        ipoc,
        positions_deg,
        tags,
        tags.external_positions,
        external,
    )


__all__ = [
    "MAX_RSI_BYTES",
    "RSI_RESOLUTION_DEG",
    "BadRsiPacket",
    "RsiMessage",
    "RsiTags",
    "format_reply",
    "format_state",
    "parse_reply",
    "parse_state",
]
