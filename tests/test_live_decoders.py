"""Telemetry decoders of the live layer against independent oracles.

- FGNetFDM: real packets from JSBSim's own FLIGHTGEAR output (c172p, UDP to a loopback port
  bound here), compared with JSBSim's properties at the same step, and with physics: level
  flight reads gravity, a coordinated turn has no side force and turns at g tan(phi) / V.
- X-Plane DATA: packets built with `struct` from the documented layout (little-endian int32
  row index and eight float32 per 36-byte record).
- CSV over UDP: encode/decode round trips.
- Bad packets of every protocol raise BadPacket and nothing else.
- The lever arm: rigid-body kinematics with analytic rotations.
"""

from __future__ import annotations

import math
import socket
import struct

import jsbsim
import numpy as np
import pytest

from mca_drake.live import (
    BadPacket,
    CsvDecoder,
    FgNetFdmDecoder,
    HeadPointTransfer,
    LeverArm,
    TelemetrySample,
    XPlaneDecoder,
    XPlaneLayout,
    encode_csv_sample,
    jsbsim_output_directive,
    specific_force_at,
    unpack_fgnetfdm,
)
from mca_drake.live.fgnetfdm import FGNETFDM_OFFSETS, JSBSIM_PLACEHOLDER_TIME
from mca_drake.references.jsbsim.model import QuietLogger

FT = 0.3048
G = 9.81
# JSBSim's gravity at 3000 ft is 9.78 to 9.83 m/s^2 depending on latitude.
GRAVITY_ATOL = 0.1
STEP_S = 0.01
STEPS = 150  # 1.5 s of flight per case: a few hundred packets in all
RESOLUTION_S = 0.001  # unit of the packets' cur_time

# JSBSim properties read after each step, beside the packet the step sent.
PROPERTIES = (
    "simulation/sim-time-sec",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
    "accelerations/a-pilot-x-ft_sec2",
    "accelerations/a-pilot-y-ft_sec2",
    "accelerations/a-pilot-z-ft_sec2",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "position/h-sl-ft",
    "velocities/vc-kts",
    "velocities/vt-fps",
    "aero/alpha-rad",
    "fcs/elevator-pos-norm",
    "fcs/rudder-pos-norm",
    "fcs/left-aileron-pos-norm",
    "position/h-agl-ft",
)


def _fly_and_listen(
    bank_deg: float, tmp_path, commands=None, steps: int = STEPS
) -> list[tuple[bytes, dict[str, float]]]:
    """Trims the c172p at 3000 ft and 100 kt (level, or a coordinated turn at `bank_deg`),
    flies `steps` steps with JSBSim's FLIGHTGEAR output sent to a loopback port, and returns
    each step's packet with the properties after that step. `commands`: {step: {property:
    value}} set before that step."""
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    previous_logger = jsbsim.get_logger()
    jsbsim.set_logger(QuietLogger())
    try:
        receiver.bind(("127.0.0.1", 0))  # an ephemeral port, free by construction
        port = receiver.getsockname()[1]
        directive = tmp_path / f"fgnetfdm_{port}.xml"
        directive.write_text(
            jsbsim_output_directive(port, rate_hz=1 / STEP_S, time_resolution_s=RESOLUTION_S)
        )
        fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        fdm.set_debug_level(0)
        assert fdm.load_model("c172p")
        assert fdm.set_output_directive(str(directive))
        fdm.set_dt(STEP_S)
        fdm["ic/h-agl-ft"] = 3000.0
        fdm["ic/vc-kts"] = 100.0
        fdm["ic/gamma-deg"] = 0.0
        fdm["ic/phi-deg"] = bank_deg
        assert fdm.run_ic()
        fdm["propulsion/set-running"] = -1
        fdm["fcs/mixture-cmd-norm"] = 1.0
        fdm["simulation/do_simple_trim"] = 5 if bank_deg else 1  # 5: turn, 1: full (level)
        # Packets of the initialisation (run_ic) are not paired with properties: drop them.
        receiver.setblocking(False)
        while True:
            try:
                receiver.recv(4096)
            except BlockingIOError:
                break
        receiver.settimeout(2.0)
        nodes = [fdm.get_property_manager().get_node(name) for name in PROPERTIES]
        flight = []
        for k in range(steps):
            for name, value in (commands or {}).get(k, {}).items():
                fdm[name] = value
            fdm.run()
            try:
                packet = receiver.recv(4096)
            except TimeoutError:
                pytest.fail("JSBSim sent no FLIGHTGEAR packet within 2 s of a step")
            flight.append(
                (
                    packet,
                    {n: node.get_double_value() for n, node in zip(PROPERTIES, nodes, strict=True)},
                )
            )
        return flight
    finally:
        jsbsim.set_logger(previous_logger)
        receiver.close()


@pytest.fixture(scope="module")
def level_flight(tmp_path_factory):
    return _fly_and_listen(0.0, tmp_path_factory.mktemp("level"))


@pytest.fixture(scope="module")
def turning_flight(tmp_path_factory):
    return _fly_and_listen(30.0, tmp_path_factory.mktemp("turn"))


@pytest.fixture(params=["level", "turn"])
def flight(request, level_flight, turning_flight):
    return level_flight if request.param == "level" else turning_flight


def _decode_all(flight, decoder=None):
    decoder = decoder or FgNetFdmDecoder(time_resolution_s=RESOLUTION_S)
    return [decoder.decode(packet) for packet, _ in flight]


def _pilot_f(props) -> np.ndarray:
    """JSBSim's eye-point specific force in head axes, m/s^2 (the recorder's conversion)."""
    return FT * np.array(
        [
            props["accelerations/a-pilot-x-ft_sec2"],
            -props["accelerations/a-pilot-y-ft_sec2"],
            -props["accelerations/a-pilot-z-ft_sec2"],
        ]
    )


def _body_omega(props) -> np.ndarray:
    """JSBSim's body rates in head axes, rad/s."""
    return np.array(
        [
            props["velocities/p-rad_sec"],
            -props["velocities/q-rad_sec"],
            -props["velocities/r-rad_sec"],
        ]
    )


# ------------------------------------------------------------------------- FGNetFDM vs JSBSim


def test_fgnetfdm_layout_matches_jsbsim_properties(flight):
    """Fields from the head (version, attitude, altitude) to the tail (control surfaces) of
    the layout hold what JSBSim's properties say: every offset is right."""
    for packet, props in flight:
        assert len(packet) == 408
        fields = unpack_fgnetfdm(packet)
        assert fields["version"] == 24
        assert fields["padding"] == 0
        assert fields["num_engines"] == 1  # the c172p's one piston engine
        assert fields["altitude"] == pytest.approx(props["position/h-sl-ft"] * FT, rel=1e-12)
        for name, prop in (
            ("phi", "attitude/phi-rad"),
            ("theta", "attitude/theta-rad"),
            ("alpha", "aero/alpha-rad"),
            ("vcas", "velocities/vc-kts"),
            ("elevator", "fcs/elevator-pos-norm"),
            ("rudder", "fcs/rudder-pos-norm"),
            ("A_X_pilot", "accelerations/a-pilot-x-ft_sec2"),
            ("A_Y_pilot", "accelerations/a-pilot-y-ft_sec2"),
            ("A_Z_pilot", "accelerations/a-pilot-z-ft_sec2"),
        ):
            assert fields[name] == pytest.approx(props[prop], rel=1e-6, abs=1e-7), name
        # Heading wraps at 2 pi; float32 rounding may put the packet on the other side.
        psi_error = math.remainder(fields["psi"] - props["attitude/psi-rad"], 2 * math.pi)
        assert abs(psi_error) < 1e-6
        # cur_time: simulation time in ms, truncated by JSBSim (so up to 1 ms early).
        t_ms = props["simulation/sim-time-sec"] * 1e3
        assert -1e-6 <= t_ms - fields["cur_time"] <= 1.0 + 1e-6


def test_fgnetfdm_passes_on_the_controls_and_state_jsbsim_sends(flight):
    """Oracle: the properties JSBSim filled the packet from, converted to `vehicle_signals`'
    conventions (knots, feet; its elevator and rudder positive nose down and nose left)."""
    for packet, props in flight:
        signals = FgNetFdmDecoder(time_resolution_s=RESOLUTION_S).decode(packet).signals
        expected = {
            "aileron": props["fcs/left-aileron-pos-norm"],
            "elevator": -props["fcs/elevator-pos-norm"],
            "rudder": -props["fcs/rudder-pos-norm"],
            "speed": props["velocities/vc-kts"] * 1852 / 3600,
            "roll": props["attitude/phi-rad"],
            "pitch": props["attitude/theta-rad"],
            "height": props["position/h-agl-ft"] * FT,
            "on_ground": 0.0,
        }
        assert signals == pytest.approx(expected, rel=1e-5, abs=1e-6)


def test_fgnetfdm_control_signs_are_the_motion_they_command(tmp_path):
    """Oracle: the aircraft's response. Each surface, commanded from trim for 0.5 s, is
    decoded with the sign of the rotation it causes: aileron positive and a right roll,
    elevator positive and the nose up, rudder positive and the nose right."""
    steps = {
        10: {"fcs/aileron-cmd-norm": 0.5},
        60: {"fcs/aileron-cmd-norm": 0.0, "fcs/elevator-cmd-norm": -0.3},
        110: {"fcs/elevator-cmd-norm": 0.0, "fcs/rudder-cmd-norm": -0.4},
    }
    flight = _fly_and_listen(0.0, tmp_path, commands=steps, steps=160)
    samples = _decode_all(flight)
    for name, rate, at in (("aileron", 0, 59), ("elevator", 1, 109), ("rudder", 2, 159)):
        # the change from where the surface was before its command (the elevator is trimmed)
        change = samples[at].signals[name] - samples[at - 50].signals[name]
        body_rate = _body_omega(flight[at][1])[rate]  # head axes: x fwd, y left, z up
        nose_up_or_right = -body_rate if name != "aileron" else body_rate
        assert change > 0.2 and nose_up_or_right > 0.02, (name, change, body_rate)


def test_fgnetfdm_decodes_to_jsbsim_body_rates_and_eye_point_force(flight):
    """Body rates rebuilt from the packet's Euler-angle rates, and the eye-point specific
    force, equal JSBSim's own properties in head axes to float32 precision."""
    samples = _decode_all(flight)
    for sample, (_, props) in zip(samples, flight, strict=True):
        np.testing.assert_allclose(sample.omega, _body_omega(props), rtol=0, atol=1e-6)
        np.testing.assert_allclose(sample.f, _pilot_f(props), rtol=1e-6, atol=1e-5)
        t = props["simulation/sim-time-sec"]
        assert 0.0 <= t - sample.t_s <= RESOLUTION_S + 1e-9
        assert sample.time_source == "sender"
        assert sample.sequence is None


def test_fgnetfdm_level_flight_reads_gravity(level_flight):
    """Trimmed cruise: f = g (sin theta, sin phi cos theta, cos phi cos theta) in head axes,
    about (0, 0, +9.81), and no rotation."""
    for sample, (_, props) in zip(_decode_all(level_flight), level_flight, strict=True):
        phi, theta = props["attitude/phi-rad"], props["attitude/theta-rad"]
        g = np.linalg.norm(sample.f)
        assert g == pytest.approx(G, abs=GRAVITY_ATOL)
        expected = g * np.array(
            [math.sin(theta), math.sin(phi) * math.cos(theta), math.cos(phi) * math.cos(theta)]
        )
        np.testing.assert_allclose(sample.f, expected, atol=0.02)
        np.testing.assert_allclose(sample.f, [0.0, 0.0, G], atol=GRAVITY_ATOL)
        np.testing.assert_allclose(sample.omega, 0.0, atol=1e-3)


def test_fgnetfdm_coordinated_turn_has_no_side_force(turning_flight):
    """A trimmed 30 deg right turn: f_y ~ 0, |f| = g / cos(phi), and the turn rate
    psidot = g tan(phi) / V about the vertical, seen in head axes (z up: a right turn is a
    negative rotation about z)."""
    for sample, (_, props) in zip(_decode_all(turning_flight), turning_flight, strict=True):
        phi, theta = props["attitude/phi-rad"], props["attitude/theta-rad"]
        assert phi == pytest.approx(math.radians(30.0), abs=0.01)
        assert sample.f[1] == pytest.approx(0.0, abs=0.05)
        assert np.linalg.norm(sample.f) == pytest.approx(G / math.cos(phi), abs=GRAVITY_ATOL)
        psidot = G * math.tan(phi) / (props["velocities/vt-fps"] * FT)
        expected = psidot * np.array(
            [-math.sin(theta), -math.cos(theta) * math.sin(phi), -math.cos(theta) * math.cos(phi)]
        )
        np.testing.assert_allclose(sample.omega, expected, rtol=0.02, atol=1e-3)


def test_fgnetfdm_without_time_uses_arrival(level_flight):
    packet = bytearray(level_flight[0][0])
    struct.pack_into(">I", packet, FGNETFDM_OFFSETS["cur_time"], JSBSIM_PLACEHOLDER_TIME)
    sample = FgNetFdmDecoder().decode(bytes(packet), received_s=12.5)
    assert sample.t_s == 12.5
    assert sample.time_source == "arrival"
    # a decoder set for the time directive (the packaged live scenarios) still takes
    # JSBSim's default stream, whose packets carry the placeholder: timed by arrival
    timed = FgNetFdmDecoder(time_resolution_s=RESOLUTION_S).decode(bytes(packet), 7.25)
    assert timed.t_s == 7.25 and timed.time_source == "arrival"
    np.testing.assert_array_equal(timed.f, sample.f)
    # and FlightGear's native-fdm output, whose cur_time is Unix time in whole seconds
    # (2026-11-30 12:00 UTC): not 20 days of simulation at 1 ms, timed by arrival too
    flightgear = _patched(bytes(packet), "cur_time", "I", 1_796_040_000)
    timed = FgNetFdmDecoder(time_resolution_s=RESOLUTION_S).decode(flightgear, 3.5)
    assert timed.t_s == 3.5 and timed.time_source == "arrival"
    # a long flight's own simulation time (10 h at 1 ms) is still the sender's
    long_flight = _patched(bytes(packet), "cur_time", "I", 36_000_000)
    timed = FgNetFdmDecoder(time_resolution_s=RESOLUTION_S).decode(long_flight, 3.5)
    assert timed.t_s == pytest.approx(36_000.0) and timed.time_source == "sender"


def _patched(packet: bytes, field: str, code: str, value) -> bytes:
    patched = bytearray(packet)
    struct.pack_into(">" + code, patched, FGNETFDM_OFFSETS[field], value)
    return bytes(patched)


def test_fgnetfdm_bad_packets_raise_bad_packet(level_flight, rng):
    good = level_flight[-1][0]
    decoder = FgNetFdmDecoder(time_resolution_s=RESOLUTION_S)
    decoder.decode(good)
    cases = {
        "too short for its version": b"",
        "too short for its version ": good[:3],
        "408 bytes": good[:-1],
        "408 bytes ": good + b"\0",
        "version 25": _patched(good, "version", "I", 25),
        "little-endian": struct.pack("<I", 24) + good[4:],
        "non-finite values: A_X_pilot": _patched(good, "A_X_pilot", "f", math.nan),
        "non-finite values: phidot": _patched(good, "phidot", "f", math.inf),
        "exceeds": _patched(good, "A_Z_pilot", "f", 1e30),
        "must be bytes": "not bytes",
    }
    for match, packet in cases.items():
        with pytest.raises(BadPacket, match=match.strip()):
            decoder.decode(packet)
    # Random garbage, of the right size and of others: BadPacket and nothing else.
    for size in (408, 408, 407, 409, 100, 1000, 4):
        garbage = rng.integers(0, 256, size=size, dtype=np.uint8).tobytes()
        with pytest.raises(BadPacket):
            decoder.decode(garbage)
    # Garbage behind a valid version word still fails on its values or its time.
    failures = 0
    for _ in range(50):
        garbage = struct.pack(">I", 24) + rng.integers(0, 256, 404, dtype=np.uint8).tobytes()
        try:
            decoder.decode(garbage)
        except BadPacket:
            failures += 1
    assert failures >= 45  # a random float32 is beyond 20 g or non-finite nearly always


# ------------------------------------------------------------------------------------ X-Plane


def _xplane_packet(rows: dict[int, list[float]]) -> bytes:
    """A DATA packet as the X-Plane documentation lays it out: "DATA", X-Plane's internal
    byte, then per row its int32 index and eight float32, all little-endian."""
    body = b"".join(
        struct.pack("<i8f", index, *(values + [-999.0] * (8 - len(values))))
        for index, values in rows.items()
    )
    return b"DATA" + b"@" + body


def _load_row(normal: float, axial: float, side: float) -> list[float]:
    # Mach, (unused), VVI ft/min, (unused), normal, axial, side g, (unused)
    return [0.2, -999.0, 0.0, -999.0, normal, axial, side, -999.0]


@pytest.mark.parametrize("version", [11, 12])
def test_xplane_level_flight_reads_gravity(version):
    packet = _xplane_packet({4: _load_row(1.0, 0.0, 0.0), 16: [0.0, 0.0, 0.0]})
    sample = XPlaneDecoder(version=version).decode(packet, received_s=3.25)
    np.testing.assert_array_equal(sample.f, [0.0, 0.0, G])
    np.testing.assert_array_equal(sample.omega, [0.0, 0.0, 0.0])
    assert sample.t_s == 3.25
    assert sample.time_source == "arrival"


def test_xplane_passes_on_speed_attitude_and_height_where_ticked():
    """Oracle: the Data Output rows as X-Plane documents them (3: speeds, kias first; 17:
    pitch, roll, headings in degrees; 20: lat, lon, altitude MSL, AGL in feet), converted
    by hand."""
    rows = {4: _load_row(1.0, 0.0, 0.0), 16: [0.0] * 8}
    rows[3] = [120.0, 118.0, 125.0, 130.0, -999.0, 138.0, 144.0, 150.0]
    rows[17] = [5.0, -30.0, 90.0, 92.0, -999.0, -999.0, -999.0, -999.0]
    rows[20] = [47.0, 8.0, 3500.0, 1000.0, -999.0, -999.0, -999.0, -999.0]
    sample = XPlaneDecoder(version=12).decode(_xplane_packet(rows))
    assert sample.signals == pytest.approx(
        {
            "speed": 120.0 * 1852 / 3600,
            "pitch": math.radians(5.0),
            "roll": math.radians(-30.0),
            "height": 304.8,
        }
    )
    bare = XPlaneDecoder(version=12).decode(_xplane_packet({4: rows[4], 16: rows[16]}))
    assert bare.signals == {}


def test_xplane_passes_on_the_pilots_controls_where_ticked():
    """Oracle: rows 8 (joystick: elev, ailrn, ruddr ratios) and 25 (commanded throttle per
    engine) as X-Plane lists them; a ratio outside its range is left out."""
    rows = {4: _load_row(1.0, 0.0, 0.0), 16: [0.0] * 8}
    rows[8] = [0.25, -0.5, 0.125, -999.0, -999.0, -999.0, -999.0, -999.0]
    rows[25] = [0.75, 0.7, -999.0, -999.0, -999.0, -999.0, -999.0, -999.0]
    sample = XPlaneDecoder(version=12).decode(_xplane_packet(rows))
    assert sample.signals == {"elevator": 0.25, "aileron": -0.5, "rudder": 0.125, "throttle": 0.75}
    rows[25][0] = 75.0  # a percentage is not a ratio
    assert "throttle" not in XPlaneDecoder(version=12).decode(_xplane_packet(rows)).signals


def test_xplane_rows_round_trip_per_version(rng):
    """X-Plane 11 sends Q, P, R in rad/s; X-Plane 12 P, Q, R in deg/s: both decode to the same
    head-frame omega = (P, -Q, -R) rad/s, and f = g (-axial, -side, normal)."""
    for _ in range(20):
        p, q, r = rng.uniform(-1.5, 1.5, size=3)
        normal, axial, side = rng.uniform(-3.0, 3.0, size=3)
        load = _load_row(normal, axial, side)
        extra = {3: [100.0, 101.0, 102.0], 17: [2.0, -5.0, 270.0, 268.0]}  # other rows: ignored
        packets = {
            11: _xplane_packet({16: [q, p, r], **extra, 4: load}),
            12: _xplane_packet({**extra, 4: load, 16: list(np.degrees([p, q, r]))}),
        }
        for version, packet in packets.items():
            sample = XPlaneDecoder(version=version).decode(packet, received_s=0.0)
            np.testing.assert_allclose(sample.omega, [p, -q, -r], rtol=1e-6, atol=1e-7)
            np.testing.assert_allclose(
                sample.f, G * np.array([-axial, -side, normal]), rtol=1e-6, atol=1e-6
            )


def test_xplane_layout_signs_are_switchable():
    layout = XPlaneLayout(axial_positive_aft=False, side_positive_right=False)
    packet = _xplane_packet({4: _load_row(1.0, 0.5, 0.25), 16: [0.0, 0.0, 0.0]})
    sample = XPlaneDecoder(layout=layout).decode(packet, received_s=0.0)
    np.testing.assert_allclose(sample.f, G * np.array([0.5, 0.25, 1.0]), rtol=1e-6)


def test_xplane_decoder_needs_its_version():
    with pytest.raises(ValueError, match="exactly one of version"):
        XPlaneDecoder()
    with pytest.raises(ValueError, match="exactly one of version"):
        XPlaneDecoder(version=12, layout=XPlaneLayout())
    with pytest.raises(ValueError, match="valid: 11, 12"):
        XPlaneDecoder(version=10)
    with pytest.raises(ValueError, match="rate_unit"):
        XPlaneDecoder(layout=XPlaneLayout(rate_unit="rpm"))


def test_xplane_bad_packets_raise_bad_packet(rng):
    decoder = XPlaneDecoder(version=12)
    good = _xplane_packet({4: _load_row(1.0, 0.0, 0.0), 16: [1.0, 2.0, 3.0]})
    decoder.decode(good, received_s=0.0)
    nan_rate = _xplane_packet({4: _load_row(1.0, 0.0, 0.0), 16: [math.nan, 0.0, 0.0]})
    nan_load = _xplane_packet({4: _load_row(math.inf, 0.0, 0.0), 16: [0.0, 0.0, 0.0]})
    cases = {
        "lacks row 4 \\(Mach, VVI, g-load\\)": _xplane_packet({16: [0.0, 0.0, 0.0]}),
        "lacks row 16 \\(angular velocities\\)": _xplane_packet({4: _load_row(1, 0, 0)}),
        "lacks row 4 .*, 16": _xplane_packet({3: [1.0]}),
        "not b'DATA'": b"DATB" + good[4:],
        "not b'DATA' ": good[:3],
        "truncated": good[:-1],
        "truncated ": good[:5],
        "twice": _xplane_packet({4: _load_row(1, 0, 0), 16: [0.0]}) + good[5:41],
        "P \\(row 16 slot 0\\) = nan": nan_rate,
        "normal load \\(row 4 slot 4\\) = inf": nan_load,
        "exceeds": _xplane_packet({4: _load_row(1e6, 0, 0), 16: [0.0, 0.0, 0.0]}),
        "must be bytes": None,
    }
    for match, packet in cases.items():
        with pytest.raises(BadPacket, match=match.strip()):
            decoder.decode(packet, received_s=0.0)
    for size in (0, 5, 41, 77, 200):
        garbage = rng.integers(0, 256, size=size, dtype=np.uint8).tobytes()
        with pytest.raises(BadPacket):
            decoder.decode(garbage, received_s=0.0)


# ---------------------------------------------------------------------------------------- CSV


def test_csv_round_trip_is_exact(rng):
    decoder = CsvDecoder()
    for _ in range(200):
        t = float(rng.uniform(0, 1e5))
        omega = rng.normal(scale=rng.choice([1e-6, 1.0, 5.0]), size=3)
        f = rng.normal(scale=10.0, size=3)
        datagram = encode_csv_sample(t, omega, f)
        assert datagram.endswith(b"\n") and datagram.count(b"\n") == 1
        assert len(datagram.split(b",")) == 7
        sample = decoder.decode(datagram, received_s=-1.0)
        assert sample.t_s == t  # the sender's time, not the arrival
        assert sample.time_source == "sender"
        np.testing.assert_array_equal(sample.omega, omega)
        np.testing.assert_array_equal(sample.f, f)


def test_csv_accepts_the_documented_variants():
    decoder = CsvDecoder()
    for datagram in (
        b"1.5,0,0,0,0,0,9.81",
        b"1.5,0,0,0,0,0,9.81\r\n",
        b" 1.5 ,\t0, 0 ,0,0.0,-0.0,+981e-2\n",
        b"1.5,.0,0.,0e0,0,0,9.81",
    ):
        sample = decoder.decode(datagram)
        assert sample.t_s == 1.5
        np.testing.assert_array_equal(sample.f, [0.0, 0.0, 9.81])


def test_csv_bad_datagrams_raise_bad_packet():
    decoder = CsvDecoder()
    cases = {
        "6 fields": b"0,0,0,0,0,0",
        "8 fields": b"0,0,0,0,0,0,9.81,1",
        "1 fields": b"",
        "field f_z is not a decimal number": b"0,0,0,0,0,0,nan",
        "field omega_x is not a decimal number": b"0,inf,0,0,0,0,9.81",
        "field t is not a decimal number": b"1_0,0,0,0,0,0,9.81",
        "field omega_y is not a decimal number": b"0,0,0x10,0,0,0,9.81",
        "field f_x is not a decimal number": b"0,0,0,0,,0,9.81",
        "field t overflows": b"1e999,0,0,0,0,0,9.81",
        "not ASCII": "0,0,0,0,0,0,9.81\u00b0".encode(),
        "at most 512": b"0," * 300 + b"0",
        "exceeds": b"0,0,0,0,0,0,1e6",
        "two lines": b"0,0,0,0,0,0,9.81\n0,0,0,0,0,0,9.81\n",
    }
    for match, datagram in cases.items():
        if match == "two lines":
            match = "fields"  # the second line adds fields to the last one
        with pytest.raises(BadPacket, match=match):
            decoder.decode(datagram)


def test_csv_encoder_rejects_what_it_cannot_send():
    with pytest.raises(ValueError, match="non-finite"):
        encode_csv_sample(0.0, [0.0, math.nan, 0.0], [0.0, 0.0, G])
    with pytest.raises(ValueError, match="shape"):
        encode_csv_sample(0.0, [0.0, 0.0], [0.0, 0.0, G])
    with pytest.raises(ValueError, match="finite"):
        encode_csv_sample(math.inf, [0.0, 0.0, 0.0], [0.0, 0.0, G])


# ------------------------------------------------------------------------------ the lever arm


def test_zero_lever_arm_leaves_samples_alone():
    sample = TelemetrySample(0.0, [0.3, -0.2, 0.1], [1.0, 2.0, 9.0])
    assert HeadPointTransfer(LeverArm()).apply(sample) is sample


@pytest.mark.parametrize("estimate", ["zero", "finite_difference"])
def test_steady_rotation_adds_the_centripetal_force(estimate):
    """Yawing steadily at w (z up) with the head 1.2 m ahead of the CG: the head's specific
    force gains -w^2 * 1.2 along x (towards the axis), whatever the alpha estimate."""
    w = 0.8
    decoder = CsvDecoder(lever_arm=LeverArm(p_SH_H=[1.2, 0.0, 0.0], angular_acceleration=estimate))
    for k in range(5):
        sample = decoder.decode(encode_csv_sample(0.01 * k, [0.0, 0.0, w], [0.5, 0.0, G]))
        np.testing.assert_allclose(sample.f, [0.5 - w * w * 1.2, 0.0, G], atol=1e-12)


def test_finite_difference_angular_acceleration_matches_analytic_roll():
    """Rolling as omega_x = A sin(W t) with the head 0.8 m above the source point: the head's
    specific force gains alpha x p = (0, -0.8 alpha_x, 0) and omega x (omega x p) =
    (0, 0, -0.8 omega_x^2). The backward difference estimates alpha half a step back."""
    amplitude, frequency, dt, height = 0.5, 2.0, 0.01, 0.8
    decoder = CsvDecoder(lever_arm=LeverArm(p_SH_H=[0.0, 0.0, height]))
    for k in range(200):
        t = k * dt
        omega_x = amplitude * math.sin(frequency * t)
        sample = decoder.decode(encode_csv_sample(t, [omega_x, 0.0, 0.0], [0.0, 0.0, G]))
        if k == 0:
            alpha_x = 0.0  # no history yet
        else:
            alpha_x = amplitude * frequency * math.cos(frequency * (t - dt / 2))
        # Truncation error of the difference: A W^3 dt^2 / 24 * height, 1.3e-5 m/s^2 here.
        assert sample.f[1] == pytest.approx(-height * alpha_x, abs=3e-5)
        assert sample.f[2] == pytest.approx(G - height * omega_x**2, abs=1e-12)
        assert sample.f[0] == pytest.approx(0.0, abs=1e-12)


def test_finite_difference_handles_gaps_and_bunched_arrivals():
    transfer = HeadPointTransfer(LeverArm(p_SH_H=[0.0, 0.0, 1.0]))

    def alpha(t, omega_x):
        return transfer.angular_acceleration(TelemetrySample(t, [omega_x, 0, 0], [0, 0, G]))

    np.testing.assert_array_equal(alpha(0.0, 0.0), 0.0)  # first sample: no history
    np.testing.assert_allclose(alpha(0.01, 0.02), [2.0, 0.0, 0.0])
    np.testing.assert_allclose(alpha(0.0105, 0.5), [2.0, 0.0, 0.0])  # bunched: kept
    np.testing.assert_array_equal(alpha(0.5, 0.6), 0.0)  # a 0.49 s gap: no difference
    np.testing.assert_array_equal(alpha(0.2, 0.6), 0.0)  # time going back: a restart
    np.testing.assert_allclose(alpha(0.21, 0.61), [1.0, 0.0, 0.0])
    transfer.reset()
    np.testing.assert_array_equal(alpha(0.22, 0.0), 0.0)


def test_specific_force_at_is_rigid_body_kinematics(rng):
    """Oracle: differentiate the head's position p_WH(t) = p_WS(t) + R(t) p_SH twice
    numerically for a body spinning about a fixed axis with growing rate; the difference of
    the two points' accelerations is what `specific_force_at` adds (gravity cancels)."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    p_SH = rng.normal(size=3)
    w0, w_dot, t, h = 0.7, 1.3, 0.4, 1e-4

    def rotation(time):
        angle = w0 * time + 0.5 * w_dot * time**2
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k

    # World acceleration of the offset, then into body axes.
    offset = [rotation(t + d) @ p_SH for d in (-h, 0.0, h)]
    a_W = (offset[0] - 2 * offset[1] + offset[2]) / h**2
    a_body = rotation(t).T @ a_W
    omega = (w0 + w_dot * t) * axis  # a fixed axis: body and world components agree
    alpha = w_dot * axis
    f_S = np.array([0.1, -0.2, 9.8])
    np.testing.assert_allclose(specific_force_at(f_S, omega, alpha, p_SH) - f_S, a_body, atol=1e-5)


def test_lever_arm_settings_are_checked():
    with pytest.raises(ValueError, match="valid: finite_difference, zero"):
        HeadPointTransfer(LeverArm(angular_acceleration="kalman"))
    with pytest.raises(ValueError, match="3 numbers"):
        HeadPointTransfer(LeverArm(p_SH_H=[1.0, 0.0]))
    with pytest.raises(ValueError, match="finite"):
        HeadPointTransfer(LeverArm(p_SH_H=[math.nan, 0.0, 0.0]))
    with pytest.raises(ValueError, match="min_difference_dt_s"):
        HeadPointTransfer(LeverArm(min_difference_dt_s=0.2))


def test_telemetry_sample_is_checked_and_read_only():
    sample = TelemetrySample(1, [0, 0, 0], [0, 0, G], sequence=7.0)
    assert sample.sequence == 7 and isinstance(sample.t_s, float)
    with pytest.raises(TypeError):  # a tuple: no item assignment
        sample.f[2] = 0.0
    with pytest.raises(ValueError, match="shape"):
        TelemetrySample(0.0, [0, 0], [0, 0, G])
    with pytest.raises(ValueError, match="non-finite"):
        TelemetrySample(0.0, [0, 0, 0], [0, math.nan, G])
    with pytest.raises(ValueError, match="time_source"):
        TelemetrySample(0.0, [0, 0, 0], [0, 0, G], time_source="gps")


def test_output_directive_is_checked():
    text = jsbsim_output_directive(5550, rate_hz=60.0, time_resolution_s=None)
    assert 'type="FLIGHTGEAR"' in text and 'port="5550"' in text and "<time" not in text
    with pytest.raises(ValueError, match="port"):
        jsbsim_output_directive(0)
    with pytest.raises(ValueError, match="time_resolution_s"):
        jsbsim_output_directive(5550, time_resolution_s=2.0)
