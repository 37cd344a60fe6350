"""The RSI driver process against the loopback RSI robot emulator (loopback only, bounded)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from conftest import RSI_LOOP_PERIOD as H
from conftest import free_udp_port, limits_of, mca_like_segments
from test_live_loop import stream

from mca_drake.live.csv_udp import CsvDecoder
from mca_drake.live.loop import run_live
from mca_drake.live.receiver import ReceiverConfig
from mca_drake.live.rsi.driver import (
    ROBOT_READY,
    RsiDriver,
    RsiDriverConfig,
    RsiRefused,
    lead_report,
)
from mca_drake.live.rsi.emulator import (
    AxisLimits,
    RsiEmulator,
    RsiEmulatorConfig,
    split_reply_latency,
)
from mca_drake.live.rsi.link import RobotClockServo, segment_socket_pair, start_rsi_driver
from mca_drake.live.rsi.motion import CommandSegment, RsiMotionConfig, SegmentBuffer
from mca_drake.platforms.files import load_platform
from mca_drake.references.flights import FlightSpec, flight_reference
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")

CYCLE = 0.004
# Replies with the right IPOC within the cycle, as a share of the cycles: how many make it is
# the machine's real-time quality (bench_rsi measures it: none late on a quiet host); a
# loaded CI machine without real-time priority misses some (3-6 % seen), so only most are
# asked here.
ON_TIME_SHARE = 0.8
# Runs of the killed-loop test whose feeding thread the machine's scheduler delayed are
# flown again, up to this many times in all.
RETRIES = 3


def feed(commands, segments, stop_after: int | None = None) -> threading.Thread:
    """Sends the segments in real time (segment k at k H) from a thread, as the loop does:
    from the driver's word that the robot is ready on; stops after `stop_after` of them
    without an end segment (a killed loop)."""

    def run():
        commands.settimeout(10.0)
        try:
            while commands.recv(64) != ROBOT_READY:
                pass
        except OSError:  # TimeoutError included: the driver refused the robot
            return
        commands.settimeout(None)
        t0 = time.perf_counter()
        for segment in segments[:stop_after]:
            time.sleep(max(0.0, t0 + segment.k * H - time.perf_counter()))
            try:
                commands.send(segment.pack())
            except OSError:  # the driver has gone (a test that ends it early)
                return

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def best_offset_error(
    recording, segments, robot_start_deg, played=None, to_controller=None
) -> tuple[int, float]:
    """The played trajectory against the integrated commands: for the time offset (whole
    ms, IPOC's unit) that fits best, the largest difference between the emulated axes
    (`played`, per cycle; default A1-A6 less `robot_start_deg`) and the exact trajectory in
    the controller's units (`to_controller` per joint; default degrees), over the cycles
    that followed it."""
    buffer = SegmentBuffer(H, capacity=len(segments) + 1)
    for segment in segments:
        buffer.add(segment)
    ipoc = recording["ipoc"] - recording["ipoc"][0]
    axes = recording["axes_deg"] - robot_start_deg if played is None else played
    scale = np.degrees(1.0) if to_controller is None else np.asarray(to_controller)
    best = (0, np.inf)
    for offset_ms in range(-200, 200):
        errors = []
        for n, t_ms in enumerate(ipoc):
            s = (t_ms - offset_ms) * 1e-3
            held = buffer.state_at(s) if s >= 0 else None
            if held is not None:
                errors.append(np.max(np.abs(scale * np.asarray(held[0]) - axes[n])))
        if len(errors) > 100 and max(errors) < best[1]:
            best = (offset_ms, max(errors))
    return best


def drive_emulator(
    robot, segments, duration_s, stop_after=None, emulator_class=RsiEmulator, timing_path=""
):
    """The driver in its own process (as the loop starts it) fed `segments` in real time
    from a thread, the emulator (`emulator_class`) here for `duration_s`; returns the
    emulator's report, the driver's status and the emulator's recording."""
    config = RsiDriverConfig(
        port=0, motion=RsiMotionConfig(cycle_s=CYCLE), timing_path=str(timing_path)
    )
    ours, theirs = segment_socket_pair()
    link = start_rsi_driver(config, robot, np.zeros(6), theirs)
    emulator = emulator_class(link.address, RsiEmulatorConfig(cycle_s=CYCLE))
    try:
        feeder = feed(ours, segments, stop_after=stop_after)
        report = emulator.run(duration_s)
        feeder.join()
    finally:
        emulator.close()
        status = link.stop()
        ours.close()
    return report, status, emulator.recording()


@pytest.fixture
def moving_run(robot):
    return mca_like_segments(robot, np.random.default_rng(11), 150, gain=1.5)


def test_a_killed_loop_ends_in_a_controlled_stop_along_the_commanded_trajectory(robot, moving_run):
    """The driver in its own process, the emulator here: the emulated axes follow the exact
    trajectory of the segments (to the replies' rounding), every reply echoes its IPOC on
    time, and when the segments stop coming mid-motion (the loop killed) the driver brakes
    to rest inside every limit; the emulator never sees a limit exceeded.

    The segments are fed by a thread of this process in real time; on a loaded 2-core
    machine the scheduler can hold that thread past a segment's deadline, and the driver
    then rightly brakes on a late command. Such a run measures the machine, not the driver:
    it is flown again, up to RETRIES times, and the last run is judged."""
    for _ in range(RETRIES):
        report, status, recording = drive_emulator(robot, moving_run, 2.0, stop_after=120)
        _, error = best_offset_error(recording, moving_run[:120], 0.0)
        if report["stop_reason"] == "" and error < 1e-5:
            break
    assert report["stop_reason"] == "", report
    assert report["bad_replies"] == 0
    assert report["on_time"] >= ON_TIME_SHARE * report["cycles"], report
    assert status["bad_state"] == 0 and status["segments"] == 120
    assert status["mode"] == "stopped" and "no command" in status["reason"], status
    assert error < 1e-5  # deg: the six decimals of the replies
    # it was moving when the segments stopped, and it came to rest
    speed = np.abs(np.diff(recording["axes_deg"], axis=0)) / CYCLE
    assert speed[len(speed) // 2].max() > 1.0
    np.testing.assert_array_equal(recording["axes_deg"][-1], recording["axes_deg"][-10])


def test_reply_latency_splits_into_the_way_there_and_the_answer():
    """Closed-form timeline: four 4 ms cycles; the driver answers 0 and 12 on time, 4 only
    after the cycle (the reply late), never sees 8."""
    recording = {
        "ipoc": np.array([0, 4, 8, 12]),
        "sent_s": np.array([10.000, 10.004, 10.008, 10.012]),
        "latency_s": np.array([0.0005, np.nan, np.nan, 0.0004]),
        "late_ipoc": np.array([4]),
        "late_arrival_s": np.array([10.0095]),
    }
    driver = {"ipoc": np.array([0, 4, 12]), "arrival_s": np.array([10.0001, 10.0090, 10.0121])}
    split = split_reply_latency(recording, driver)
    np.testing.assert_allclose(split["there_s"], [1e-4, 5e-3, np.nan, 1e-4], atol=1e-12)
    np.testing.assert_allclose(split["answer_s"], [4e-4, 5e-4, np.nan, 3e-4], atol=1e-12)
    late, lost = split["unanswered"]
    assert late["ipoc"] == 4 and late["sent_s"] == 10.004
    assert abs(late["there_s"] - 5e-3) < 1e-12 and abs(late["answer_s"] - 5e-4) < 1e-12
    assert lost["ipoc"] == 8 and np.isnan(lost["there_s"]) and np.isnan(lost["answer_s"])


def test_the_driver_and_the_emulator_time_their_cycles_on_one_clock(robot, moving_run, tmp_path):
    """The driver's per-cycle timing file against the emulator's recording, two processes'
    kernel stamps on one monotonic clock, checked by causality cycle by cycle (so a loaded
    machine's preemptions cannot break it): every answered cycle in the file, each state's
    arrival at the driver after it left the emulator, and each reply in the emulator's
    socket before the driver's clock read after its `sendto` (over loopback the packet is
    delivered inside that call), both to the stamps' conversion, 50 us."""
    timing_path = tmp_path / "timing.npz"
    report, status, recording = drive_emulator(robot, moving_run, 1.0, timing_path=timing_path)
    timing = dict(np.load(timing_path))
    assert report["stop_reason"] == "" and report["bad_replies"] == 0, report
    assert timing["ipoc"].size == status["cycles"] > 0.9 * 1.0 / CYCLE
    split = split_reply_latency(recording, timing)
    on_time = np.isfinite(recording["latency_s"])
    there, answer = split["there_s"][on_time], split["answer_s"][on_time]
    assert np.isfinite(there).all() and there.min() > -50e-6, there.min()
    assert timing["reply_s"].size == timing["ipoc"].size
    row_of = {int(m): j for j, m in enumerate(timing["ipoc"])}
    own = timing["reply_s"][[row_of[int(m)] for m in recording["ipoc"][on_time]]]
    assert np.isfinite(answer).all() and (answer > 0).all(), answer.min()
    assert (answer <= own + 50e-6).all(), np.max(answer - own)


class CorruptingEmulator(RsiEmulator):
    """Sends garbage instead of its state at one cycle."""

    corrupt_at = 200

    def _state_packet(self, n, ipoc, axes):
        if n == self.corrupt_at:
            return b'<Rob Type="KUKA"><AIPos A1="garbage'
        return super()._state_packet(n, ipoc, axes)


def test_a_malformed_state_packet_brakes_the_robot_to_rest(robot, moving_run):
    report, status, recording = drive_emulator(
        robot, moving_run, 1.6, emulator_class=CorruptingEmulator
    )
    assert report["stop_reason"] == "", report  # no limit exceeded on the way to rest
    assert status["bad_state"] == 1
    assert status["mode"] == "stopped" and "malformed state packet" in status["reason"]
    axes = recording["axes_deg"]
    np.testing.assert_array_equal(axes[-1], axes[-20])


def refusal_at_start(robot, emulator_config) -> tuple[str, dict]:
    """The driver for `robot` (in a thread here) against an emulator with `emulator_config`
    for 1 s: the driver's refusal (RsiRefused's message; "" if none) and the emulator's
    report."""
    config = RsiDriverConfig(port=0, motion=RsiMotionConfig(cycle_s=CYCLE), robot_silence_s=0.3)
    driver = RsiDriver(config, limits_of(robot), robot.home, None, robot.joint_kinds)
    outcome = {"refused": ""}

    def run():
        try:
            driver.run()
        except RsiRefused as error:
            outcome["refused"] = str(error)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    emulator = RsiEmulator(driver.address, emulator_config)
    try:
        report = emulator.run(1.0)
    finally:
        emulator.close()
        thread.join(timeout=5)
        driver.close()
    return outcome["refused"], report


def test_the_driver_refuses_a_robot_away_from_home(robot):
    """Nothing is sent to a robot that does not report the home pose: it misses its replies
    and stops, and the driver says why."""
    start = [0.0, 3.0, 0.0, 0.0, 0.0, 0.0]
    refused, report = refusal_at_start(robot, RsiEmulatorConfig(cycle_s=CYCLE, start_deg=start))
    assert "A2 reads 3.000 deg" in refused
    assert report["on_time"] == 0 and "without an on-time reply" in report["stop_reason"]


def test_the_emulator_stops_a_correction_beyond_the_limits(robot):
    """The emulator's own check, with the real limits: a reply that would move an axis
    faster than it can is not applied, and the emulator stops."""
    limits = AxisLimits.of_robot(robot)
    config = RsiDriverConfig(port=0, motion=RsiMotionConfig(cycle_s=CYCLE))
    emulator = RsiEmulator(("127.0.0.1", 9), RsiEmulatorConfig(cycle_s=CYCLE), limits)
    too_fast = limits.velocity_deg_s[0] * CYCLE * 1.01
    fast = [too_fast, 0, 0, 0, 0, 0]
    assert "velocity" in emulator._check([0.0] * 6, [0.0] * 6, fast, CYCLE, CYCLE)
    # after a held cycle the same step is half the speed: allowed at that speed
    cruising = [too_fast / (2 * CYCLE), 0, 0, 0, 0, 0]
    assert emulator._check([0.0] * 6, cruising, fast, 2 * CYCLE, CYCLE) == ""
    beyond = [0.0] * 6
    beyond[2] = limits.max_deg[2] + 0.01
    assert "position" in emulator._check(beyond, [0.0] * 6, beyond, CYCLE, CYCLE)
    emulator.close()
    assert config.to_dict()["motion"]["cycle_s"] == CYCLE
    assert RsiDriverConfig.from_dict(config.to_dict()) == config
    with pytest.raises(ValueError, match="unknown"):
        RsiDriverConfig.from_dict({"speed": 3})
    with pytest.raises(ValueError, match="axis_signs"):
        RsiDriverConfig(axis_signs=[1, 1, 1, 1, 1, 2]).validate()


def live_run_with_emulator(tmp_path, sender, robot, emulator_args, mca="washout"):
    """`run_live` of `mca` for 3 s on `robot` with a robot over RSI: telemetry from
    `sender(address, 3.2)` in a thread, the driver in its process and the emulator
    (`emulator_args` added to its command) in another, both started once the loop listens.
    Returns the live summary, the emulator's report and its recording."""
    rsi = RsiDriverConfig(port=0, motion=RsiMotionConfig(cycle_s=CYCLE))
    processes, threads = [], []

    def start(address):
        threads.append(threading.Thread(target=sender, args=(address, 3.2), daemon=True))
        threads[0].start()
        command = [sys.executable, "-m", "mca_drake.live.rsi.emulator"]
        command += ["--driver", f"127.0.0.1:{rsi.port}", "--duration", "8"]  # its port now
        command += [*emulator_args, "--report", str(tmp_path / "report.json")]
        command += ["--recording", str(tmp_path / "recording.npz")]
        processes.append(subprocess.Popen(command, stdout=subprocess.DEVNULL))

    summary = run_live(
        CsvDecoder(),
        mca,
        3.0,
        receiver=ReceiverConfig(port=0),
        on_listening=start,
        rsi=rsi,
        robot=robot,
    )
    processes[0].wait(timeout=30)
    threads[0].join(timeout=5)
    report = json.loads((tmp_path / "report.json").read_text())
    return summary, report, np.load(tmp_path / "recording.npz")


def test_a_live_run_drives_the_emulated_robot_through_a_telemetry_stop(tmp_path):
    """`run_live` with a robot: CSV telemetry with a 0.6 s stop and a NaN burst, the washout
    MCA, the driver in its process and the emulator in another (started at the washout's
    home pose, so the driver accepts it). The robot follows every period's segment, washes
    out through the stop (the supervisor's), never meets a limit, and after the run the
    driver brakes it to rest; only then do the replies end."""

    home_deg = np.degrees([0.0, 0.0, 0.5, 0.0, -0.5, 0.0])
    emulator = ["--start-deg", ",".join(repr(float(v)) for v in home_deg)]
    summary, report, recording = live_run_with_emulator(tmp_path, stream, KR500, emulator)
    driver = summary["rsi"]
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert driver["segments"] == driver["segments_sent"] >= 299 and driver["segments_unsent"] == 0
    assert driver["bad_state"] == 0 and driver["bad_segments"] == 0
    assert driver["mode"] == "stopped", driver
    assert driver["reason"] in ("the loop ended", "the driver was asked to stop"), driver
    assert "limit" not in report["stop_reason"], report  # it ended by the replies stopping
    assert report["bad_replies"] == 0, report
    assert report["on_time"] >= ON_TIME_SHARE * report["cycles"], report
    axes = recording["axes_deg"] - home_deg
    assert np.abs(axes).max() > 0.5  # it moved (the surge oscillation)
    on_time = np.isfinite(recording["latency_s"])
    np.testing.assert_array_equal(axes[on_time][-1], axes[on_time][-10])  # at rest at the end


def test_a_predictive_mca_drives_the_emulated_robot(tmp_path):
    """The predictive NMPC-rti (the learned forecast beside it, in the live loop's phase)
    over RSI: every period's segment sent and followed, no limit met, at rest at the end."""
    home_deg = np.degrees(KR500.home)
    emulator = ["--start-deg", ",".join(repr(float(v)) for v in home_deg)]
    summary, report, recording = live_run_with_emulator(
        tmp_path, stream, KR500, emulator, mca="nmpc-rti-predictive"
    )
    driver = summary["rsi"]
    assert summary["mca"] == "nmpc-rti-predictive"
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert driver["segments"] == driver["segments_sent"] >= 299 and driver["segments_unsent"] == 0
    assert driver["bad_state"] == 0 and driver["bad_segments"] == 0 and report["bad_replies"] == 0
    assert report["on_time"] >= ON_TIME_SHARE * report["cycles"], report
    assert np.abs(recording["axes_deg"] - home_deg).max() > 0.5  # it moved


class FakePacer:
    phase_s = 0.0
    rate_trim = 0.0


def test_the_loops_clock_follows_a_drifting_robot_clock():
    """A controller whose clock runs 300 ppm fast against the PC's: without the servo the
    driver's lead would shrink by 0.3 ms every second; the servo's trim settles at -300 ppm
    and the lead back where it started. The lead's model: d lead / dt = -(drift + trim)
    (the loop's segments come at 1 - trim, the robot plays at 1 + drift); the reports are
    the driver's own bytes through a socket pair."""
    ours, theirs = segment_socket_pair()
    ours.setblocking(False)
    now = [0.0]
    pacer = FakePacer()
    servo = RobotClockServo(ours, pacer, clock=lambda: now[0])
    drift, lead, dt = 3e-4, 0.030, 0.6
    leads = []
    for step in range(200):  # 120 s of reports
        theirs.send(lead_report(lead))
        servo.update()
        leads.append(lead)
        lead -= (drift + pacer.rate_trim) * dt
        now[0] += dt
        if step == 100:
            pacer.phase_s += 0.004  # a phase-lock shift: the lead jumps, by design
            lead += 0.004
    ours.close()
    theirs.close()
    assert pacer.rate_trim == pytest.approx(-drift, rel=0.05)
    assert abs(leads[-1] - 0.004 - 0.030) < 2e-4  # back at its start (and the shift kept)
    assert min(leads) > 0.025  # never near running out


def test_killing_the_live_process_brakes_the_robot_to_rest():
    """`mca-drake live --robot` in its own process, killed (SIGKILL) while the robot moves:
    its driver process learns of it (the kernel's parent-death signal), brakes the emulated
    robot to rest inside every limit, holds it there a moment and ends; the robot, left
    without replies, stops where it stands (RSI's own end)."""
    port, telemetry_port = free_udp_port(), free_udp_port()
    command = [
        sys.executable,
        "-c",
        "import sys; from mca_drake.app.cli import main; sys.exit(main())",
    ]
    command += ["live", "--protocol", "csv", "--port", str(telemetry_port), "--duration", "30"]
    command += ["--mca", "washout", "--robot", f"rsi://127.0.0.1:{port}"]
    live = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    try:
        assert "listening on udp://" in live.stdout.readline()
        threading.Thread(
            target=stream,
            args=(("127.0.0.1", telemetry_port), 6.0),
            kwargs={"gap": (9, 9)},
            daemon=True,
        ).start()
        home_deg = np.degrees([0.0, 0.0, 0.5, 0.0, -0.5, 0.0]).tolist()
        emulator = RsiEmulator(
            ("127.0.0.1", port), RsiEmulatorConfig(cycle_s=CYCLE, start_deg=home_deg)
        )
        killer = threading.Timer(2.5, lambda: live.send_signal(signal.SIGKILL))
        killer.start()
        report = emulator.run(5.5)
        emulator.close()
    finally:
        live.kill()
        live.wait(timeout=10)
    # no limit met: the replies ended after the driver had braked and held the robot
    assert report["stop_reason"].endswith("without an on-time reply"), report
    assert report["cycles"] < round(5.0 / CYCLE)  # it ended before the robot stopped asking
    # before the driver's end, the replies came on time
    assert report["missed_before_stop"] <= 0.03 * report["on_time"], report
    recording = emulator.recording()
    answered = np.isfinite(recording["latency_s"])
    axes = recording["axes_deg"][answered] - home_deg
    moving = np.abs(np.diff(axes, axis=0)).max(axis=1) / CYCLE
    assert moving[: round(2.4 / CYCLE)].max() > 0.5  # deg/s: it moved before the kill
    np.testing.assert_array_equal(axes[-1], axes[-40])  # at rest, held, at the end


# slow: its 1e-5 deg bound holds only when every 4 ms cycle is on time, which a loaded
# 2-core machine running the whole suite does not always give
@pytest.mark.slow
def test_a_replayed_flight_drives_the_emulated_axes_along_the_mcas_trajectory(robot):
    """The DPC on a built-in light-aircraft flight (a training seed), closed on the
    analytical plant; its states and commands, sent as the loop sends them in real time,
    drive the emulated axes exactly along the plant's trajectory: to 1e-5 deg (the replies'
    six decimals) at the best whole-millisecond offset, every reply on time with its IPOC;
    the end segment brings the robot to rest."""
    reference = flight_reference(FlightSpec(vehicle="light", seed=3), 3.0)
    result = run_closed_loop(
        mca="dpc", reference=reference, plant="analytical", progress=False, robot=KR500
    )
    segments = [
        CommandSegment(k, x[:6], x[6:], u)
        for k, (x, u) in enumerate(zip(result.states[:-1], result.commands[:-1], strict=True))
    ]
    last = result.states[-1]
    segments.append(CommandSegment(len(segments), last[:6], last[6:], [0.0] * 6, end=True))
    report, status, recording = drive_emulator(robot, segments, len(segments) * H + 3.0)
    assert status["mode"] == "stopped" and status["reason"] == "the loop ended", status
    assert report["stop_reason"] == "" and report["bad_replies"] == 0, report
    assert report["late"] + report["missed"] <= 0.03 * report["cycles"], report
    _, error = best_offset_error(recording, segments[:-1], 0.0)
    assert error < 1e-5  # deg
    assert np.abs(recording["axes_deg"]).max() > 0.5  # the flight moved it
