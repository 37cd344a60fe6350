"""RSI messages: a state message as ROS-Industrial's
kuka_rsi_hw_interface documents the controller's, replies checked by Python's own XML parser,
and every malformed datagram refused with BadRsiPacket, never another exception."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mca_drake.live.rsi.xml import (
    MAX_RSI_BYTES,
    BadRsiPacket,
    RsiTags,
    format_reply,
    format_state,
    parse_reply,
    parse_state,
)

# A controller's message in the layout of kuka_rsi_hw_interface's documentation: other
# elements around the actual positions, line breaks and indentation.
STATE = b"""<Rob Type="KUKA">
  <RIst X="445.0" Y="0.0" Z="990.0" A="180.0" B="0.0" C="180.0"/>
  <RSol X="445.0" Y="0.0" Z="990.0" A="180.0" B="0.0" C="180.0"/>
  <AIPos A1="0.0" A2="-90.0" A3="90.0" A4="0.0" A5="90.5" A6="-1.25E1"/>
  <ASPos A1="0.0" A2="-90.0" A3="90.0" A4="0.0" A5="90.0" A6="0.0"/>
  <Delay D="0"/>
  <IPOC>4208275638</IPOC>
</Rob>
"""


def test_a_controllers_state_gives_its_counter_and_actual_positions():
    message = parse_state(STATE)
    assert message.ipoc == 4208275638
    assert message.axes_deg == (0.0, -90.0, 90.0, 0.0, 90.5, -12.5)


def test_other_tags_read_other_elements():
    message = parse_state(STATE, RsiTags(actual_positions="ASPos"))
    assert message.axes_deg == (0.0, -90.0, 90.0, 0.0, 90.0, 0.0)


def test_a_reply_is_well_formed_xml_with_the_echoed_counter():
    corrections = (0.1234, -5.0, 12.34567, 0.0, -0.00004, 179.9999)
    packet = format_reply(4208275638, corrections)
    root = ElementTree.fromstring(packet)  # the oracle: Python's own XML parser
    assert root.tag == "Sen" and root.attrib == {"Type": "ImFree"}
    ak = root.find("AK")
    assert [float(ak.attrib[f"A{i}"]) for i in range(1, 7)] == pytest.approx(corrections, abs=5e-5)
    assert root.find("IPOC").text == "4208275638"
    back = parse_reply(packet)
    assert back.ipoc == 4208275638
    assert back.axes_deg == pytest.approx(corrections, abs=5e-5)


def test_a_formatted_state_reads_back():
    packet = format_state(7, (1.0, -2.0, 3.5, 0.0, 90.0, -179.0))
    assert ElementTree.fromstring(packet).attrib == {"Type": "KUKA"}
    assert parse_state(packet).axes_deg == (1.0, -2.0, 3.5, 0.0, 90.0, -179.0)
    with pytest.raises(BadRsiPacket, match="not one <Sen> element"):
        parse_reply(packet)  # a state is no reply


# A controller with a linear track as E1 adds its external axes' actual positions as its
# RSI configuration's DEF_EIPos declares them (E1 to E6; E1 in mm, the others unused).
STATE_WITH_TRACK = STATE.replace(
    b"  <Delay", b'  <EIPos E1="1250.5" E2="0.0" E3="0.0" E4="0.0" E5="0.0" E6="0.0"/>\n  <Delay'
)


def test_a_controller_with_a_track_gives_its_external_axis():
    message = parse_state(STATE_WITH_TRACK, external=1)
    assert message.axes_deg == (0.0, -90.0, 90.0, 0.0, 90.5, -12.5)
    assert message.external == (1250.5,)
    assert parse_state(STATE_WITH_TRACK).external == ()  # not asked for: not read
    with pytest.raises(BadRsiPacket, match="0 <EIPos> elements"):
        parse_state(STATE, external=1)  # asked for, not sent
    with pytest.raises(ValueError, match="0 to 6 axes"):
        parse_state(STATE_WITH_TRACK, external=7)


def test_a_reply_with_an_external_correction_is_the_axis_correction_objects_layout():
    """Oracle: Python's XML parser: the robot's six corrections in AK, the track's in EK
    (RSI's AXISCORREXT object reads EK.E1), one each, and it reads back."""
    packet = format_reply(12, (0.5, -1.0, 2.0, 0.0, 0.25, -3.0), external=(-340.125,))
    root = ElementTree.fromstring(packet)
    assert [e.tag for e in root] == ["AK", "EK", "IPOC"]
    assert root.find("EK").attrib == {"E1": "-340.125000"}
    back = parse_reply(packet, external=1)
    assert back.external == (-340.125,) and back.axes_deg[4] == 0.25
    state = format_state(13, (0.0,) * 6, external=(100.0, 0.0))
    assert parse_state(state, external=2).external == (100.0, 0.0)
    with pytest.raises(ValueError, match="finite external axis values"):
        format_reply(12, (0.0,) * 6, external=(float("nan"),))


def _replace(old: bytes, new: bytes) -> bytes:
    assert old in STATE
    return STATE.replace(old, new)


@pytest.mark.parametrize(
    "packet, match",
    [
        (b"x" * (MAX_RSI_BYTES + 1), "at most"),
        (STATE.replace(b"0.0", "\u00b0".encode(), 1), "not ASCII"),
        (b"<Sen Type='x'/>", "not one <Rob> element"),
        (_replace(b"AIPos", b"AIPosX"), "0 <AIPos> elements"),
        (_replace(b"<Delay", b'<AIPos A1="1"/><Delay'), "2 <AIPos> elements"),
        (_replace(b' A6="-1.25E1"', b""), "lacks axis A6"),
        (_replace(b'A5="90.5"', b'A5="90.5" A5="1"'), "repeats an attribute"),
        (_replace(b'A5="90.5"', b'A5="abc"'), "not a decimal number"),
        (_replace(b'A5="90.5"', b'A5="nan"'), "not a decimal number"),
        (_replace(b'A5="90.5"', b'A5="1e999"'), "not finite"),
        (_replace(b"<IPOC>4208275638</IPOC>", b""), "0 <IPOC> counters"),
        (_replace(b"<IPOC>4208275638</IPOC>", b"<IPOC>-3</IPOC>"), "0 <IPOC> counters"),
        (_replace(b"4208275638", b"99999999999999999999"), "exceeds 64 bits"),
        (_replace(b"<Delay", b"<IPOC>1</IPOC><Delay"), "2 <IPOC> counters"),
        (STATE[:-10], "not one <Rob> element"),
        (b'<!DOCTYPE l [<!ENTITY a "aaaa">]>' + STATE, "not one <Rob> element"),
    ],
)
def test_malformed_states_are_refused_with_the_reason(packet, match):
    with pytest.raises(BadRsiPacket, match=match):
        parse_state(packet)


@pytest.mark.parametrize(
    "root", [b'<Rob TYPE="KUKA">', b'<Rob type="kuka">', b"<Rob>", b'<Rob Type="ABB">']
)
def test_the_roots_type_attribute_is_not_required(root):
    """ROS-Industrial's kuka_rsi_simulator writes TYPE="KUKA", others none; its hardware
    interface reads no Type at all: the state parses whatever the attribute says."""
    state = parse_state(_replace(b'<Rob Type="KUKA">', root))
    assert state.ipoc == 4208275638 and len(state.axes_deg) == 6


def test_only_bytes_are_read():
    with pytest.raises(BadRsiPacket, match="must be bytes"):
        parse_state(STATE.decode())


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=600) | st.builds(lambda cut: STATE[:cut], st.integers(0, len(STATE))))
def test_garbage_raises_bad_rsi_packet_and_nothing_else(packet):
    try:
        parse_state(packet)
    except BadRsiPacket:
        pass


def test_nothing_unchecked_is_sent():
    with pytest.raises(ValueError, match="six finite"):
        format_reply(1, (0.0, 0.0, 0.0, 0.0, 0.0, float("nan")))
    with pytest.raises(ValueError, match="six finite"):
        format_reply(1, (0.0,) * 5)
    with pytest.raises(ValueError, match="IPOC"):
        format_reply(-1, (0.0,) * 6)
    with pytest.raises(ValueError, match="IPOC"):
        format_reply(2**64, (0.0,) * 6)


def test_bad_tags_are_refused():
    with pytest.raises(ValueError, match="six distinct"):
        format_reply(1, (0.0,) * 6, RsiTags(axes=("A1",) * 6))
    with pytest.raises(ValueError, match=r"RsiTags\.ipoc"):
        parse_state(STATE, RsiTags(ipoc="IP OC"))
