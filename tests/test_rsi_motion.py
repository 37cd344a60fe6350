"""The RSI driver's motion: segments, their exact trajectory, and the per-cycle follower."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from conftest import RSI_LOOP_PERIOD as H
from conftest import limits_of, mca_like_segments
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from scipy.integrate import solve_ivp

from mca_drake.live.rsi.motion import (
    BadSegment,
    CommandSegment,
    MotionFollower,
    RsiMotionConfig,
    SegmentBuffer,
)
from mca_drake.safety import ViabilityClamp
from mca_drake.systems import MotionCueingPlant

T = 0.004  # the robot's cycle


def test_segments_round_trip_and_bad_datagrams_are_refused():
    segment = CommandSegment(42, [0.1] * 6, [-0.2] * 6, [1.5] * 6, end=True)
    back = CommandSegment.unpack(segment.pack(), 6)
    assert back == segment
    good = segment.pack()
    # the layout: magic, flags, k, then 18 little-endian doubles (struct as the oracle)
    assert good == struct.pack("<4sIq18d", b"MCAS", 1, 42, *[0.1] * 6, *[-0.2] * 6, *[1.5] * 6)
    rail = CommandSegment(7, range(7), [0.5] * 7, [-1.0] * 7)
    assert CommandSegment.unpack(rail.pack(), 7) == rail
    with pytest.raises(BadSegment, match=r"expected 160 \(6 joints\)"):
        CommandSegment.unpack(rail.pack(), 6)  # the loop and the driver disagree
    for bad, why in (
        (good[:-1], "bytes"),
        (b"XXXX" + good[4:], "starts"),
        (good[:4] + (7).to_bytes(4, "little") + good[8:], "flags"),
        (good[:-8] + np.float64(np.nan).tobytes(), "finite"),
    ):
        with pytest.raises(BadSegment, match=why):
            CommandSegment.unpack(bad, 6)
    with pytest.raises(ValueError, match="k must be"):
        CommandSegment(-1, [0] * 6, [0] * 6, [0] * 6)
    with pytest.raises(ValueError, match="qd must hold 7"):
        CommandSegment(0, [0] * 7, [0] * 6, [0] * 7)


def test_the_segments_trajectory_is_the_analytical_plants(robot, rng):
    """At every segment's end the buffer's trajectory meets the MotionCueingPlant's next
    state (Drake's discrete step as the oracle), and inside a segment it is the solution of
    qdd = u_k (scipy's integrator as the oracle)."""
    segments = mca_like_segments(robot, rng, 30)
    buffer = SegmentBuffer(H, capacity=64)
    for segment in segments:
        assert buffer.add(segment)
    for segment in segments[:-1]:
        builder = DiagramBuilder()
        plant = builder.AddSystem(
            MotionCueingPlant(robot, H, initial_state=np.r_[segment.q, segment.qd])
        )
        source = builder.AddSystem(ConstantVectorSource(np.array(segment.u)))
        builder.Connect(source.get_output_port(), plant.GetInputPort("joint_acceleration"))
        simulator = Simulator(builder.Build())
        simulator.AdvanceTo(H)
        x_next = plant.GetOutputPort("state").Eval(
            plant.GetMyContextFromRoot(simulator.get_context())
        )
        q, qd, end = buffer.state_at((segment.k + 1) * H - 1e-12)
        np.testing.assert_allclose(np.r_[q, qd], x_next, atol=1e-9)
        assert not end
    segment = segments[7]
    u = np.array(segment.u)
    ode = solve_ivp(
        lambda t, x: np.r_[x[6:], u],
        (0.0, 0.0037),
        np.r_[segment.q, segment.qd],
        rtol=1e-12,
        atol=1e-14,
    )
    q, qd, _ = buffer.state_at(7 * H + 0.0037)
    np.testing.assert_allclose(np.r_[q, qd], ode.y[:, -1], atol=1e-10)
    assert buffer.state_at(30 * H + 1e-6) is None  # not sent yet
    assert buffer.lead_s(25 * H) == pytest.approx(5 * H)


def test_the_buffer_keeps_the_newest_segments_and_ignores_repeats():
    buffer = SegmentBuffer(H, capacity=4)
    zeros = [0.0] * 6
    for k in range(10):
        assert buffer.add(CommandSegment(k, zeros, zeros, zeros))
    assert not buffer.add(CommandSegment(9, zeros, zeros, zeros))  # a repeat
    assert not buffer.add(CommandSegment(2, zeros, zeros, zeros))  # older than kept
    assert buffer.state_at(5.5 * H) is None and buffer.state_at(6.5 * H) is not None
    buffer.add(CommandSegment(10, zeros, zeros, zeros, end=True))
    assert not buffer.add(CommandSegment(11, zeros, zeros, zeros))  # after the end
    assert buffer.state_at(10.2 * H)[2]


def play(follower, buffer, cycles: int, delay: float, start_cycle: int = 0):
    """Steps the follower `cycles` robot cycles (s = n T - delay); returns per cycle the
    target the buffer holds (or None), the commanded q, qd and the mode."""
    rows = []
    for n in range(start_cycle, start_cycle + cycles):
        s = n * T - delay
        target = buffer.state_at(s) if s >= 0 else None
        q = follower.step(s, T, buffer) if s >= 0 else follower.q
        rows.append((target, list(q), list(follower.qd), follower.mode))
    return rows


def test_the_follower_plays_a_viable_run_exactly_then_brakes_when_the_commands_stop(robot, rng):
    """On a run the loop could have sent, every cycle's commanded state is the trajectory's
    own (no check trips); when the segments stop coming the follower brakes from the last
    state it sent: no jump, within every limit, to rest, where it holds."""
    segments = mca_like_segments(robot, rng, 150, gain=1.5)
    buffer = SegmentBuffer(H, capacity=256)
    for segment in segments:
        buffer.add(segment)
    follower = MotionFollower(limits_of(robot), np.zeros(6), RsiMotionConfig(cycle_s=T))
    delay = 0.025
    # then up to 3 s to brake (joint 4's top speed takes 2.8 s to stop)
    rows = play(follower, buffer, round((150 * H + delay + 3.0) / T), delay)
    following = [r for r in rows if r[3] == "following"]
    assert len(following) >= round(150 * H / T) - 1
    for target, q, qd, _ in following:
        assert q == target[0] and qd == target[1]
    assert follower.mode == "stopped" and "no command" in follower.reason
    assert max(abs(v) for v in following[-1][2]) > 0.05  # it was moving when they stopped
    q = np.array([r[1] for r in rows])
    qd = np.array([r[2] for r in rows])
    assert np.all(q >= robot.q_min - 1e-9) and np.all(q <= robot.q_max + 1e-9)
    assert np.all(np.abs(qd) <= robot.qd_max * (1 + 1e-9))
    mean_acceleration = np.diff(qd, axis=0) / T
    assert np.all(np.abs(mean_acceleration) <= robot.qdd_max * (1 + 1e-6))
    # no jump: no cycle moves further than the speed allows, and while braking (a constant
    # acceleration per cycle) the position moves exactly as the velocities say
    assert np.all(np.abs(np.diff(q, axis=0)) <= robot.qd_max * T * (1 + 1e-9))
    # and what the controller checks: the second differences of the positions sent
    assert np.all(np.abs(np.diff(q, 2, axis=0)) / T**2 <= robot.qdd_max * (1 + 1e-6) + 1e-6)
    braking = np.array([r[3] == "braking" for r in rows[1:]])
    assert braking.sum() >= 5
    step = np.diff(q, axis=0)[braking]
    np.testing.assert_allclose(step, (0.5 * T * (qd[1:] + qd[:-1]))[braking], atol=1e-12)
    np.testing.assert_array_equal(qd[-1], 0.0)
    np.testing.assert_array_equal(q[-1], q[-20])  # holds at rest


def test_braking_near_a_limit_stays_inside_it(robot):
    """A joint rushing at its upper limit, in a viable state, when the commands stop: the
    strongest braking the clamp allows stops it inside."""
    clamp = ViabilityClamp.for_robot(robot, T)
    j = 0
    q, qd = np.zeros(6), np.zeros(6)
    qd[j] = 0.9 * robot.qd_max[j]
    # as close to the limit as is still viable at this speed
    low, high = robot.q_min[j], robot.q_max[j]
    for _ in range(60):
        mid = 0.5 * (low + high)
        q[j] = mid
        low, high = (mid, high) if clamp.is_viable(np.r_[q, qd]) else (low, mid)
    q[j] = low
    buffer = SegmentBuffer(H)
    buffer.add(CommandSegment(0, q, qd, np.zeros(6)))
    follower = MotionFollower(limits_of(robot), np.zeros(6), RsiMotionConfig(cycle_s=T))
    follower.q, follower.qd, follower.mode = list(q), list(qd), "following"
    peak = q[j]
    for n in range(2000):
        follower.step(H + n * T, T, buffer)  # no segment there: braking
        peak = max(peak, follower.q[j])
        if follower.mode == "stopped":
            break
    assert follower.mode == "stopped"
    assert peak <= robot.q_max[j] + 1e-9
    assert follower.q[j] > q[j]  # it did travel on while braking


def test_a_jump_in_the_commands_brakes_instead_of_following(robot, rng):
    segments = mca_like_segments(robot, rng, 40)
    jumped = segments[20]
    segments[20] = CommandSegment(20, np.array(jumped.q) + 0.02, jumped.qd, jumped.u)
    buffer = SegmentBuffer(H)
    for segment in segments:
        buffer.add(segment)
    follower = MotionFollower(limits_of(robot), np.zeros(6), RsiMotionConfig(cycle_s=T))
    rows = play(follower, buffer, 150, delay=0.0)
    assert follower.mode in ("braking", "stopped")
    assert "a jump in the commands" in follower.reason
    q = np.array([r[1] for r in rows])
    assert np.max(np.abs(np.diff(q, axis=0))) < 0.02  # the jump was never sent


def test_the_end_of_the_run_brakes_and_a_halt_before_the_start_holds_home(robot, rng):
    segments = mca_like_segments(robot, rng, 20)
    last = segments[-1]
    end_state = np.r_[last.q, last.qd]  # the state at its start; the end holds from there
    buffer = SegmentBuffer(H)
    for segment in segments[:-1]:
        buffer.add(segment)
    buffer.add(CommandSegment(19, end_state[:6], end_state[6:], [0.0] * 6, end=True))
    follower = MotionFollower(limits_of(robot), np.zeros(6), RsiMotionConfig(cycle_s=T))
    play(follower, buffer, 200, delay=0.0)
    assert follower.mode == "stopped" and follower.reason == "the loop ended"
    idle = MotionFollower(limits_of(robot), np.zeros(6), RsiMotionConfig(cycle_s=T))
    idle.halt("the telemetry went stale")
    assert idle.mode == "stopped" and idle.q == [0.0] * 6
    idle.step(0.5, T, buffer)
    assert idle.q == [0.0] * 6  # halted: nothing is followed any more


def test_bad_settings_and_an_unviable_home_are_refused(robot):
    with pytest.raises(ValueError, match="home pose"):
        MotionFollower(limits_of(robot), robot.q_max + 0.1, RsiMotionConfig())
    with pytest.raises(ValueError, match="cycle_s"):
        RsiMotionConfig(cycle_s=0.0).validate()
    with pytest.raises(ValueError, match="delay_s"):
        RsiMotionConfig(delay_s=math.nan).validate()
    with pytest.raises(ValueError, match="capacity"):
        SegmentBuffer(H, capacity=1)
