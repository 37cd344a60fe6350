"""The KR500 on its rail over RSI: the rail as the controller's external axis E1, in mm.

A KUKA controller drives a track as external axis E1 of the same controller: its actual
position arrives in the state's EIPos element and its correction goes back in the reply's
EK element, in millimetres (KUKA's unit for a linear axis), beside A1-A6 in degrees. The
oracles are those units (1000 mm a metre, 180/pi deg a radian), the rail's published limits
(the MPI CyberMotion Simulator's track: +-1.47 m/s, +-1.078 m/s^2) and the segments' own
exact trajectory (`SegmentBuffer`, checked against Drake's plant in test_rsi_motion).
"""

from __future__ import annotations

import math
import socket
import time

import numpy as np
import pytest
from conftest import mca_like_segments
from test_rsi_driver import (
    CYCLE,
    ON_TIME_SHARE,
    RETRIES,
    best_offset_error,
    feed,
    live_run_with_emulator,
    refusal_at_start,
)

from mca_drake.live.csv_udp import encode_csv_sample
from mca_drake.live.rsi.axes import RsiAxisMap
from mca_drake.live.rsi.driver import RsiDriverConfig
from mca_drake.live.rsi.emulator import AxisLimits, RsiEmulator, RsiEmulatorConfig
from mca_drake.live.rsi.link import segment_socket_pair, start_rsi_driver
from mca_drake.live.rsi.motion import RsiMotionConfig
from mca_drake.live.rsi.xml import RsiTags
from mca_drake.platforms.files import load_platform

RAIL = load_platform("kr500-rail")
ROBOT_AXES = ["A1", "A2", "A3", "A4", "A5", "A6"]


def test_the_rail_is_e1_in_mm_and_the_robots_joints_a1_to_a6_in_degrees():
    tags = RsiTags()
    axes = RsiAxisMap.build(RAIL.joint_kinds, RAIL.home, tags.axes, tags.external_axes)
    assert axes.names == ("E1", *ROBOT_AXES) and axes.external == 1
    assert axes.units == ("mm", "deg", "deg", "deg", "deg", "deg", "deg")
    q = np.array([0.25, 0.1, -0.2, 0.3, -0.4, 0.5, -0.6])
    robot, external = axes.corrections(q)
    np.testing.assert_allclose(external, [250.0])  # mm
    np.testing.assert_allclose(robot, q[1:] * 180 / math.pi)
    # signs and a controller whose track reads 4750 mm at the model's rail centre
    signed = RsiAxisMap.build(
        RAIL.joint_kinds,
        RAIL.home,
        tags.axes,
        tags.external_axes,
        axis_signs=[1, -1, 1, 1, 1, 1],
        external_signs=[-1],
        external_home=[4750.0],
    )
    robot, external = signed.corrections(q)
    np.testing.assert_allclose(external, [-250.0])
    assert robot[1] == pytest.approx(0.2 * 180 / math.pi)
    assert signed.home[0] == 4750.0
    # the six-axis KR500 has no external axis; a setting for one is refused, naming it
    kr500 = load_platform("kr500")
    plain = RsiAxisMap.build(kr500.joint_kinds, kr500.home, tags.axes, tags.external_axes)
    assert plain.external == 0 and plain.names == tuple(ROBOT_AXES)
    with pytest.raises(ValueError, match="external_home must hold 0 values"):
        RsiAxisMap.build(
            kr500.joint_kinds, kr500.home, tags.axes, tags.external_axes, [], [], [], [1]
        )
    with pytest.raises(ValueError, match="a platform of 6 to 12 joints; this one has 3"):
        RsiAxisMap.build(["revolute"] * 3, [0] * 3, tags.axes, tags.external_axes)


def test_the_emulated_controller_holds_the_rails_published_limits_in_mm():
    """E1's limits as the controller sees them: the rail's +-4.55 m travel, 1.47 m/s and
    1.078 m/s^2 in mm; A1-A6 the KR500's in degrees, in the messages' order."""
    limits = AxisLimits.of_robot(RAIL)
    kr500 = AxisLimits.of_robot(load_platform("kr500"))
    assert limits.min_deg[6] == pytest.approx(-4550.0) and limits.max_deg[6] == pytest.approx(
        4550.0
    )
    assert limits.velocity_deg_s[6] == pytest.approx(1470.0)
    assert limits.acceleration_deg_s2[6] == pytest.approx(1078.0)
    np.testing.assert_allclose(limits.max_deg[:6], kr500.max_deg)
    emulator = RsiEmulator(
        ("127.0.0.1", 9), RsiEmulatorConfig(cycle_s=CYCLE, platform="kr500-rail")
    )
    try:
        rest = [0.0] * 7
        # one cycle from rest at 1.01 times the rail's acceleration: its second difference
        too_hard = [*rest[:6], 1.01 * 1078.0 * CYCLE * CYCLE]
        assert "E1 acceleration" in emulator._check(rest, rest, too_hard, CYCLE, CYCLE)
        assert "mm/s^2" in emulator._check(rest, rest, too_hard, CYCLE, CYCLE)
        gentle = [*rest[:6], 0.99 * 1078.0 * CYCLE * CYCLE]
        assert emulator._check(rest, rest, gentle, CYCLE, CYCLE) == ""
        beyond = [*rest[:6], 4551.0]
        assert "E1 position 4551.0000 mm" in emulator._check(beyond, rest, beyond, CYCLE, CYCLE)
    finally:
        emulator.close()


def test_the_driver_drives_the_rail_and_the_robot_along_the_commanded_trajectory():
    """The driver in its own process (as the live loop starts it), the emulated controller
    with the rail here: E1 follows the segments' rail trajectory in mm and A1-A6 the
    joints' in degrees, to the replies' six decimals, at one time offset; the rail moved
    (over 10 mm); when the segments stop the driver brakes everything to rest.

    The segments are fed in real time by a thread of this process; a run that the loaded
    machine's scheduler delayed is flown again (test_rsi_driver's killed-loop test)."""
    segments = mca_like_segments(RAIL, np.random.default_rng(12), 150, gain=1.5)
    for _ in range(RETRIES):
        config = RsiDriverConfig(port=0, motion=RsiMotionConfig(cycle_s=CYCLE))
        ours, theirs = segment_socket_pair()
        link = start_rsi_driver(config, RAIL, RAIL.home, theirs)
        emulator = RsiEmulator(
            link.address, RsiEmulatorConfig(cycle_s=CYCLE, platform="kr500-rail")
        )
        try:
            feeder = feed(ours, segments, stop_after=120)
            report = emulator.run(2.0)
            feeder.join()
        finally:
            emulator.close()
            status = link.stop()
            ours.close()
        recording = emulator.recording()
        played = np.c_[recording["external_axes"], recording["axes_deg"]]
        # the controller's units: mm a metre for the rail, degrees a radian for the rest
        to_controller = np.r_[1000.0, np.full(6, 180 / math.pi)]
        _, error = best_offset_error(recording, segments[:120], 0.0, played, to_controller)
        if report["stop_reason"] == "" and error < 1e-5:
            break
    assert report["stop_reason"] == "" and report["bad_replies"] == 0, report
    assert report["on_time"] >= ON_TIME_SHARE * report["cycles"], report
    assert status["segments"] == 120 and status["bad_segments"] == 0, status
    assert status["mode"] == "stopped" and "no command" in status["reason"], status
    assert error < 1e-5  # deg and mm: the six decimals of the replies
    rail_mm = recording["external_axes"][:, 0]
    assert recording["external_axes"].shape == (len(recording["ipoc"]), 1)
    assert np.ptp(rail_mm) > 10.0  # the rail moved
    np.testing.assert_array_equal(recording["external_axes"][-1], recording["external_axes"][-10])
    np.testing.assert_array_equal(recording["axes_deg"][-1], recording["axes_deg"][-10])


def test_the_driver_refuses_a_rail_away_from_home():
    """A track that reads 5 mm where home is 0 (tolerance 1 mm): nothing is sent and the
    driver names E1 in mm."""
    refused, report = refusal_at_start(
        RAIL, RsiEmulatorConfig(cycle_s=CYCLE, platform="kr500-rail", start_external=[5.0])
    )
    assert "E1 reads 5.000 mm, home is 0.000 mm" in refused
    assert report["on_time"] == 0


def sway_stream(address, duration_s, rate_hz=100.0):
    """Sends a sway oscillation (f_y, 0.4 Hz) at `rate_hz` for `duration_s` (wall); bounded,
    stops by itself."""
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    start, k = time.perf_counter(), 0
    while (t := time.perf_counter() - start) < duration_s:
        f = [0.0, 2.0 * np.sin(2 * np.pi * 0.4 * t), 9.81]
        sender.sendto(encode_csv_sample(t, [0.0, 0.0, 0.0], f), address)
        k += 1
        time.sleep(max(0.0, start + k / rate_hz - time.perf_counter()))
    sender.close()


def test_a_live_run_on_the_rail_drives_the_emulated_controllers_e1(tmp_path):
    """`run_live` on the rail with a robot: CSV telemetry, the washout (which uses the rail
    for sway), the driver and the emulated controller (`--platform kr500-rail`, started at
    the washout's home) in processes of their own. The rail moves over E1 in mm with the
    analytical plant's rail joint, no limit is met, and the run ends at rest."""
    home = RAIL.washout_home
    home_deg, rail_mm = np.degrees(home[1:]), 1000.0 * home[0]
    emulator = ["--platform", "kr500-rail", "--start-external", repr(float(rail_mm))]
    emulator += ["--start-deg", ",".join(repr(float(v)) for v in home_deg)]
    summary, report, recording = live_run_with_emulator(tmp_path, sway_stream, RAIL, emulator)
    driver = summary["rsi"]
    assert summary["platform"]["name"] == "kr500-rail"
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert driver["segments"] == driver["segments_sent"] >= 299, driver
    assert driver["bad_state"] == 0 and driver["bad_segments"] == 0, driver
    assert driver["mode"] == "stopped", driver
    assert "limit" not in report["stop_reason"] and report["bad_replies"] == 0, report
    # the plant's rail swept this share of its 9.1 m travel (rounded to 1e-4 of it)
    plant_rail_mm = summary["joint_range_used"][0] * 9100.0
    assert plant_rail_mm > 1.0  # the washout moved the rail
    # E1 moved with the plant's rail joint, in mm, and never further (the trajectory itself
    # is checked to the replies' decimals above; on a loaded machine the driver may brake
    # before the loop's end, when a segment comes late, so E1 may travel less)
    rail_mm_swept = np.ptp(recording["external_axes"][:, 0])
    assert 0.1 < rail_mm_swept <= plant_rail_mm + 1.0
