"""Hexapods whose legs are turned by cranks (rotary actuators): the arms' angles against
an independent construction of the mechanism (Drake's rotation of each arm about its
motor's axis, the rod's length closing it), their derivatives against finite
differences, forward kinematics inverting them, torch equal to numpy, the description
file, and closed loops far beyond the rig's range inside every arm's limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RotationMatrix
from test_hexapod_platform import far_reference

from mca_drake.platforms.files import read_platform_file
from mca_drake.platforms.leg_platform import leg_platform, pose_of
from mca_drake.platforms.legs import (
    LegGeometry,
    _actuators,
    _legs,
    actuator_positions,
    forward_kinematics,
    leg_jacobian,
    leg_linearisation,
    leg_motion,
)
from mca_drake.simulation.closed_loop import run_closed_loop

# A seat-sized rotary hexapod: servos on a 0.5 m circle, arms of 0.15 m turning +-0.8 rad.
LAYOUT = dict(
    base_radius=0.5,
    platform_radius=0.35,
    base_half_angle=math.radians(12.0),
    platform_half_angle=math.radians(8.0),
    neutral_height=0.55,
    stroke=1.6,
    max_speed=3.0,
    max_acceleration=30.0,
    arm_length=0.15,
)


@pytest.fixture(scope="module")
def cranks() -> LegGeometry:
    geometry = LegGeometry.symmetric(**LAYOUT)
    geometry.validate()
    return geometry


@pytest.fixture(scope="module")
def platform(cranks):
    return leg_platform(
        cranks,
        name="crank-hexapod",
        head_position=(0.0, 0.0, 0.6),
        payload_mass=150.0,
        payload_inertia=(20.0, 20.0, 20.0),
    )


def random_poses(rng, count: int) -> np.ndarray:
    """Poses well inside a seat hexapod's reach: centimetres and a few degrees."""
    return rng.uniform(-1.0, 1.0, (count, 6)) * np.array([0.05, 0.05, 0.04, 0.1, 0.1, 0.15])


def test_each_arm_closes_the_mechanism_at_its_angle(cranks, rng):
    # Oracle: each arm's tip by Drake's rotation of the arm's zero direction about its
    # motor's axis; the rod from there must reach the platform joint, and the other
    # angle that closes it is the one farther from zero.
    c = cranks.cranks
    poses = random_poses(rng, 20)
    angles = actuator_positions(poses, cranks)
    legs = _legs(poses, cranks)
    base = np.asarray(cranks.base_joints)
    for pose_angles, pose_legs in zip(angles, legs, strict=True):
        for i, angle in enumerate(pose_angles):
            axis = np.asarray(c.motor_axes[i])
            arm = np.asarray(c.arm_directions[i])
            turned = RotationMatrix(AngleAxis(angle, axis)).multiply(arm)
            tip = base[i] + c.arm_length * turned
            joint = base[i] + pose_legs[i]
            assert np.linalg.norm(joint - tip) == pytest.approx(c.rod_length, abs=1e-12)
            # the other closing angle: scan the arm's circle for the rod's length
            scan = np.linspace(-math.pi, math.pi, 20001)
            tips = base[i] + c.arm_length * np.array(
                [RotationMatrix(AngleAxis(a, axis)).multiply(arm) for a in scan[::50]]
            )
            gaps = np.linalg.norm(joint - tips, axis=1) - c.rod_length
            roots = scan[::50][np.nonzero(np.diff(np.sign(gaps)))[0]]
            assert len(roots) == 2
            assert abs(angle) <= np.min(np.abs(roots)) + 0.02


def test_the_symmetric_layout_holds_its_arms_level_at_the_neutral_pose(cranks):
    np.testing.assert_allclose(actuator_positions(np.zeros(6), cranks), 0.0, atol=1e-12)
    # heave alone turns every arm the same way, up for up
    up = actuator_positions(np.array([0.0, 0.0, 0.02, 0.0, 0.0, 0.0]), cranks)
    assert np.all(up > 0) and np.ptp(up) < 1e-12


def test_the_angles_first_and_second_derivatives_by_the_leg_vector(cranks, rng):
    # Oracle: central differences of the closed-form angle and of its gradient.
    legs = _legs(random_poses(rng, 5), cranks)
    _, g, H = _actuators(legs, cranks)
    step = 1e-6
    for c in range(3):
        e = np.zeros(3)
        e[c] = step
        ahead, g_ahead, _ = _actuators(legs + e, cranks)
        behind, g_behind, _ = _actuators(legs - e, cranks)
        np.testing.assert_allclose(g[..., c], (ahead - behind) / (2 * step), atol=1e-8)
        np.testing.assert_allclose(H[..., c], (g_ahead - g_behind) / (2 * step), atol=1e-6)


def test_the_jacobian_and_the_linearisation_are_the_derivatives(cranks, rng):
    step = 1e-6
    for pose in random_poses(rng, 4):
        rate = rng.uniform(-0.3, 0.3, 6)
        _, _, J, S = leg_linearisation(pose, rate, cranks)
        np.testing.assert_allclose(J, leg_jacobian(pose, cranks), atol=1e-13)
        for j in range(6):
            e = np.zeros(6)
            e[j] = step
            ahead = leg_motion(pose + e, rate, np.zeros(6), cranks)
            behind = leg_motion(pose - e, rate, np.zeros(6), cranks)
            np.testing.assert_allclose(J[:, j], (ahead[0] - behind[0]) / (2 * step), atol=1e-8)
            np.testing.assert_allclose(S[:, j], (ahead[1] - behind[1]) / (2 * step), atol=1e-7)


def test_speeds_and_accelerations_are_the_angles_time_derivatives(cranks, rng):
    # A smooth motion through the workspace; oracle: central differences in time.
    amplitude = np.array([0.04, 0.04, 0.03, 0.08, 0.08, 0.1])
    frequency = rng.uniform(0.3, 1.5, 6)

    def pose(t):
        return amplitude * np.sin(frequency * t)

    def rate(t):
        return amplitude * frequency * np.cos(frequency * t)

    def accel(t):
        return -amplitude * frequency**2 * np.sin(frequency * t)

    dt = 1e-5
    for t in np.linspace(0.1, 5.0, 7):
        angles, speeds, accelerations = leg_motion(pose(t), rate(t), accel(t), cranks)
        before = actuator_positions(pose(t - dt), cranks)
        after = actuator_positions(pose(t + dt), cranks)
        np.testing.assert_allclose(speeds, (after - before) / (2 * dt), atol=1e-8)
        np.testing.assert_allclose(accelerations, (after - 2 * angles + before) / dt**2, atol=2e-4)


def test_forward_kinematics_inverts_the_arms_angles(cranks, rng):
    for pose in random_poses(rng, 10):
        found = forward_kinematics(actuator_positions(pose, cranks), cranks)
        np.testing.assert_allclose(found, pose, atol=1e-9)


def test_torch_is_numpy(cranks, rng):
    import torch  # the torch twin is what training uses; numpy is the reference

    from mca_drake.learning.legs import actuator_positions as torch_positions

    poses = random_poses(rng, 50)
    got = torch_positions(torch.tensor(poses, dtype=torch.float64), cranks).numpy()
    np.testing.assert_allclose(got, actuator_positions(poses, cranks), rtol=0, atol=1e-13)


def test_a_pose_beyond_the_arms_reach_is_outside_every_range(cranks):
    # 0.5 m of heave: no arm of 0.15 m reaches; the angles are NaN, never a number inside.
    angles = actuator_positions(np.array([0.0, 0.0, 0.5, 0.0, 0.0, 0.0]), cranks)
    assert np.all(np.isnan(angles))


def test_a_crank_hexapod_file_loads_by_layout_or_by_listed_cranks(tmp_path, cranks):
    layout = "\n".join(f"{k}: {v!r}" for k, v in LAYOUT.items())
    path = tmp_path / "seat.yaml"
    path.write_text(f"!Hexapod\nname: seat\n{layout}\n")
    symmetric = read_platform_file(path).geometry()
    assert symmetric == cranks
    c = cranks.cranks
    listed = tmp_path / "listed.yaml"
    listed.write_text(
        "!Hexapod\nname: listed\n"
        f"base_joints: {cranks.base_joints!r}\nplatform_joints: {cranks.platform_joints!r}\n"
        f"neutral_height: 0.55\nmin_angle: -0.8\nmax_angle: 0.8\n"
        f"max_speed: 3.0\nmax_acceleration: 30.0\narm_length: {c.arm_length!r}\n"
        f"rod_length: {c.rod_length!r}\narm_directions: {c.arm_directions!r}\n"
        f"motor_axes: {c.motor_axes!r}\n"
    )
    geometry = read_platform_file(listed).geometry()
    lengths = tmp_path / "lengths.yaml"
    lengths.write_text(listed.read_text() + "min_length: 0.4\nmax_length: 0.7\n")
    with pytest.raises(ValueError, match="give min_angle and max_angle"):
        read_platform_file(lengths).geometry()
    np.testing.assert_allclose(
        actuator_positions(np.array([0.01, 0.0, 0.02, 0.05, 0.0, 0.0]), geometry),
        actuator_positions(np.array([0.01, 0.0, 0.02, 0.05, 0.0, 0.0]), cranks),
        atol=1e-14,
    )


@pytest.mark.parametrize(
    "extra, message",
    [
        ("min_length: 0.1\nmax_length: 0.9\n", "gives stroke, not min/max_length"),
        ("rod_length: 0.6\n", "take none"),
    ],
)
def test_a_bad_crank_file_names_what_is_wrong(tmp_path, extra, message):
    layout = "\n".join(f"{k}: {v!r}" for k, v in LAYOUT.items())
    path = tmp_path / "bad.yaml"
    path.write_text(f"!Hexapod\nname: bad\n{layout}\n{extra}")
    with pytest.raises(ValueError, match=message):
        read_platform_file(path).geometry()


def test_arms_not_perpendicular_to_their_axes_are_refused(cranks):
    bad = LegGeometry(**{**cranks.__dict__, "cranks": None})  # a copy
    bad.cranks = type(cranks.cranks)(
        arm_length=0.15,
        rod_length=cranks.cranks.rod_length,
        arm_directions=cranks.cranks.arm_directions,
        motor_axes=cranks.cranks.arm_directions,  # each axis along its arm
    )
    with pytest.raises(ValueError, match="perpendicular"):
        bad.validate()


def test_the_summary_states_the_arms_range_in_radians(platform):
    actuators = platform.summary()["actuators"]
    assert actuators["kind"] == "rotary" and actuators["unit"] == "rad"
    assert (actuators["min_position"], actuators["max_position"]) == (-0.8, 0.8)


@pytest.mark.parametrize("mca", ["washout", "nmpc-rti"])
def test_cues_far_beyond_the_rig_leave_every_arm_inside_its_limits(platform, mca):
    result = run_closed_loop(
        mca=mca, reference=far_reference(), duration_s=8.0, progress=False, robot=platform
    )
    violations = result.summary["violations"]
    arms = {name: count for name, count in violations.items() if name.startswith("actuator")}
    assert len(arms) == 3 and sum(arms.values()) == 0, violations
    # Oracle: the arms' angles of the run's joint trajectory, straight from the closed form
    q = result.states[:, : platform.num_joints]
    angles = actuator_positions(pose_of(q), platform.actuators)
    assert np.all((angles >= -0.8) & (angles <= 0.8))
    # The coordinates' box is each one's reach alone, a planning range: where braking inside
    # it asks more of the arms than they have, the clamp keeps the arms (platforms.leg_clamp)
    # and a coordinate may pass its single-axis reach, by little.
    span = platform.q_max - platform.q_min
    assert np.max((q - platform.q_max) / span) < 0.05
    assert np.max((platform.q_min - q) / span) < 0.05
    if mca == "washout":  # the NMPC here runs the KR500's weights: nothing tuned it
        assert result.summary["pi"] < result.summary["pi_zero_motion"]


def test_meshcat_draws_each_arm_and_its_rod(platform):
    from mca_drake.systems.meshcat_legs import leg_segments, stroke_used

    q = np.array([0.02, -0.01, 0.03, 0.05, -0.04, 0.06])
    segments = leg_segments(platform, q)
    assert segments.shape == (6, 3, 3)  # pivot, arm's tip, platform joint
    c = platform.actuators.cranks
    np.testing.assert_allclose(
        np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1), c.arm_length, atol=1e-12
    )
    np.testing.assert_allclose(
        np.linalg.norm(segments[:, 2] - segments[:, 1], axis=1), c.rod_length, atol=1e-12
    )
    np.testing.assert_allclose(stroke_used(platform, np.array([-0.8, 0.0, 0.4])), [1, 0, 0.5])
