"""Racing-simulator telemetry decoders against packets built here, with `struct`, from the
protocols' documented layouts (BeamNG.drive MotionSim, Live for Speed OutSim and OutSim 2,
F1 23/24 Motion and Motion Ex), not from the decoders' own tables:

- physics: a level car at rest reads f = (0, 0, +9.81) and omega = 0; a yaw rate, braking and
  the lateral acceleration of a left turn land in the right head-frame channel with the right
  sign; LFS's world-axis vectors are rotated into the car (an independent rotation oracle);
- bad packets raise BadPacket, and random bytes raise nothing else;
- each protocol over a loopback UDP socket into the live receiver, to its reference.
"""

from __future__ import annotations

import math
import socket
import struct

import numpy as np
import pytest

from mca_drake.live import (
    BadPacket,
    BeamNGConfig,
    BeamNGDecoder,
    F1Config,
    F1Decoder,
    OutSimConfig,
    OutSimDecoder,
)

G = 9.81

# ------------------------------------------------------------------------------------ BeamNG
# "BNG1", then 21 little-endian float32: pos, vel, acc (gravity not included), up vector,
# rollPos/pitchPos/yawPos, rollVel/pitchVel/yawVel, rollAcc/pitchAcc/yawAcc.


def beamng_packet(
    *,
    acc=(0.0, 0.0, 0.0),
    angles=(0.0, 0.0, 0.0),
    rates=(0.0, 0.0, 0.0),
    up=(0.0, 0.0, 1.0),
    magic=b"BNG1",
) -> bytes:
    pos, vel, angular_acc = (10.0, -20.0, 3.0), (25.0, 1.0, 0.0), (0.0, 0.0, 0.0)
    values = (*pos, *vel, *acc, *up, *angles, *rates, *angular_acc)
    return magic + struct.pack("<21f", *values)


def test_beamng_level_car_at_rest_reads_gravity():
    sample = BeamNGDecoder().decode(beamng_packet(), received_s=2.5)
    np.testing.assert_allclose(sample.f, [0.0, 0.0, G], atol=1e-12)
    np.testing.assert_allclose(sample.omega, [0.0, 0.0, 0.0], atol=1e-12)
    assert sample.t_s == 2.5 and sample.time_source == "arrival"


def test_beamng_passes_on_speed_and_attitude():
    """Oracle: the documented velX, velY, velZ (world m/s; the packet's (25, 1, 0)) and
    rollPos, pitchPos (rad), with the decoder's default signs and switched ones."""
    packet = beamng_packet(angles=(0.125, -0.25, 2.0))
    sample = BeamNGDecoder().decode(packet, received_s=0.0)
    speed = math.hypot(25.0, 1.0)
    assert sample.signals == pytest.approx({"speed": speed, "roll": 0.125, "pitch": -0.25})
    flipped = BeamNGDecoder(
        config=BeamNGConfig(
            roll_angle_positive_right_down=False, pitch_angle_positive_nose_up=False
        )
    ).decode(packet, received_s=0.0)
    assert flipped.signals == pytest.approx({"speed": speed, "roll": -0.125, "pitch": 0.25})


@pytest.mark.parametrize(
    "packet, omega, f",
    [
        # turning left at 0.5 rad/s: yawVel is positive nose right
        (beamng_packet(rates=(0.0, 0.0, -0.5)), [0.0, 0.0, 0.5], [0.0, 0.0, G]),
        # braking at 6 m/s^2: accY is the forward acceleration
        (beamng_packet(acc=(0.0, -6.0, 0.0)), [0.0, 0.0, 0.0], [-6.0, 0.0, G]),
        # a left turn's 4 m/s^2 towards the left: accX is positive to the right
        (beamng_packet(acc=(-4.0, 0.0, 0.0)), [0.0, 0.0, 0.0], [0.0, 4.0, G]),
        # cresting a hill, 2 m/s^2 downwards: accZ is positive down
        (beamng_packet(acc=(0.0, 0.0, 2.0)), [0.0, 0.0, 0.0], [0.0, 0.0, G - 2.0]),
        # rolling right side down at 0.3 rad/s, pitching nose up at 0.2 rad/s
        (beamng_packet(rates=(0.3, 0.2, 0.0)), [0.3, -0.2, 0.0], [0.0, 0.0, G]),
    ],
    ids=["yaw-left", "braking", "left-turn", "crest", "roll-pitch"],
)
def test_beamng_channels_and_signs(packet, omega, f):
    sample = BeamNGDecoder().decode(packet, received_s=0.0)
    np.testing.assert_allclose(sample.omega, omega, atol=1e-6)
    np.testing.assert_allclose(sample.f, f, atol=1e-5)


def test_beamng_tilt_puts_gravity_into_the_car_axes():
    """At rest nose up by 0.2 rad an accelerometer reads g sin(0.2) forward; rolled right side
    down by 0.3 rad it reads g sin(0.3) towards the (raised) left."""
    nose_up = BeamNGDecoder().decode(beamng_packet(angles=(0.0, 0.2, 1.0)), received_s=0.0)
    np.testing.assert_allclose(nose_up.f, G * np.array([math.sin(0.2), 0.0, math.cos(0.2)]))
    right_down = BeamNGDecoder().decode(beamng_packet(angles=(0.3, 0.0, 0.0)), received_s=0.0)
    np.testing.assert_allclose(right_down.f, G * np.array([0.0, math.sin(0.3), math.cos(0.3)]))


def test_beamng_config_switches_each_sign():
    config = BeamNGConfig(
        roll_angle_positive_right_down=False,
        pitch_angle_positive_nose_up=False,
        roll_rate_positive_right_down=False,
        pitch_rate_positive_nose_up=False,
        yaw_rate_positive_nose_right=False,
    )
    packet = beamng_packet(angles=(0.3, 0.2, 0.0), rates=(0.1, 0.2, 0.5))
    default = BeamNGDecoder().decode(packet, received_s=0.0)
    flipped = BeamNGDecoder(config=config).decode(packet, received_s=0.0)
    np.testing.assert_allclose(flipped.omega, -np.array(default.omega), atol=1e-7)
    np.testing.assert_allclose(flipped.f[:2], -np.array(default.f[:2]), atol=1e-6)
    assert flipped.f[2] == pytest.approx(default.f[2])
    with pytest.raises(ValueError, match=r"BeamNGConfig\.yaw_rate_positive_nose_right"):
        BeamNGDecoder(config=BeamNGConfig(yaw_rate_positive_nose_right="yes"))


def test_beamng_bad_packets_raise_bad_packet():
    decoder = BeamNGDecoder()
    good = beamng_packet()
    cases = {
        "88 bytes starting b'BNG1'": good[:-1],
        "of 4 bytes": good[:4],
        "starting b'BNG2'": beamng_packet(magic=b"BNG2"),
        "accY = nan": beamng_packet(acc=(0.0, math.nan, 0.0)),
        "yawVel = inf": beamng_packet(rates=(0.0, 0.0, math.inf)),
        "exceeds 196.2 m/s": beamng_packet(acc=(1e4, 0.0, 0.0)),
        "exceeds 35 rad/s": beamng_packet(rates=(90.0, 0.0, 0.0)),
        "degrees": beamng_packet(angles=(30.0, 0.0, 0.0)),
        "at most 88": good + b"\0",
    }
    for match, packet in cases.items():
        with pytest.raises(BadPacket, match=match):
            decoder.decode(packet, received_s=0.0)


# ------------------------------------------------------------------------- Live for Speed
# OutSimPack: uint32 Time (ms), AngVel (3 float), Heading, Pitch, Roll (float), Accel,
# Vel (3 float each), Pos (3 int32, 1 m = 65536), [int32 ID]; world axes, Z up.


def outsim_main(
    *, ang_vel=(0.0, 0.0, 0.0), angles=(0.0, 0.0, 0.0), accel=(0.0, 0.0, 0.0), vel=(0.0, 0.0, 0.0)
):
    """OutSimMain: AngVel, Heading, Pitch, Roll, Accel, Vel, Pos (60 bytes)."""
    pos = (65536 * 100, -65536 * 40, 65536 * 2)
    return struct.pack("<3f3f3f3f3i", *ang_vel, *angles, *accel, *vel, *pos)


def outsim_packet(time_ms: int = 12345, *, outsim_id: int | None = None, **main) -> bytes:
    packet = struct.pack("<I", time_ms) + outsim_main(**main)
    return packet if outsim_id is None else packet + struct.pack("<i", outsim_id)


def rotation_world_from_car(heading: float, pitch: float, roll: float) -> np.ndarray:
    """LFS's attitude as a matrix, composed here from elementary rotations: heading about
    world Z, then pitch about the car's X (right), then roll about its Y (forward)."""

    def about(axis, angle):
        k = np.zeros((3, 3))
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        k[j, i], k[i, j] = 1.0, -1.0
        return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k

    return about(2, heading) @ about(0, pitch) @ about(1, roll)


def car_to_head(v_car) -> np.ndarray:
    """LFS car axes (right, forward, up) to head axes (forward, left, up)."""
    return np.array([v_car[1], -v_car[0], v_car[2]])


@pytest.mark.parametrize("outsim_id", [None, 7])
def test_outsim_level_car_at_rest_reads_gravity(outsim_id):
    packet = outsim_packet(2500, outsim_id=outsim_id, angles=(1.2, 0.0, 0.0))
    assert len(packet) == (64 if outsim_id is None else 68)
    sample = OutSimDecoder().decode(packet, received_s=99.0)
    np.testing.assert_allclose(sample.f, [0.0, 0.0, G], atol=1e-6)
    np.testing.assert_allclose(sample.omega, [0.0, 0.0, 0.0], atol=1e-12)
    assert sample.t_s == 2.5 and sample.time_source == "sender"


def test_outsim_heading_90_rotates_world_acceleration_into_the_car():
    """Heading 90 deg (anticlockwise from world Y) faces world -X, its left is world -Y:
    accelerating along world -X is accelerating forward, along world -Y is to the left."""
    decoder = OutSimDecoder()
    forward = decoder.decode(outsim_packet(angles=(math.pi / 2, 0, 0), accel=(-3.0, 0, 0)))
    np.testing.assert_allclose(forward.f, [3.0, 0.0, G], atol=1e-6)
    left = decoder.decode(outsim_packet(angles=(math.pi / 2, 0, 0), accel=(0, -2.0, 0)))
    np.testing.assert_allclose(left.f, [0.0, 2.0, G], atol=1e-6)


@pytest.mark.parametrize(
    "main, omega, f",
    [
        # yawing left at 0.5 rad/s about world Z
        ({"ang_vel": (0.0, 0.0, 0.5)}, [0.0, 0.0, 0.5], [0.0, 0.0, G]),
        # heading 0 faces world +Y: braking at 6 m/s^2 is Accel (0, -6, 0)
        ({"accel": (0.0, -6.0, 0.0)}, [0.0, 0.0, 0.0], [-6.0, 0.0, G]),
        # a left turn: 4 m/s^2 towards world -X, the car's left at heading 0
        ({"accel": (-4.0, 0.0, 0.0)}, [0.0, 0.0, 0.0], [0.0, 4.0, G]),
        # heading 180: the same left turn is towards world +X
        ({"angles": (math.pi, 0, 0), "accel": (4.0, 0, 0)}, [0, 0, 0], [0.0, 4.0, G]),
    ],
    ids=["yaw-left", "braking", "left-turn", "left-turn-heading-180"],
)
def test_outsim_channels_and_signs(main, omega, f):
    sample = OutSimDecoder().decode(outsim_packet(**main), received_s=0.0)
    np.testing.assert_allclose(sample.omega, omega, atol=1e-6)
    np.testing.assert_allclose(sample.f, f, atol=1e-5)


def test_outsim_pitch_and_roll_follow_the_documented_senses():
    """Pitch anticlockwise from the right is nose up (gravity reads forward); roll
    anticlockwise from the front is right side down (gravity reads to the left)."""
    nose_up = OutSimDecoder().decode(outsim_packet(angles=(0.7, 0.2, 0.0)))
    np.testing.assert_allclose(
        nose_up.f, G * np.array([math.sin(0.2), 0, math.cos(0.2)]), atol=1e-5
    )
    right_down = OutSimDecoder().decode(outsim_packet(angles=(-2.0, 0.0, 0.3)))
    np.testing.assert_allclose(
        right_down.f, G * np.array([0, math.sin(0.3), math.cos(0.3)]), atol=1e-5
    )


def test_outsim_rotates_any_attitude_like_the_oracle(rng):
    decoder = OutSimDecoder()
    for _ in range(50):
        heading, pitch, roll = rng.uniform(-math.pi, math.pi), *rng.uniform(-0.6, 0.6, size=2)
        ang_vel, accel = rng.normal(scale=0.8, size=3), rng.normal(scale=5.0, size=3)
        packet = outsim_packet(angles=(heading, pitch, roll), ang_vel=ang_vel, accel=accel)
        sample = decoder.decode(packet, received_s=0.0)
        # the packet's float32 values, as the decoder reads them
        ang_vel, accel = np.float32(ang_vel).astype(float), np.float32(accel).astype(float)
        heading, pitch, roll = np.float32([heading, pitch, roll]).astype(float)
        r_wc = rotation_world_from_car(heading, pitch, roll)
        np.testing.assert_allclose(sample.omega, car_to_head(r_wc.T @ ang_vel), atol=1e-9)
        f_world = accel + np.array([0.0, 0.0, G])
        np.testing.assert_allclose(sample.f, car_to_head(r_wc.T @ f_world), atol=1e-9)


def test_outsim_passes_on_speed_attitude_and_pedals():
    """Oracle: OutSimMain's Vel (world m/s), Pitch and Roll (rad), and OutSimInputs'
    Throttle and Brake (the first two of its five floats), as LFS documents them."""
    main = outsim_main(angles=(0.5, 0.125, -0.25), vel=(3.0, -4.0, 12.0))
    classic = OutSimDecoder().decode(struct.pack("<I", 1000) + main)
    assert classic.signals == pytest.approx({"speed": 13.0, "pitch": 0.125, "roll": -0.25})
    opts = 0x4 | 0x8 | 0x10  # Time, OutSimMain, inputs
    inputs = struct.pack("<5f", 0.75, 0.25, -0.3, 0.0, 1.0)
    packet = struct.pack("<I", 1000) + main + inputs
    sample = OutSimDecoder(config=OutSimConfig(opts=opts)).decode(packet)
    assert sample.signals == pytest.approx(
        {"speed": 13.0, "pitch": 0.125, "roll": -0.25, "throttle": 0.75, "brake": 0.25}
    )
    odd = struct.pack("<I", 1000) + main + struct.pack("<5f", math.nan, 80.0, 0.0, 0.0, 0.0)
    bare = OutSimDecoder(config=OutSimConfig(opts=opts)).decode(odd)
    assert "throttle" not in bare.signals and "brake" not in bare.signals


def test_outsim2_layouts_follow_the_option_bits():
    main = outsim_main(ang_vel=(0.0, 0.0, 0.25), accel=(0.0, -3.0, 0.0))
    inputs, drive, distance = bytes(20), bytes(12), bytes(8)
    wheels, extra = bytes(160), bytes(8)
    every = b"LFST" + struct.pack("<iI", 3, 4000) + main + inputs + drive + distance
    every += wheels + extra
    assert len(every) == 280  # LFS's documented size for OutSim Opts 1ff
    for opts, packet, t_s in [
        (0x1FF, every, 4.0),
        (0x0C, struct.pack("<I", 4000) + main, 4.0),  # Time and OutSimMain: 64 bytes
        (0x08 | 0x80, main + wheels, None),  # no Time: arrival time
    ]:
        sample = OutSimDecoder(config=OutSimConfig(opts=opts)).decode(packet, received_s=8.0)
        np.testing.assert_allclose(sample.omega, [0.0, 0.0, 0.25], atol=1e-7)
        np.testing.assert_allclose(sample.f, [-3.0, 0.0, G], atol=1e-6)
        assert sample.t_s == (8.0 if t_s is None else t_s)
    with pytest.raises(BadPacket, match="not b'LFST'"):
        OutSimDecoder(config=OutSimConfig(opts=0x1FF)).decode(b"LFSX" + every[4:])
    with pytest.raises(BadPacket, match="sends 280"):
        OutSimDecoder(config=OutSimConfig(opts=0x1FF)).decode(every[:64])


def test_outsim_config_is_checked():
    with pytest.raises(ValueError, match="lacks OSO_MAIN"):
        OutSimDecoder(config=OutSimConfig(opts=0x7))
    with pytest.raises(ValueError, match="bits LFS does not define"):
        OutSimDecoder(config=OutSimConfig(opts=0x200))
    with pytest.raises(ValueError, match="must be an integer"):
        OutSimDecoder(config=OutSimConfig(opts="1ff"))


def test_outsim_bad_packets_raise_bad_packet():
    decoder = OutSimDecoder()
    good = outsim_packet()
    cases = {
        "63 bytes; OutSim Opts 0 sends 64 or 68": good[:-1],
        "65 bytes": good + b"\0",
        "Accel.y = nan": outsim_packet(accel=(0.0, math.nan, 0.0)),
        "AngVel.z = inf": outsim_packet(ang_vel=(0.0, 0.0, math.inf)),
        "exceeds 196.2": outsim_packet(accel=(0.0, 1e4, 0.0)),
        "exceeds 35 rad/s": outsim_packet(ang_vel=(0.0, 0.0, 80.0)),
        "degrees": outsim_packet(angles=(0.0, 12.0, 0.0)),
    }
    for match, packet in cases.items():
        with pytest.raises(BadPacket, match=match):
            decoder.decode(packet, received_s=0.0)


# ----------------------------------------------------------------------------------- F1 games
# Header (29 bytes): uint16 format, uint8 year, major, minor, packet version, packet id,
# uint64 session UID, float session time, uint32 frame, uint32 overall frame, uint8 player
# index, uint8 secondary player index. Motion (id 0): 22 x CarMotionData (6 float, 6 int16,
# 6 float). Motion Ex (id 13): 32 wheel floats, COG height, local velocity[3], angular
# velocity[3], ... (F1 24: 52 floats, F1 23: 47).


def f1_header(packet_id: int, t_s: float, *, fmt=2024, player=5, session=77, version=1):
    return struct.pack(
        "<HBBBBBQfIIBB", fmt, fmt % 100, 1, 4, version, packet_id, session, t_s, 9, 9, player, 255
    )


def f1_motion(t_s=10.0, *, g_forces=(0.0, 0.0, 1.0), player=5, **header) -> bytes:
    """A Motion packet: the player's car has `g_forces` (lateral, longitudinal, vertical);
    every other car brakes hard in a right turn, so that reading the wrong car shows."""
    cars = []
    for index in range(22):
        lateral, longitudinal, vertical = g_forces if index == player else (-3.0, -4.0, 2.0)
        cars.append(
            struct.pack(
                "<6f6h6f",
                *(100.0 + index, 0.5, -200.0, 60.0, 0.0, 1.0),
                *(0, 0, 32767, -32767, 0, 0),
                lateral,
                longitudinal,
                vertical,
                *(0.1, 0.0, 0.0),
            )
        )
    return f1_header(0, t_s, player=player, **header) + b"".join(cars)


def f1_motion_ex(t_s=10.0, *, angular_velocity=(0.0, 0.0, 0.0), fmt=2024, **header) -> bytes:
    before = [0.01] * 32 + [0.3, 1.0, -0.2, 60.0]  # wheels, COG height, local velocity
    after = [0.0, 0.0, 0.0, 0.05] + [3000.0] * 4  # angular acceleration, wheels angle, loads
    if fmt == 2024:
        after += [0.03, 0.06, 0.0, 0.0, 0.01]  # plank heights, suspension roll, chassis yaw
    floats = [*before, *angular_velocity, *after]
    return f1_header(13, t_s, fmt=fmt, **header) + struct.pack(f"<{len(floats)}f", *floats)


def f1_pair(decoder, *, g_forces=(0.0, 0.0, 1.0), angular_velocity=(0.0, 0.0, 0.0), t_s=10.0):
    """The samples of a frame's Motion Ex packet and of its Motion packet, sent again after it
    (the first Motion packet of a fresh decoder has nothing to pair with)."""
    motion = f1_motion(t_s, g_forces=g_forces)
    try:
        decoder.decode(motion, 0.0)
    except BadPacket:
        pass
    first = decoder.decode(f1_motion_ex(t_s, angular_velocity=angular_velocity), 0.0)
    return first, decoder.decode(motion, 0.0)


def test_f1_level_car_at_rest_reads_gravity():
    decoder = F1Decoder()
    with pytest.raises(BadPacket, match="waits for a Motion Ex"):
        decoder.decode(f1_motion(9.98), received_s=0.0)
    first = decoder.decode(f1_motion_ex(10.0), received_s=0.0)  # pairs with the 9.98 Motion
    second = decoder.decode(f1_motion(10.0), received_s=0.0)
    for sample in (first, second):
        np.testing.assert_allclose(sample.f, [0.0, 0.0, G], atol=1e-12)
        np.testing.assert_allclose(sample.omega, [0.0, 0.0, 0.0], atol=1e-12)
    assert first.t_s == second.t_s == 10.0 and second.time_source == "sender"


@pytest.mark.parametrize(
    "g_forces, angular_velocity, omega, f",
    [
        # yawing left at 0.5 rad/s: local y is up
        ((0, 0, 1), (0.0, 0.5, 0.0), [0.0, 0.0, 0.5], [0.0, 0.0, G]),
        # braking at 1.2 g
        ((0.0, -1.2, 1.0), (0, 0, 0), [0, 0, 0], [-1.2 * G, 0.0, G]),
        # a left turn at 1.5 g
        ((1.5, 0.0, 1.0), (0, 0, 0), [0, 0, 0], [0.0, 1.5 * G, G]),
        # rolling right side down (local z forward), pitching nose down (local x left)
        ((0, 0, 1), (0.2, 0.0, 0.3), [0.3, 0.2, 0.0], [0.0, 0.0, G]),
    ],
    ids=["yaw-left", "braking", "left-turn", "roll-pitch"],
)
def test_f1_channels_and_signs(g_forces, angular_velocity, omega, f):
    for sample in f1_pair(F1Decoder(), g_forces=g_forces, angular_velocity=angular_velocity):
        np.testing.assert_allclose(sample.omega, omega, atol=1e-6)
        np.testing.assert_allclose(sample.f, f, atol=1e-5)


def test_f1_reads_the_player_car_of_the_header():
    decoder = F1Decoder()
    f1_pair(decoder, t_s=10.0)
    for player in (0, 5, 21):
        sample = decoder.decode(f1_motion(10.0, player=player, g_forces=(0.5, 0.25, 1.0)))
        np.testing.assert_allclose(sample.f, G * np.array([0.25, 0.5, 1.0]), atol=1e-5)
    with pytest.raises(BadPacket, match="player car index 255"):
        decoder.decode(f1_motion(10.0, player=255))


def test_f1_23_format_has_the_shorter_motion_ex():
    decoder = F1Decoder(config=F1Config(packet_format=2023))
    ex = f1_motion_ex(3.0, angular_velocity=(0.0, -0.4, 0.0), fmt=2023)
    assert len(ex) == 217
    with pytest.raises(BadPacket, match="waits for a Motion Ex"):
        decoder.decode(f1_motion(3.0, fmt=2023), received_s=0.0)
    decoder.decode(ex, received_s=0.0)
    sample = decoder.decode(f1_motion(3.0, fmt=2023, g_forces=(0.0, 0.5, 1.0)))
    np.testing.assert_allclose(sample.omega, [0.0, 0.0, -0.4], atol=1e-6)
    np.testing.assert_allclose(sample.f, [0.5 * G, 0.0, G], atol=1e-5)
    with pytest.raises(BadPacket, match="format 2024; the decoder reads 2023"):
        decoder.decode(f1_motion(3.0))
    with pytest.raises(BadPacket, match="Motion Ex packet of 237 bytes; format 2023 sends 217"):
        decoder.decode(f1_motion_ex(3.0, fmt=2023) + bytes(20))


def test_f1_pairs_only_within_a_session_and_its_window():
    decoder = F1Decoder()
    f1_pair(decoder, t_s=10.0)
    with pytest.raises(BadPacket, match=r"no Motion Ex \(13\) packet of its session"):
        decoder.decode(f1_motion(10.0, session=78))
    with pytest.raises(BadPacket, match=r"within 0\.1 s"):
        decoder.decode(f1_motion(10.5))
    decoder.reset()
    with pytest.raises(BadPacket, match="waits for a Motion"):
        decoder.decode(f1_motion_ex(10.5))


def test_f1_config_switches_signs_and_is_checked():
    config = F1Config(
        lateral_positive_left=False,
        longitudinal_positive_forward=False,
        vertical_positive_up=False,
        local_axes_right_handed=False,
    )
    _, sample = f1_pair(
        F1Decoder(config=config), g_forces=(1.5, -1.2, -1.0), angular_velocity=(0.2, 0.5, 0.3)
    )
    np.testing.assert_allclose(sample.f, G * np.array([1.2, -1.5, 1.0]), atol=1e-5)
    np.testing.assert_allclose(sample.omega, [-0.3, 0.2, -0.5], atol=1e-6)
    for bad, match in [
        ({"packet_format": 2022}, "valid: 2023, 2024"),
        ({"pairing_window_s": 0.0}, "pairing_window_s"),
        ({"vertical_positive_up": 1}, "vertical_positive_up must be true or false"),
    ]:
        with pytest.raises(ValueError, match=match):
            F1Decoder(config=F1Config(**bad))


def f1_car_telemetry(t_s=10.0, *, controls=(180, 0.75, 0.5, 0.25), player=5, **header):
    """A Car Telemetry packet (id 6, 1352 bytes): 22 CarTelemetryData of 60 bytes, the
    player's with `controls` (speed km/h, throttle, steer, brake), every other car full
    throttle, full right lock and no brake; then the three MFD bytes."""
    cars = []
    for index in range(22):
        speed, throttle, steer, brake = controls if index == player else (300, 1.0, 1.0, 0.0)
        cars.append(
            struct.pack("<H3fBbHBBH", speed, throttle, steer, brake, 0, 7, 11000, 0, 80, 0)
            + struct.pack("<4H4B4BH4f4B", *[900] * 4, *[90] * 8, 100, *[23.0] * 4, *[0] * 4)
        )
    return f1_header(6, t_s, player=player, **header) + b"".join(cars) + bytes((255, 255, 0))


def test_f1_passes_on_the_players_speed_and_controls():
    """Oracle: CarTelemetryData as EA's specification lays it out (speed uint16 km/h, then
    throttle, steer -1 full left ... 1 full right, brake), the steering turned to ISO 8855's
    positive left; the controls ride on the samples of their session and time window."""
    decoder = F1Decoder()
    telemetry = f1_car_telemetry()
    assert len(telemetry) == 1352
    with pytest.raises(BadPacket, match="controls ride on the motion samples"):
        decoder.decode(telemetry)
    first, second = f1_pair(decoder)
    expected = {"speed": 50.0, "throttle": 0.75, "steering": -0.5, "brake": 0.25}
    assert first.signals == pytest.approx(expected) and second.signals == first.signals
    with pytest.raises(BadPacket):
        decoder.decode(f1_car_telemetry(controls=(90, 2.0, math.nan, 0.5)))
    _, held = f1_pair(decoder)
    assert held.signals == pytest.approx({"speed": 25.0, "brake": 0.5})  # the rest refused
    _, later = f1_pair(decoder, t_s=11.0)  # the controls are a second old: not passed on
    assert later.signals == {}


def test_f1_bad_packets_raise_bad_packet():
    decoder = F1Decoder()
    f1_pair(decoder)
    lap_data = f1_header(2, 10.0) + bytes(1256)  # Lap Data, another packet of the game
    cases = {
        "packet id 2 \\(Lap Data\\)": lap_data,
        "Car Telemetry packet of 1351 bytes": f1_car_telemetry()[:-1],
        "shorter than the 29-byte header": f1_motion()[:20],
        "Motion packet of 1348 bytes": f1_motion()[:-1],
        "version 2": f1_motion(version=2),
        "session time nan": f1_motion(math.nan),
        "non-finite g-forces": f1_motion(g_forces=(0.0, math.inf, 1.0)),
        "non-finite angular velocity": f1_motion_ex(angular_velocity=(math.nan, 0.0, 0.0)),
        "beyond 20 g": f1_motion(g_forces=(0.0, 40.0, 1.0)),
        "beyond 35 rad/s": f1_motion_ex(angular_velocity=(0.0, 100.0, 0.0)),
        "at most 2048": bytes(4096),
    }
    for match, packet in cases.items():
        with pytest.raises(BadPacket, match=match):
            decoder.decode(packet, received_s=0.0)
    # the refused parts were not kept: the stream goes on with the good ones
    _, sample = f1_pair(decoder, t_s=10.01)
    np.testing.assert_allclose(sample.f, [0.0, 0.0, G], atol=1e-12)


# ------------------------------------------------------------------------------- all three


def _good_packets(protocol: str) -> list[bytes]:
    if protocol == "beamng":
        return [beamng_packet()]
    if protocol == "outsim":
        return [outsim_packet(), outsim_packet(outsim_id=3)]
    return [f1_motion_ex(), f1_motion()]


DECODERS = {"beamng": BeamNGDecoder, "outsim": OutSimDecoder, "f1": F1Decoder}


@pytest.mark.parametrize("protocol", sorted(DECODERS))
def test_random_bytes_raise_bad_packet_and_nothing_else(protocol, rng):
    """Random datagrams of random and of the protocol's own sizes, and good packets with
    random bytes written over parts of them: every outcome is a sample or BadPacket."""
    decoder = DECODERS[protocol]()
    good = _good_packets(protocol)
    for trial in range(600):
        template = good[trial % len(good)]
        if trial % 3 == 0:
            size = int(rng.integers(0, 300)) if trial % 2 else len(template)
            packet = rng.integers(0, 256, size=size, dtype=np.uint8).tobytes()
        else:
            data = bytearray(template)
            start = int(rng.integers(0, len(data)))
            stop = min(len(data), start + int(rng.integers(1, 16)))
            data[start:stop] = rng.integers(0, 256, size=stop - start, dtype=np.uint8).tobytes()
            packet = bytes(data)
        try:
            sample = decoder.decode(packet, received_s=float(trial))
        except BadPacket:
            continue
        assert all(map(math.isfinite, (*sample.omega, *sample.f, sample.t_s)))


# ---------------------------------------------------------------------------------- loopback


@pytest.mark.parametrize("protocol", sorted(DECODERS))
def test_each_protocol_streams_over_loopback_into_the_receiver(protocol):
    """A sender on 127.0.0.1 sends the protocol's packets (a left turn while braking, yawing
    left) and garbage to a live receiver: its reference is the y_ref of the decoded sample
    (s_w = s_f = 0.5, gravity removed), the garbage and the F1 game's other packets bad."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from mca_drake.live.receiver import ReceiverConfig, TelemetryReceiver

    turn = {
        "beamng": [beamng_packet(acc=(-4.0, -2.0, 0.0), rates=(0.0, 0.0, -0.5))],
        "outsim": [outsim_packet(ang_vel=(0.0, 0.0, 0.5), accel=(-4.0, -2.0, 0.0))],
        "f1": [
            f1_motion_ex(angular_velocity=(0.0, 0.5, 0.0)),
            f1_header(6, 10.0) + bytes(1323),  # Car Telemetry: not read
            f1_motion(g_forces=(4.0 / G, -2.0 / G, 1.0)),
        ],
    }[protocol]
    builder = DiagramBuilder()
    receiver = builder.AddSystem(
        TelemetryReceiver(DECODERS[protocol](), ReceiverConfig(host="127.0.0.1", port=0))
    )
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for packet in [b"\xff" * 40, *turn]:
            sender.sendto(packet, receiver.address)
        simulator.AdvanceTo(0.01)  # one poll, at t = 0
        context = receiver.GetMyContextFromRoot(simulator.get_context())
        reference = receiver.GetOutputPort("reference").Eval(context)
        counters = receiver.counters(context)
    finally:
        sender.close()
        receiver.close()
    # the garbage; for F1 also the Car Telemetry packet and the first Motion Ex, which has no
    # Motion packet to pair with yet
    expected_bad = 3 if protocol == "f1" else 1
    assert counters["packets"] == len(turn) + 1 and counters["bad"] == expected_bad
    np.testing.assert_allclose(reference, [0.0, 0.0, 0.25, 0.5 * -2.0, 0.5 * 4.0, 0.0], atol=1e-5)


def test_live_command_and_scenario_register_the_racing_protocols(tmp_path):
    from mca_drake.app.cli import build_parser
    from mca_drake.app.cli.live import _scenario_from_flags
    from mca_drake.app.scenarios import LiveScenario, load_scenario
    from mca_drake.live.loop import PROTOCOLS, make_decoder

    assert {"beamng", "outsim", "f1"} <= set(PROTOCOLS)
    assert isinstance(make_decoder("beamng"), BeamNGDecoder)
    assert make_decoder("outsim", outsim=OutSimConfig(opts=0x1FF)).config.opts == 0x1FF
    assert make_decoder("f1", f1=F1Config(packet_format=2023)).config.packet_format == 2023
    base = ["live", "--duration", "5", "--mca", "washout", "--port", "0"]
    parser = build_parser()
    f1 = _scenario_from_flags(parser.parse_args([*base, "--protocol", "f1", "--f1-format", "2023"]))
    assert f1.protocol == "f1" and f1.f1.packet_format == 2023
    lfs = _scenario_from_flags(
        parser.parse_args([*base, "--protocol", "outsim", "--outsim-opts", "1ff"])
    )
    assert lfs.protocol == "outsim" and lfs.outsim.opts == 0x1FF
    with pytest.raises(ValueError, match=r"LiveScenario\.f1: unknown F1Config\.packet_format 2022"):
        LiveScenario(protocol="f1", f1=F1Config(packet_format=2022), mca="washout").validate()
    scenario_file = tmp_path / "live_f1.yaml"
    scenario_file.write_text(
        "scenario: !LiveScenario\n  protocol: f1\n  mca: washout\n"
        "  f1: {packet_format: 2023, lateral_positive_left: false}\n"
        "  outsim: {opts: 0x1ff}\n  beamng: {pitch_angle_positive_nose_up: false}\n"
    )
    loaded = load_scenario(scenario_file)
    loaded.validate()
    assert loaded.f1 == F1Config(packet_format=2023, lateral_positive_left=False)
    assert loaded.outsim.opts == 0x1FF and not loaded.beamng.pitch_angle_positive_nose_up
