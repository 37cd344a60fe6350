"""Hexapod kinematics against closed forms on the symmetric geometry, forward kinematics
inverting the inverse to 1e-9, the Jacobian against finite differences, torch = numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mca_drake.platforms.legs import (
    LegGeometry,
    forward_kinematics,
    leg_jacobian,
    leg_lengths,
    leg_motion,
)

# A symmetric 6-6 hexapod of simulator size (base 1.2 m, platform 0.8 m radius).
RB, RP, HB, HP, HEIGHT = 1.2, 0.8, math.radians(10.0), math.radians(12.0), 1.0


@pytest.fixture(scope="module")
def hexapod() -> LegGeometry:
    geometry = LegGeometry.symmetric(RB, RP, HB, HP, HEIGHT, 0.8, 0.6, 6.0)
    geometry.validate()
    return geometry


def base_and_platform_angles():
    """Each leg's base and platform joint angles on their circles (the layout's definition)."""
    angles = []
    for pair in range(3):
        centre = math.radians(120.0 * pair)
        for side in (-1, 1):
            angles.append((centre + side * HB, centre + side * (math.radians(60.0) - HP)))
    return angles


def test_heave_and_yaw_lengths_are_the_closed_form(hexapod):
    """Heave z and yaw psi about the vertical axis: by the law of cosines on the circles,
    l^2 = RB^2 + RP^2 - 2 RB RP cos(theta_p + psi - theta_b) + (HEIGHT + z)^2."""
    for z, psi in [(0.0, 0.0), (0.15, 0.0), (-0.2, 0.0), (0.0, 0.3), (0.1, -0.25)]:
        expected = [
            math.sqrt(RB**2 + RP**2 - 2 * RB * RP * math.cos(tp + psi - tb) + (HEIGHT + z) ** 2)
            for tb, tp in base_and_platform_angles()
        ]
        pose = [0.0, 0.0, z, 0.0, 0.0, psi]
        np.testing.assert_allclose(leg_lengths(pose, hexapod), expected, rtol=0, atol=1e-14)


def test_leg_lengths_are_drakes_rigid_transform_of_the_joints(hexapod, rng):
    """Drake's own pose arithmetic: the platform frame at RigidTransform(RollPitchYaw(roll,
    pitch, yaw), t) in the base frame, each leg from b_i to X_BP p_i."""
    from pydrake.math import RigidTransform, RollPitchYaw

    for pose in random_poses(rng, 25):
        X_BP = RigidTransform(
            RollPitchYaw(*pose[3:]), pose[:3] + np.array([0.0, 0.0, hexapod.neutral_height])
        )
        expected = [
            np.linalg.norm(X_BP @ np.asarray(p) - np.asarray(b))
            for p, b in zip(hexapod.platform_joints, hexapod.base_joints, strict=True)
        ]
        np.testing.assert_allclose(leg_lengths(pose, hexapod), expected, rtol=0, atol=1e-14)


def test_the_neutral_pose_has_six_equal_legs_inside_the_stroke(hexapod):
    lengths = leg_lengths(np.zeros(6), hexapod)
    assert np.ptp(lengths) < 1e-14
    assert hexapod.min_position < lengths[0] < hexapod.max_position


def random_poses(rng, n):
    scale = np.array([0.15, 0.15, 0.12, 0.2, 0.2, 0.3])
    return rng.uniform(-1, 1, size=(n, 6)) * scale


def test_forward_kinematics_inverts_the_inverse(hexapod, rng):
    poses = random_poses(rng, 200)
    lengths = leg_lengths(poses, hexapod)  # batched
    for pose, legs in zip(poses, lengths, strict=True):
        found = forward_kinematics(legs, hexapod)
        np.testing.assert_allclose(found, pose, atol=1e-9)


def test_the_jacobian_is_the_derivative(hexapod, rng):
    for pose in random_poses(rng, 20):
        J = leg_jacobian(pose, hexapod)
        step = 1e-6
        numeric = np.column_stack(
            [
                (leg_lengths(pose + step * e, hexapod) - leg_lengths(pose - step * e, hexapod))
                / (2 * step)
                for e in np.eye(6)
            ]
        )
        np.testing.assert_allclose(J, numeric, atol=1e-8)


def test_leg_speeds_and_accelerations_are_the_time_derivatives(hexapod, rng):
    """Along a smooth pose trajectory (sines of random amplitude, frequency and phase per
    coordinate), the legs' speeds and accelerations against central differences in time
    of their lengths."""
    amplitude = rng.uniform(0.02, 0.12, 6)
    omega = rng.uniform(0.5, 3.0, 6)
    phase = rng.uniform(0, 2 * np.pi, 6)

    def pose(t):
        return amplitude * np.sin(omega * t + phase)

    def rate(t):
        return amplitude * omega * np.cos(omega * t + phase)

    def accel(t):
        return -amplitude * omega**2 * np.sin(omega * t + phase)

    dt = 1e-4
    for t in np.linspace(0.0, 3.0, 13):
        lengths, speeds, accelerations = leg_motion(pose(t), rate(t), accel(t), hexapod)
        before, after = leg_lengths(pose(t - dt), hexapod), leg_lengths(pose(t + dt), hexapod)
        np.testing.assert_allclose(lengths, leg_lengths(pose(t), hexapod), atol=1e-15)
        np.testing.assert_allclose(speeds, (after - before) / (2 * dt), atol=1e-8)
        np.testing.assert_allclose(accelerations, (after - 2 * lengths + before) / dt**2, atol=2e-5)


def test_torch_is_numpy(hexapod, rng):
    torch = pytest.importorskip("torch")
    from mca_drake.learning.legs import leg_lengths as torch_leg_lengths

    poses = random_poses(rng, 50)
    got = torch_leg_lengths(torch.tensor(poses, dtype=torch.float64), hexapod).numpy()
    np.testing.assert_allclose(got, leg_lengths(poses, hexapod), rtol=0, atol=1e-14)


def test_bad_input_says_what_is_wrong(hexapod):
    with pytest.raises(ValueError, match="six finite numbers"):
        leg_lengths([0.0, 0.0, math.nan, 0.0, 0.0, 0.0], hexapod)
    with pytest.raises(ValueError, match="six finite actuator positions"):
        forward_kinematics([1.0] * 5, hexapod)
    with pytest.raises(ValueError, match="did not converge"):
        forward_kinematics([10.0, 0.1, 10.0, 0.1, 10.0, 0.1], hexapod, max_iterations=20)
    bad = LegGeometry.symmetric(RB, RP, HB, HP, HEIGHT, 0.8, 0.6, 6.0)
    bad.min_position = bad.max_position + 0.1
    with pytest.raises(ValueError, match="max_position must exceed"):
        bad.validate()
