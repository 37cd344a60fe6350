"""The DPC's policy for a reference that names no vehicle: recognized from the reference as
it goes (`mca_drake.cueing.recognition`), handed over smoothly, reported in the summary.

Oracles: the transport envelope's published rates (20, 6, 5 deg/s, 14 CFR / CS 25
handling) times the reference's angular scale; the closed-form step response of a
first-order discrete low-pass, lp_k = A (1 - (1 - alpha)^k); the smoothstep 3 s^2 - 2 s^3;
and `PolicyInference` of each policy alone for the blended command.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from mca_drake.cueing.dpc import DpcConfig, PolicyInference, policy_record
from mca_drake.cueing.recognition import (
    GROUND,
    LIGHT,
    RECOGNIZED_POLICIES,
    TRANSPORT,
    RecognitionConfig,
    initial_recognition_state,
    policy_changes,
    policy_weights,
    recognition_final,
    recognition_step,
    recognized_policy,
)
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.resources import data_dir
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.systems.dpc import DpcPolicy

DT = 0.01
CONFIG = RecognitionConfig()


def _run(samples: np.ndarray, config: RecognitionConfig = CONFIG) -> tuple[np.ndarray, list]:
    """The recognizer's state after `samples` (T, 6) and the policy chosen after each."""
    state = initial_recognition_state()
    chosen = []
    for sample in samples:
        recognition_step(state, sample, DT, config)
        chosen.append(recognized_policy(state))
    return state, chosen


def _first_crossing(amplitude: float, bound: float, config: RecognitionConfig = CONFIG) -> int:
    """The 1-based sample at which a step of `amplitude` smoothed by the recognizer's
    low-pass first exceeds `bound`: lp_k = A (1 - (1 - alpha)^k) > bound."""
    alpha = DT / (config.smoothing_s + DT)
    return math.floor(math.log(1.0 - bound / amplitude) / math.log(1.0 - alpha)) + 1


def test_the_transport_bounds_are_the_transport_envelopes_rates_on_the_reference():
    deg = math.pi / 180.0
    expected = (0.5 * 20.0 * deg, 0.5 * 6.0 * deg, 0.5 * 5.0 * deg)
    assert CONFIG.transport_rates == pytest.approx(expected, rel=1e-12)


def test_a_reference_inside_the_transport_envelope_gets_the_transport_policy_once_settled():
    rates = 0.8 * np.asarray(CONFIG.transport_rates)
    samples = np.tile(np.r_[rates, 1.0, 0.3, 0.8], (3000, 1))
    state, chosen = _run(samples)
    settle = round(CONFIG.settle_s / DT)  # the step whose time reaches settle_s
    assert chosen[settle - 2] == 0 and chosen[settle - 1] == TRANSPORT
    assert policy_changes(state) == [(pytest.approx(CONFIG.settle_s), TRANSPORT)]


def _pull(samples: int, pitch_rate: float, vertical: float) -> np.ndarray:
    """A pull-up: pitch rate `pitch_rate` (rad/s, up: y points left, so w_y < 0) with the
    vertical specific force `vertical` (m/s^2 above 1 g), both on the reference."""
    pull = np.zeros((samples, 6))
    pull[:, 1], pull[:, 5] = -pitch_rate, vertical
    return pull


def test_a_slow_pull_beyond_a_transports_rates_brings_the_light_policy_a_fast_roll_ends_it():
    """The transport ruled out by a pull at a light aircraft's speed, inside a light
    aircraft's bounds: the light policy at once; a trainer's roll ends it for good."""
    transport, light = CONFIG.transport_rates[1], CONFIG.light_roll_rate
    quiet = np.zeros((2500, 6))
    # 2 x the transport's pitch rate at 2 m/s^2: a pull at 2 / 0.105 = 19 m/s, a light
    # aircraft's speed (a_z / -w_y = g (n - 1) / q at the default scales)
    pull = _pull(600, 2.0 * transport, 2.0)
    roll = np.zeros((300, 6))
    roll[:, 0] = 2.0 * light  # a roll rate of a trainer or a fighter
    state, chosen = _run(np.vstack((quiet, pull, roll, quiet)))
    not_transport = 2500 + _first_crossing(2.0 * transport, transport)
    assert chosen[not_transport - 2] == TRANSPORT and chosen[not_transport - 1] == LIGHT
    to_default = 3100 + _first_crossing(2.0 * light, light)
    assert chosen[to_default - 2] == LIGHT and chosen[to_default - 1] == 0
    assert set(chosen[to_default - 1 :]) == {0}  # the quiet that follows does not return it
    assert policy_changes(state) == [
        (pytest.approx(CONFIG.settle_s), TRANSPORT),
        (pytest.approx(not_transport * DT), LIGHT),
        (pytest.approx(to_default * DT), 0),
    ]


def test_the_light_policy_can_wait_for_seconds_of_slow_pulls():
    """With `light_needs_slow_pulls` the default runs from the transport's end until the
    pulls have been slow for `light_pull_s`."""
    config = RecognitionConfig(light_needs_slow_pulls=True)
    transport = config.transport_rates[1]
    quiet = np.zeros((2500, 6))
    state, chosen = _run(np.vstack((quiet, _pull(600, 2.0 * transport, 2.0), quiet)), config)
    not_transport = 2500 + _first_crossing(2.0 * transport, transport, config)
    assert chosen[not_transport - 2] == TRANSPORT and chosen[not_transport - 1] == 0
    # a pull from where both smoothed signals pass their thresholds, for light_pull_s
    pulling = max(
        _first_crossing(2.0 * transport, config.pull_pitch_rate, config),
        _first_crossing(2.0, config.pull_vertical, config),
    )
    to_light = 2500 + pulling + round(config.light_pull_s / DT) - 1
    assert chosen[to_light - 2] == 0 and chosen[to_light - 1] == LIGHT
    assert [i for _, i in policy_changes(state)] == [TRANSPORT, 0, LIGHT]


def test_fast_pulls_are_never_a_light_aircrafts_and_end_its_policy():
    # 0.06 rad/s at 4 m/s^2: 67 m/s, a trainer's or a fighter's pull, beyond the
    # transport's pitch rate: the pulls so far are fast when the transport is ruled out
    _, chosen = _run(np.vstack((np.zeros((2500, 6)), _pull(3000, 0.06, 4.0))))
    assert LIGHT not in chosen and chosen[-1] == 0
    # a slow pull brings the light policy; fast pulls of more than half its time end it
    mixed = np.vstack((_pull(500, 0.1, 2.0), np.zeros((300, 6)), _pull(800, 0.06, 4.0)))
    state, chosen = _run(np.vstack((np.zeros((2500, 6)), mixed, np.zeros((1000, 6)))))
    assert [i for _, i in policy_changes(state)] == [TRANSPORT, LIGHT, 0]
    assert chosen[-1] == 0


def test_pulls_that_swing_about_the_ratio_keep_the_light_policy_until_fast_ones_outlast():
    """Slow pulls bring the light policy; once it runs it stays, as a named light
    aircraft's does, while fast pulls last no longer than the slow ones, however often the
    two alternate; fast pulls outlasting them end it for good: the slow pulls that follow
    do not bring it back, so the change record (at most default, transport, default,
    light, default, ground) never overflows."""
    # 0.1 rad/s at 2 m/s^2 (20 m/s, a light single's pull) and 0.06 rad/s at 4 m/s^2 (67
    # m/s, a trainer's): 4 s slow, 4 s fast, then three times as much slow as fast, 8 times
    slow, fast = _pull(400, 0.1, 2.0), _pull(400, 0.06, 4.0)
    quiet = np.zeros((2500, 6))
    swinging = np.vstack((quiet, slow, fast, *([slow, slow, slow, fast] * 8)))
    state, chosen = _run(swinging)
    assert [i for _, i in policy_changes(state)] == [TRANSPORT, LIGHT]
    assert chosen[-1] == LIGHT
    # about 100 s of slow pulls against 36 s of fast ones: 120 s more of fast outlast them
    state, chosen = _run(np.vstack((swinging, _pull(12000, 0.06, 4.0), *([slow] * 10))))
    assert [i for _, i in policy_changes(state)] == [TRANSPORT, LIGHT, 0]
    left = round(policy_changes(state)[-1][0] / DT)
    assert len(swinging) < left < len(swinging) + 12000 and LIGHT not in chosen[left:]


def test_the_light_bounds_are_the_light_envelopes_yaw_and_surge_on_the_reference():
    assert CONFIG.light_yaw_rate == pytest.approx(0.5 * 20.0 * math.pi / 180.0, rel=1e-12)
    # 0.3 g and a third more, times the force scale 0.5, with g = 9.81 m/s^2
    assert CONFIG.light_surge == pytest.approx(0.5 * 0.4 * 9.81, rel=1e-3)


def test_a_reference_that_leaves_the_light_bounds_before_it_settles_keeps_the_default():
    surge = np.zeros((3000, 6))
    surge[:500, 3] = 2.0 * CONFIG.light_surge  # a fighter's afterburner take-off...
    surge[:500, 0] = 1.5 * CONFIG.transport_rates[0]  # ...rolling as no transport does
    _, chosen = _run(surge)
    assert set(chosen) == {0}
    off = RecognitionConfig(recognize_light=False)
    pull = np.zeros((3000, 6))
    pull[:, 1] = 2.0 * off.transport_rates[1]
    _, chosen = _run(pull, off)
    assert set(chosen) == {0}


def test_a_single_sample_spike_does_not_rule_out_a_transport():
    samples = np.zeros((2200, 6))
    samples[500, :3] = 10.0 * np.asarray(CONFIG.transport_rates)  # moves the low-pass by 0.1
    _, chosen = _run(samples)
    assert chosen[-1] == TRANSPORT


def test_a_level_lateral_force_without_roll_is_recognized_as_a_car():
    samples = np.zeros((1000, 6))
    samples[:, 4] = 2.0  # f_y on the reference, m/s^2
    samples[:, 2] = 0.15  # a car's yaw rate in the bend: no transport
    _, chosen = _run(samples)
    evidence = _first_crossing(2.0, CONFIG.ground_lateral)
    held = round(CONFIG.ground_hold_s / DT)
    assert chosen[evidence + held - 3] == 0 and chosen[evidence + held - 2] == GROUND
    assert chosen[-1] == GROUND


def test_an_aircraft_that_pulled_g_is_never_taken_for_a_car():
    pull = np.zeros((300, 6))
    pull[:, 5] = 3.0  # a_z: load factor no road gives
    skid = np.zeros((1000, 6))
    skid[:, 4] = 2.0
    _, chosen = _run(np.vstack((pull, skid)))
    assert GROUND not in chosen


def test_the_hand_over_is_a_smoothstep_over_its_time():
    config = RecognitionConfig(settle_s=0.5, handover_s=0.4)
    state = initial_recognition_state()
    weights = []
    for _ in range(120):
        recognition_step(state, np.zeros(6), DT, config)
        weights.append(policy_weights(state, config))
    change = round(config.settle_s / DT) - 1  # index of the step that changed
    assert weights[change - 1] == (0, -1, 1.0)
    for k in range(change, change + 40):
        share = (k - change) * DT / config.handover_s
        policy, previous, weight = weights[k]
        assert (policy, previous) == (TRANSPORT, 0)
        assert weight == pytest.approx(3 * share**2 - 2 * share**3, abs=1e-9)
    assert weights[change + 40] == (TRANSPORT, -1, 1.0)


def test_the_hand_back_to_the_default_takes_its_own_shorter_time():
    # light aircraft not recognized: the roll's first 0.1 s is inside a light one's bounds
    config = RecognitionConfig(settle_s=0.5, handover_s=0.4, handback_s=0.1, recognize_light=False)
    state = initial_recognition_state()
    roll = np.zeros(6)
    roll[0] = 10.0 * config.transport_rates[0]
    weights = []
    for k in range(200):
        recognition_step(state, roll if k >= 100 else np.zeros(6), DT, config)
        weights.append(policy_weights(state, config))
    ((_, _), (back, _)) = policy_changes(state)
    change = round(back / DT) - 1  # the step that handed back
    assert weights[change - 1] == (TRANSPORT, -1, 1.0)
    for k in range(change, change + 10):
        share = (k - change) * DT / config.handback_s
        assert weights[k][:2] == (0, TRANSPORT)
        assert weights[k][2] == pytest.approx(3 * share**2 - 2 * share**3, abs=1e-9)
    assert weights[change + 10] == (0, -1, 1.0)


def test_decisions_become_final_and_stay_so():
    roll = np.zeros((400, 6))
    roll[:, 0] = 2.0 * CONFIG.light_roll_rate  # a fighter's roll: no transport, no light
    pull = np.zeros((200, 6))
    pull[:, 5] = 3.0  # a pull no road gives: no car
    state, chosen = _run(np.vstack((roll, pull)))
    assert recognition_final(state, CONFIG) and set(chosen) == {0}
    for sample in (np.zeros(6), np.array([0.0, 0.0, 0.15, 0.0, 2.0, 0.0])):
        for _ in range(500):  # a transport's calm, a car's bend: nothing changes now
            recognition_step(state, sample, DT, CONFIG)
    assert recognized_policy(state) == 0 and policy_changes(state) == []
    # a car's decision is final once handed over; a transport's never
    bend = np.zeros((600, 6))
    bend[:, 4], bend[:, 2] = 2.0, 0.15
    state, _ = _run(bend)
    assert recognized_policy(state) == GROUND and recognition_final(state, CONFIG)
    state, _ = _run(np.zeros((2500, 6)))
    assert recognized_policy(state) == TRANSPORT and not recognition_final(state, CONFIG)


def test_settings_that_are_not_positive_are_refused():
    with pytest.raises(ValueError, match="handover_s"):
        RecognitionConfig(handover_s=0.0).validate()
    with pytest.raises(ValueError, match="transport_rates"):
        RecognitionConfig(transport_rates=(0.1, math.nan, 0.1)).validate()
    with pytest.raises(ValueError, match="unnamed"):
        DpcConfig(unnamed="guess").validate()


def _tiny_policy(rng: np.random.Generator, joints: int) -> dict[str, np.ndarray]:
    """A random policy whose commands stay far inside its bounds and the clamp's limits."""
    inputs, hidden = 12 + 2 * joints, 8
    return {
        "W1": 0.1 * rng.standard_normal((hidden, inputs)),
        "W2": 0.1 * rng.standard_normal((3 * joints, hidden)),
        "input_scale": np.ones(inputs),
        "lower": -np.ones(3 * joints),
        "upper": np.ones(3 * joints),
    }


def test_the_dpc_blends_the_commands_of_the_two_policies_while_handing_over():
    robot = load_platform("kr500")
    n = robot.num_joints
    rng = np.random.default_rng(7)
    policies = tuple(_tiny_policy(rng, n) for _ in RECOGNIZED_POLICIES)
    config = RecognitionConfig(settle_s=0.3, handover_s=0.2)
    reference = np.r_[0.5 * np.asarray(config.transport_rates), 0.4, 0.1, 0.2]
    x, y = np.zeros(2 * n), np.array([0.01, -0.02, 0.0, 0.1, 0.05, -0.1])
    builder = DiagramBuilder()
    dpc = builder.AddSystem(
        DpcPolicy(policies[0], robot, DT, recognized=policies, recognition=config)
    )
    for port, value in (("reference", reference), ("state", x), ("inertial_output", y)):
        source = builder.AddSystem(ConstantVectorSource(value))
        builder.Connect(source.get_output_port(), dpc.GetInputPort(port))
    simulator = Simulator(builder.Build())
    context = dpc.GetMyContextFromRoot(simulator.get_mutable_context())
    u_default = PolicyInference(policies[0])(y, x, reference)[0]
    u_transport = PolicyInference(policies[TRANSPORT])(y, x, reference)[0]
    # AdvanceTo(k DT) runs the steps at 0, DT, .., (k - 1) DT (the one at k DT runs when the
    # simulation moves past it): k samples, the recognizer's clock at k DT
    for k in (10, 29, 30, 31, 35, 40, 49, 50, 60):
        simulator.AdvanceTo(k * DT)
        share = min(max((k * DT - config.settle_s) / config.handover_s, 0.0), 1.0)
        weight = 3 * share**2 - 2 * share**3
        expected = u_default + weight * (u_transport - u_default)
        command = dpc.GetOutputPort("joint_acceleration").Eval(context)
        assert command == pytest.approx(expected, abs=1e-12), k
    assert dpc.policy_changes(context) == [(pytest.approx(config.settle_s), TRANSPORT)]


def test_a_change_during_a_hand_over_goes_on_from_the_blend_it_reached():
    """A transport ruled out while the transport policy is still taking over hands back
    from the blend reached, not from the transport policy's command alone: the command
    is u_d + (1 - w) w0 (u_t - u_d), w0 the transport's weight at the change and w the
    hand-back's smoothstep, equal to the blend at the change (no step)."""
    robot = load_platform("kr500")
    n = robot.num_joints
    rng = np.random.default_rng(11)
    policies = tuple(_tiny_policy(rng, n) for _ in RECOGNIZED_POLICIES)
    config = RecognitionConfig(settle_s=0.3, handover_s=0.4, handback_s=0.4, recognize_light=False)
    calm = np.r_[0.5 * np.asarray(config.transport_rates), 0.4, 0.1, 0.2]
    roll = calm.copy()
    roll[0] = 10.0 * config.transport_rates[0]  # no transport's
    x, y = np.zeros(2 * n), np.array([0.01, -0.02, 0.0, 0.1, 0.05, -0.1])
    builder = DiagramBuilder()
    dpc = builder.AddSystem(
        DpcPolicy(policies[0], robot, DT, recognized=policies, recognition=config)
    )
    sources = {}
    for port, value in (("reference", calm), ("state", x), ("inertial_output", y)):
        sources[port] = builder.AddSystem(ConstantVectorSource(value))
        builder.Connect(sources[port].get_output_port(), dpc.GetInputPort(port))
    simulator = Simulator(builder.Build())
    root = simulator.get_mutable_context()
    context = dpc.GetMyContextFromRoot(root)
    simulator.AdvanceTo(0.4)  # the transport policy a quarter into its hand-over
    source = sources["reference"]
    source.get_mutable_source_value(source.GetMyMutableContextFromRoot(root)).SetFromVector(roll)
    u_d = PolicyInference(policies[0])(y, x, roll)[0]
    u_t = PolicyInference(policies[TRANSPORT])(y, x, roll)[0]
    commands = {}
    for k in range(41, 100):
        simulator.AdvanceTo(k * DT)
        commands[k] = dpc.GetOutputPort("joint_acceleration").Eval(context).copy()
    ((_, _), (back, policy)) = dpc.policy_changes(context)
    assert policy == 0 and config.settle_s + 0.1 < back < config.settle_s + config.handover_s

    def smoothstep(share: float) -> float:
        share = min(max(share, 0.0), 1.0)
        return 3 * share**2 - 2 * share**3

    w0 = smoothstep((back - config.settle_s) / config.handover_s)
    changed = round(back / DT)
    assert 0.1 < w0 < 0.9
    for k in range(changed, 100):
        w = smoothstep((k * DT - back) / config.handback_s)
        expected = u_d + (1.0 - w) * w0 * (u_t - u_d)
        assert commands[k] == pytest.approx(expected, abs=1e-12), k
    # the step before the change was the transport's blend: the change adds no step
    before = u_d + smoothstep(((changed - 1) * DT - config.settle_s) / config.handover_s) * (
        u_t - u_d
    )
    assert commands[changed - 1] == pytest.approx(before, abs=1e-12)
    assert np.abs(commands[changed] - commands[changed - 1]).max() < 0.05 * np.abs(u_t - u_d).max()


def test_an_unnamed_car_reference_runs_the_ground_policy_and_says_so():
    samples = np.zeros((600, 6))
    samples[:, 4] = 2.0
    samples[:, 2] = 0.15
    reference = Reference(y=samples, name="logger.csv")  # names no vehicle
    robot = load_platform("kr500")
    result = run_closed_loop(mca=DpcConfig(), reference=reference, robot=robot, progress=False)
    summary = result.summary
    assert summary["policy_file"] == "ground_policy.npz"
    changes = summary["policy_changes"]
    assert [c["policy_file"] for c in changes] == ["ground_policy.npz"]
    evidence = _first_crossing(2.0, CONFIG.ground_lateral)
    # held for ground_hold_s from the sample that brought the evidence, that one counted
    held = round(CONFIG.ground_hold_s / DT)
    assert changes[0]["t_s"] == pytest.approx((evidence + held - 1) * DT)
    assert "car" in summary["policy_reason"]


def _run_named(named: int, samples: np.ndarray) -> tuple[list, list]:
    """The policy a DPC that starts in `named` has chosen after each of `samples`, and its
    changes of policy."""
    state = initial_recognition_state(named)
    chosen = []
    for sample in samples:
        recognition_step(state, sample, DT, CONFIG)
        chosen.append(recognized_policy(state))
    return chosen, policy_changes(state)


def test_a_named_light_aircraft_starts_in_its_policy_and_hands_back_once_for_good():
    """No settling and no pulls needed: a named light aircraft runs the light policy from
    the first sample; a roll rate beyond the light bound hands back to the default at the
    sample where its smoothed magnitude passes the bound, and a gentle reference after it
    does not bring the light policy back."""
    assert policy_weights(initial_recognition_state(LIGHT), CONFIG) == (LIGHT, -1, 1.0)
    gentle = np.tile([0.1, 0.0, 0.05, 0.5, 0.2, 0.3], (2500, 1))
    chosen, changes = _run_named(LIGHT, gentle)
    assert set(chosen) == {LIGHT} and changes == []
    roll = np.zeros((1000, 6))
    roll[:, 0] = 0.6
    chosen, changes = _run_named(LIGHT, np.vstack([roll, gentle]))
    crossing = _first_crossing(0.6, CONFIG.light_roll_rate)
    assert chosen[crossing - 2] == LIGHT and chosen[crossing - 1] == 0
    assert set(chosen[crossing - 1 :]) == {0}
    assert changes == [(pytest.approx(crossing * DT), 0)]


def test_a_named_transport_hands_back_on_a_fighters_pitch_rate_and_is_never_a_car():
    pitch = np.zeros((800, 6))
    pitch[:, 1] = -3.0 * CONFIG.transport_rates[1]
    chosen, changes = _run_named(TRANSPORT, pitch)
    crossing = _first_crossing(3.0 * CONFIG.transport_rates[1], CONFIG.transport_rates[1])
    assert chosen[crossing - 2] == TRANSPORT and chosen[crossing - 1] == 0
    assert changes == [(pytest.approx(crossing * DT), 0)]
    # a car's evidence (level lateral force without roll) on a named transport: its bounds
    # hold (2 m/s^2 is inside its sideslip) and it stays the transport policy
    car = np.zeros((600, 6))
    car[:, 4] = 2.0
    chosen, _ = _run_named(TRANSPORT, car)
    assert set(chosen) == {TRANSPORT}
    with pytest.raises(ValueError, match="named"):
        initial_recognition_state(GROUND)


def test_a_named_envelope_vehicle_hands_back_unless_told_not_to():
    light = DpcConfig(vehicle="DHC6")
    assert light.hands_back() and light.first_policy() == LIGHT
    assert light.recognized_policy_paths("kr500") == DpcConfig().recognized_policy_paths("kr500")
    assert DpcConfig(vehicle="MD11").first_policy() == TRANSPORT
    # the hexapod's default policy stands for the light one: one policy, nothing handed
    assert light.recognized_policy_paths("hexapod") is None
    assert len(set(light.recognized_policy_paths("kr500-rail"))) == 4
    assert not light.recognizes() and not light.clips_reference()
    for config in (
        DpcConfig(vehicle="DHC6", envelope_handback=False),
        DpcConfig(vehicle="f16"),
        DpcConfig(vehicle="light", profile="ground"),
        DpcConfig(vehicle="light", predictor="learned"),
        DpcConfig(vehicle="bmw-320i"),
    ):
        assert not config.hands_back(), config
        assert config.recognized_policy_paths("kr500") is None, config
        assert config.first_policy() == 0
    with pytest.raises(ValueError, match="envelope_handback"):
        DpcConfig(envelope_handback="yes").validate()


def test_a_named_light_aircraft_rolled_hard_is_handed_to_the_default_and_says_so():
    """Closed loop: the named Twin Otter's run starts in the light policy (its first
    second array for array the light policy's run named outright) and, rolled beyond a
    light aircraft's bounds, ends in the default policy, its summary saying why."""
    t = np.arange(0.0, 4.0, DT)
    samples = np.zeros((t.size, 6))
    share = np.clip((t - 1.0) / 0.5, 0.0, 1.0)  # rolling in over 0.5 s from t = 1 s
    samples[:, 0] = 0.8 * share * share * (3.0 - 2.0 * share)
    reference = Reference(y=samples, name="flight", vehicle="DHC6")
    robot = load_platform("kr500")
    runs = [
        run_closed_loop(mca=config, reference=reference, robot=robot, progress=False)
        for config in (DpcConfig(), DpcConfig(envelope_handback=False))
    ]
    summary = runs[0].summary
    assert summary["policy_file"] == "default_policy.npz"
    assert "left a light aircraft's bounds" in summary["policy_reason"]
    changes = summary["policy_changes"]
    assert [c["policy_file"] for c in changes] == ["default_policy.npz"]
    # the first-order low-pass the recognizer smooths with, run on the samples: the sample
    # (1-based, as the recognizer's clock counts) where it first passes the light bound
    alpha = DT / (CONFIG.smoothing_s + DT)
    smoothed = 0.0
    crossing = None
    for step, w_x in enumerate(samples[:, 0], start=1):
        smoothed += alpha * (abs(w_x) - smoothed)
        if smoothed > CONFIG.light_roll_rate:
            crossing = step
            break
    assert changes[0]["t_s"] == pytest.approx(crossing * DT)
    assert runs[1].summary["policy_file"] == "light_policy.npz"
    assert "policy_changes" not in runs[1].summary
    np.testing.assert_array_equal(runs[0].outputs[:100], runs[1].outputs[:100])
    assert not np.array_equal(runs[0].outputs[-50:], runs[1].outputs[-50:])


def test_a_named_vehicle_or_the_default_setting_runs_one_policy():
    assert DpcConfig(vehicle="c172x").recognized_policy_paths("kr500") is None
    assert DpcConfig(vehicle="t6texan2").recognized_policy_paths("kr500") is None
    assert DpcConfig(unnamed="default").recognized_policy_paths("kr500") is None
    record = policy_record(DpcConfig(unnamed="default"), "kr500")
    assert record == {
        "policy_file": "default_policy.npz",
        "policy_reason": "no vehicle named: the default policy",
    }
    paths = DpcConfig().recognized_policy_paths("kr500")
    assert paths == tuple(data_dir() / f"{name}.npz" for name in RECOGNIZED_POLICIES)
    rail = DpcConfig().recognized_policy_paths("kr500-rail")
    assert [p.name for p in rail] == [f"kr500-rail_{n}.npz" for n in RECOGNIZED_POLICIES]
