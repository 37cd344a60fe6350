"""The driver moves only the robot the scenario names: an intruder on 127.0.0.2 is never
answered and cannot end the run; the IPOC's unit is measured (ROS-Industrial's simulator
counts cycles) or refused naming the setting; the scenario sets the robot's home in axis
angles; the driver ends with its parent and leaves no folder behind.

ROS-Industrial's kuka_rsi_simulator is played from its documented behaviour: every 4 ms it
sends <Rob TYPE="KUKA"> with RIst, RSol, AIPos, ASPos, Delay and IPOC elements, and waits
for the reply before its next cycle."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import astuple

import numpy as np
import pytest
from conftest import RSI_LOOP_PERIOD as H
from conftest import limits_of, mca_like_segments
from test_rsi_driver import CYCLE, feed

from mca_drake.app.jobs import run_live_scenario
from mca_drake.app.scenarios import load_scenario
from mca_drake.live.rsi.driver import RsiDriver, RsiDriverConfig, ipoc_unit_of
from mca_drake.live.rsi.emulator import AxisLimits, RsiEmulator, RsiEmulatorConfig
from mca_drake.live.rsi.link import segment_socket_pair, start_rsi_driver
from mca_drake.live.rsi.motion import RsiMotionConfig
from mca_drake.live.rsi.xml import format_state
from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform


class RosIndustrialSimulator(RsiEmulator):
    """The emulated controller speaking as ROS-Industrial's kuka_rsi_simulator does."""

    def _state_packet(self, n, ipoc, axes):
        pose = " ".join(f'{k}="0.0"' for k in "XYZABC")
        joints = " ".join(f'A{i + 1}="{v}"' for i, v in enumerate(axes))
        return (
            f'<Rob TYPE="KUKA"><RIst {pose}/><RSol {pose}/><AIPos {joints}/>'
            f'<ASPos {joints}/><Delay D="0"/><IPOC>{ipoc}</IPOC></Rob>'
        ).encode()


def intrude(address, stop: threading.Event, counts: dict) -> None:
    """From 127.0.0.2: a state packet every 4 ms with an IPOC of 10^12 and up, counting
    any reply; bounded by `stop` and 10 s."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.2", 0))
    sock.setblocking(False)
    end = time.monotonic() + 10.0
    k = 0
    while not stop.is_set() and time.monotonic() < end:
        sock.sendto(format_state(10**12 + k, [0.0] * 6), address)
        counts["sent"] += 1
        k += 1
        time.sleep(0.004)
        try:
            while sock.recv(2048):
                counts["replies"] += 1
        except BlockingIOError:
            pass
    sock.close()


def drive(
    robot,
    segments,
    duration_s,
    *,
    config=None,
    emulator=RsiEmulator,
    intruder=False,
    emulator_config=None,
):
    """Driver (own process), emulator here, segments fed once the robot is ready, and
    optionally an intruder from the start; (report, status, intruder counts)."""
    config = config or RsiDriverConfig(port=0, motion=RsiMotionConfig(cycle_s=CYCLE))
    ours, theirs = segment_socket_pair()
    link = start_rsi_driver(config, robot, np.zeros(6), theirs)
    counts, stop = {"sent": 0, "replies": 0}, threading.Event()
    threads = []
    if intruder:
        threads.append(threading.Thread(target=intrude, args=(link.address, stop, counts)))
        threads[0].start()
        time.sleep(0.05)  # the intruder speaks first
    robot_emulator = emulator(link.address, emulator_config or RsiEmulatorConfig(cycle_s=CYCLE))
    try:
        feeder = feed(ours, segments)
        report = robot_emulator.run(duration_s)
        feeder.join(timeout=10)
    finally:
        stop.set()
        for thread in threads:
            thread.join(timeout=10)
        robot_emulator.close()
        status = link.stop()
        ours.close()
    return report, status, counts


@pytest.fixture
def moving(robot):
    return mca_like_segments(robot, np.random.default_rng(5), 60, gain=1.0)


def test_a_named_controller_ignores_an_intruder_that_speaks_first(robot, moving):
    """The scenario names the controller's address: an intruder on 127.0.0.2, sending from
    before the robot with IPOCs of 10^12, is never answered, never locked in, and the run
    goes on undisturbed."""
    config = RsiDriverConfig(port=0, motion=RsiMotionConfig(cycle_s=CYCLE), controller="127.0.0.1")
    report, status, counts = drive(robot, moving, 1.5, config=config, intruder=True)
    assert counts["sent"] > 100 and counts["replies"] == 0
    assert status["foreign"] >= counts["sent"] - 5  # a few may still be in flight
    assert status["controller"].startswith("127.0.0.1:")
    assert report["stop_reason"] == "" and report["bad_replies"] == 0, report
    assert status["bad_state"] == 0 and status["segments"] == len(moving)


def test_an_intruder_after_the_robot_locked_in_is_ignored(robot, moving):
    """No controller named: the first sender, the robot, is locked in; an intruder that
    starts later is never answered and the run goes on."""
    config = RsiDriverConfig(port=0, motion=RsiMotionConfig(cycle_s=CYCLE))
    ours, theirs = segment_socket_pair()
    link = start_rsi_driver(config, robot, np.zeros(6), theirs)
    counts, stop = {"sent": 0, "replies": 0}, threading.Event()
    emulator = RsiEmulator(link.address, RsiEmulatorConfig(cycle_s=CYCLE))
    intruder = threading.Timer(0.2, intrude, args=(link.address, stop, counts))
    try:
        intruder.start()
        feeder = feed(ours, moving)
        report = emulator.run(1.5)
        feeder.join(timeout=10)
    finally:
        stop.set()
        intruder.join(timeout=12)
        emulator.close()
        status = link.stop()
        ours.close()
    assert counts["sent"] > 100 and counts["replies"] == 0
    assert report["stop_reason"] == "" and status["bad_state"] == 0, (report, status)


@pytest.mark.parametrize(
    ("rate", "unit"), [(1000.0, "ms"), (250.0, "cycles"), (83.3, None), (4000.0, None)]
)
def test_the_ipoc_unit_is_told_from_its_rate(rate, unit):
    assert ipoc_unit_of(rate, 0.004) == unit


def test_ros_industrials_simulator_is_followed_at_the_right_speed(robot, moving):
    """Its IPOC counts cycles: measured over the first cycles, the driver plays the
    trajectory on the robot's time (the lead stays at the 25 ms delay) until the segments
    stop; it never brakes for a clock reason."""
    emulator_config = RsiEmulatorConfig(cycle_s=CYCLE, ipoc_unit="cycles", first_ipoc=0)
    report, status, _ = drive(
        robot, moving, 1.5, emulator=RosIndustrialSimulator, emulator_config=emulator_config
    )
    assert status["ipoc_unit"] == "cycles" and status["bad_state"] == 0
    assert report["stop_reason"] == "" and report["bad_replies"] == 0, report
    delay = RsiMotionConfig().delay_s
    assert abs(status["lead_s"]["median"] - delay) < 2 * H, status["lead_s"]
    assert "no command" in status["reason"], status  # the segments ran out: the loop's end


def test_a_configured_ipoc_unit_that_does_not_match_is_refused(robot, moving):
    config = RsiDriverConfig(port=0, motion=RsiMotionConfig(cycle_s=CYCLE), ipoc_unit="ms")
    emulator_config = RsiEmulatorConfig(cycle_s=CYCLE, ipoc_unit="cycles")
    _, status, _ = drive(
        robot,
        moving,
        0.5,
        config=config,
        emulator=RosIndustrialSimulator,
        emulator_config=emulator_config,
    )
    assert "rsi.ipoc_unit is 'ms'" in status["refused"] and "counts cycles" in status["refused"]


def test_the_scenario_sets_the_robots_home_in_axis_angles():
    """`--set '{rsi: {home_deg: [0, -90, 90, 0, 90, 0]}}'` on the packaged live_rsi scenario
    drives an emulated robot that starts there; without it the driver refuses that robot."""
    home = [0.0, -90.0, 90.0, 0.0, 90.0, 0.0]
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    base = (
        f"{{port: 0, duration_s: 1.0, mca: washout, output_json: '', "
        f"robot: 'rsi://127.0.0.1:{port}'}}"
    )

    def run(overrides):
        reports = []

        def start_robot(_address):
            # this robot's axes read -90 and 90 where the model's joints read 0: its position
            # limits sit elsewhere, its rates are the KR500's
            kr500 = AxisLimits.of_robot(load_platform(DEFAULT_PLATFORM))
            limits = AxisLimits([-360.0] * 6, [360.0] * 6, *astuple(kr500)[2:])
            emulator = RsiEmulator(
                ("127.0.0.1", port), RsiEmulatorConfig(cycle_s=CYCLE, start_deg=home), limits
            )
            thread = threading.Thread(target=lambda: reports.append(emulator.run(2.0)))
            thread.start()

        return run_live_scenario(
            load_scenario("live_rsi", [base, *overrides]), on_listening=start_robot
        )

    summary = run(["{rsi: {home_deg: [0, -90, 90, 0, 90, 0]}}"])
    assert summary["rsi"]["cycles"] > 100 and "refused" not in summary["rsi"]
    with pytest.raises(RuntimeError, match="not at the home pose"):
        run([])


@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGKILL])
def test_the_driver_ends_with_its_parent_before_any_robot(tmp_path, how):
    """The live command ended before a robot ever connected (SIGTERM: its clean-up runs;
    SIGKILL: none does) takes its driver with it: the RSI port is free again and no
    folder is left in the temporary directory."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    command = [sys.executable, "-m", "mca_drake.app.cli", "live", "--protocol", "csv"]
    command += ["--port", "0", "--duration", "30", "--mca", "washout"]
    command += ["--robot", f"rsi://127.0.0.1:{port}"]
    environment = {**os.environ, "TMPDIR": str(tmp_path)}
    live = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, env=environment)
    try:
        assert "listening on udp://" in live.stdout.readline()
        live.send_signal(how)
        live.wait(timeout=20)
    finally:
        live.kill()
    deadline = time.monotonic() + 10.0
    while True:  # the driver's port is released once it has ended
        try:
            probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            probe.bind(("127.0.0.1", port))
            probe.close()
            break
        except OSError:
            probe.close()
            assert time.monotonic() < deadline, "the driver outlived its parent"
            time.sleep(0.1)
    if how == signal.SIGTERM:
        assert live.returncode == 130
        assert not list(tmp_path.glob("mca_drake_rsi_*"))


@pytest.mark.parametrize(
    ("lead_s", "segments_arriving", "reason"),
    [
        (0.6, True, "runs slower than the loop's"),
        (-0.01, True, "runs faster than the loop's"),
        (-0.01, False, ""),  # no segments: a stalled loop, the follower's to judge
        (0.03, True, ""),
    ],
)
def test_a_lead_out_of_its_bounds_brakes_with_that_reason(robot, lead_s, segments_arriving, reason):
    driver = RsiDriver(
        RsiDriverConfig(port=0, motion=RsiMotionConfig(cycle_s=CYCLE)),
        limits_of(robot),
        np.zeros(6),
        None,
    )
    try:
        driver.follower.mode = "following"  # as after the loop's first segments
        driver._segment_seen = time.perf_counter() if segments_arriving else -1e9
        driver._check_lead(lead_s)
        if reason:
            # at rest already, braking ends at once
            assert driver.follower.mode in ("braking", "stopped")
            assert reason in driver.follower.reason
        else:
            assert driver.follower.mode == "following"
    finally:
        driver.close()
