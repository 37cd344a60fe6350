"""2- and 3-DOF rigs: their chains and actuator lengths against closed forms, their files
refused where they cannot move, and the washout (tilt coordination on the coordinates a
rig has) and the NMPC-rti cueing a reference far beyond them with zero actuator
violations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_hexapod_platform import far_reference

from mca_drake.platforms.files import load_platform
from mca_drake.platforms.kinematics import head_pose
from mca_drake.platforms.legs import leg_lengths
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.systems.washout import tracked_velocity_components


def rot_y(a):
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def rot_x(a):
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def test_the_two_dof_seat_turns_about_its_pivot():
    rig = load_platform("rig-2dof")
    assert rig.kind == "rig-2dof" and rig.joint_names == ("pitch", "roll")
    g = rig.actuators
    rng = np.random.default_rng(0)
    for pitch, roll in rng.uniform(0.8 * rig.q_min, 0.8 * rig.q_max, size=(20, 2)):
        R = rot_y(pitch) @ rot_x(roll)
        pivot = np.array([0.0, 0.0, g.neutral_height])
        X = head_pose(np.array([[pitch, roll]]), rig)[0]
        np.testing.assert_allclose(X[:3, :3], R, atol=1e-14)
        np.testing.assert_allclose(X[:3, 3], pivot + R @ np.array(rig.head_position), atol=1e-14)
        # each actuator spans its base joint to its seat joint turned about the pivot
        expected = [
            np.linalg.norm(pivot + R @ np.array(p) - np.array(b))
            for b, p in zip(g.base_joints, g.platform_joints, strict=True)
        ]
        np.testing.assert_allclose(rig.actuator_positions([pitch, roll]), expected, atol=1e-14)


def test_the_three_dof_rig_heaves_on_all_three_actuators():
    rig = load_platform("rig-3dof")
    assert rig.kind == "rig-3dof" and rig.joint_names == ("heave", "pitch", "roll")
    neutral = rig.actuator_positions([0.0, 0.0, 0.0])
    # heave alone lengthens every vertical actuator by the heave
    np.testing.assert_allclose(rig.actuator_positions([0.05, 0.0, 0.0]), neutral + 0.05)
    # pitch nose-down (positive about y) raises the rear (x < 0) and lowers the front
    lengths = rig.actuator_positions([0.0, 0.1, 0.0]) - neutral
    front, rear = lengths[:2], lengths[2]
    assert np.all(front < 0) and rear > 0
    # heave reaches the stroke's end at the box edge: 75 mm each way
    assert rig.q_max[0] == pytest.approx(0.075, abs=1e-8)
    assert rig.q_min[0] == pytest.approx(-0.075, abs=1e-8)
    J = rig.actuator_jacobian(np.zeros(3))
    assert J.shape == (3, 3)
    np.testing.assert_allclose(J[:, 0], 1.0)


def test_the_washout_tracks_the_head_velocity_a_rig_can_make():
    assert tracked_velocity_components(load_platform("rig-2dof")) == [
        True,
        True,
        False,
        False,
        False,
        False,
    ]
    assert tracked_velocity_components(load_platform("rig-3dof")) == [
        True,
        True,
        False,
        False,
        False,
        True,
    ]
    assert tracked_velocity_components(load_platform("hexapod")) == [True] * 6
    assert tracked_velocity_components(load_platform("kr500")) == [True] * 6


@pytest.mark.parametrize("rig", ["rig-2dof", "rig-3dof"])
@pytest.mark.parametrize("mca", ["washout", "nmpc-rti"])
def test_a_rig_cues_a_reference_beyond_it_without_an_actuator_violation(rig, mca):
    robot = load_platform(rig)
    result = run_closed_loop(
        mca=mca, reference=far_reference(8.0), duration_s=6.0, progress=False, robot=robot
    )
    s = result.summary
    assert sum(s["violations"].values()) == 0, s["violations"]
    lengths = leg_lengths(robot.pose(result.states[:, : robot.num_joints]), robot.actuators)
    g = robot.actuators
    assert np.all((lengths >= g.min_position) & (lengths <= g.max_position))
    assert np.ptp(lengths) > 0.01  # it moved
    if mca == "washout":
        assert s["pi"] < s["pi_zero_motion"]


RIG = """!Rig
coordinates: {coordinates}
base_joints: {base}
platform_joints: {base}
neutral_height: 0.45
min_length: 0.375
max_length: 0.525
max_speed: 0.2
max_acceleration: 5.0
"""
TWO = "[[-0.35, 0.3, 0.0], [-0.35, -0.3, 0.0]]"


@pytest.mark.parametrize(
    "coordinates, base, message",
    [
        ("[pitch, wobble]", TWO, "must be some of"),
        ("[roll, pitch]", TWO, "chain order"),
        ("[heave, pitch, roll]", TWO, "do not hold every coordinate"),
        ("[]", TWO, "lists the coordinates"),
        ("[pitch, roll]", "[[0, 0, 0]]", "moves no leg"),
        ("pitch", TWO, "list of names"),
    ],
)
def test_a_rig_that_cannot_move_as_it_says_is_refused(tmp_path, coordinates, base, message):
    path = tmp_path / "rig.yaml"
    path.write_text(RIG.format(coordinates=coordinates, base=base))
    with pytest.raises(ValueError, match=message):
        load_platform(path)


def test_a_scenario_cues_a_hexapod_or_a_seat_described_inline():
    """`platform: !Hexapod {...}` and `!Rig {...}` in a scenario (or --set) build the same
    platform as the file would, and a closed loop runs on it within every leg limit."""
    from mca_drake.app.jobs import run_closed_loop_scenario
    from mca_drake.app.scenarios import load_scenario

    hexapod = (
        "{platform: !Hexapod {name: inline-hexapod, base_radius: 1.2, platform_radius: 0.55, "
        "base_half_angle: 0.349066, platform_half_angle: 0.0698132, neutral_height: 1.05, "
        "stroke: 0.30, max_speed: 0.25, max_acceleration: 4.0, head_position: [0, 0, 1.1]}}"
    )
    seat = (
        "{platform: !Rig {name: inline-seat, coordinates: [pitch, roll], "
        "base_joints: [[-0.35, 0.30, 0.0], [-0.35, -0.30, 0.0]], "
        "platform_joints: [[-0.35, 0.30, 0.0], [-0.35, -0.30, 0.0]], neutral_height: 0.45, "
        "min_length: 0.375, max_length: 0.525, max_speed: 0.2, max_acceleration: 5.0}}"
    )
    quick = "{mca: washout, plant: analytical, duration_s: 2.0}"
    for override, name, kind, dof in (
        (hexapod, "inline-hexapod", "hexapod", 6),
        (seat, "inline-seat", "rig-2dof", 2),
    ):
        scenario = load_scenario("closed_loop_dpc", [quick, override])
        result = run_closed_loop_scenario(scenario, progress=False, json_path="", plot_dir="")
        platform = result.summary["platform"]
        assert (platform["name"], platform["kind"], platform["dof"]) == (name, kind, dof)
        assert sum(result.summary["violations"].values()) == 0
        assert "actuator_position" in result.summary["violations"]
    with pytest.raises(ValueError, match="platform"):
        load_scenario("closed_loop_dpc", [quick, seat.replace("[pitch, roll]", "[roll, pitch]")])
