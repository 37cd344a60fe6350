"""Numpy kinematics and plant output against Drake's MultibodyPlant, finite differences
and closed-form cases."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_joint_states
from drake_oracle import drake_head_pose, drake_plant_output

from mca_drake.platforms import kinematics

G = 9.81


def textbook_dh_head_pose(q: np.ndarray) -> np.ndarray:
    """Standard DH forward kinematics typed from Table I (exact pi/2), times X_6H."""
    pi2 = np.pi / 2
    a = [0.5, 1.3, -0.055, 0.0, 0.0, 0.0]
    d = [1.045, 0.0, 0.0, 1.025, 0.0, 0.29]
    alpha = [-pi2, 0.0, -pi2, pi2, -pi2, 0.0]
    offset = [0.0, -pi2, 0.0, 0.0, 0.0, 0.0]
    X = np.eye(4)
    for i in range(6):
        th = q[i] + offset[i]
        c, s, ca, sa = np.cos(th), np.sin(th), np.cos(alpha[i]), np.sin(alpha[i])
        X = X @ np.array(
            [
                [c, -s * ca, s * sa, a[i] * c],
                [s, c * ca, -c * sa, a[i] * s],
                [0, sa, ca, d[i]],
                [0, 0, 0, 1],
            ]
        )
    X_6H = np.eye(4)
    X_6H[:3, :3] = [[0, 0, 1], [0, -1, 0], [1, 0, 0]]
    X_6H[:3, 3] = [0.9, 0.0, 0.5]
    return X @ X_6H


def test_urdf_matches_dh_at_1000_configurations(robot, drake_plant, rng):
    context = drake_plant.CreateDefaultContext()
    q_all = rng.uniform(robot.q_min, robot.q_max, size=(1000, 6))
    ours = kinematics.head_pose(q_all, robot)
    for q, X_ours in zip(q_all, ours, strict=True):
        X_drake = drake_head_pose(drake_plant, context, q)
        np.testing.assert_allclose(X_drake, textbook_dh_head_pose(q), atol=1e-9, rtol=0)
        np.testing.assert_allclose(X_ours, X_drake, atol=1e-9, rtol=0)


def test_neutral_pose_is_level(robot):
    X_WH = kinematics.head_pose(np.zeros(6), robot)
    np.testing.assert_allclose(X_WH[:3, :3], np.eye(3), atol=1e-12)


def test_plant_output_matches_drake(robot, drake_plant, rng):
    context = drake_plant.CreateDefaultContext()
    q, qd, qdd = random_joint_states(rng, robot, 200)
    ours = kinematics.plant_output(q, qd, qdd, robot)
    for k in range(q.shape[0]):
        expected = drake_plant_output(drake_plant, context, q[k], qd[k], qdd[k])
        np.testing.assert_allclose(ours[k], expected, atol=1e-8, rtol=0)


def test_output_at_rest_in_neutral_pose_is_zero(robot):
    z = np.zeros(6)
    np.testing.assert_allclose(kinematics.plant_output(z, z, z, robot), np.zeros(6), atol=1e-12)


def test_output_at_rest_is_tilted_gravity(robot, rng):
    """At rest the accelerometer reads -g in H: f = R^T (0, 0, 9.81); a_z = 0; w = 0."""
    q = rng.uniform(robot.q_min, robot.q_max, size=(20, 6))
    z = np.zeros_like(q)
    y = kinematics.plant_output(q, z, z, robot)
    R = kinematics.head_pose(q, robot)[:, :3, :3]
    f = np.einsum("nji,j->ni", R, [0.0, 0.0, G])
    np.testing.assert_allclose(y[:, :3], 0.0, atol=1e-12)
    np.testing.assert_allclose(y[:, 3:5], f[:, :2], atol=1e-12)
    np.testing.assert_allclose(y[:, 5], 0.0, atol=1e-12)


def test_joint_1_spin_is_yaw_rate_and_centripetal(robot):
    """Closed form: turning the base at w about the vertical at q = 0 gives yaw rate w and
    a centripetal acceleration w^2 * radius towards the axis (-x in H)."""
    w = 0.7
    qd = np.array([w, 0, 0, 0, 0, 0.0])
    z = np.zeros(6)
    y = kinematics.plant_output(z, qd, z, robot)
    radius = kinematics.head_pose(z, robot)[0, 3]  # head x in W at q = 0 (2.315 m)
    np.testing.assert_allclose(y, [0, 0, w, -(w**2) * radius, 0, 0], atol=1e-12)


def test_jacobians_match_central_differences(robot, rng):
    q, qd, qdd = random_joint_states(rng, robot, 30)
    jac = kinematics.plant_output_jacobians(q, qd, qdd, robot)
    np.testing.assert_allclose(jac.y, kinematics.plant_output(q, qd, qdd, robot), atol=1e-14)
    eps = 1e-6
    for name, arg in (("q", 0), ("qd", 1), ("qdd", 2)):
        numeric = np.zeros((q.shape[0], 6, 6))
        for j in range(6):
            plus, minus = [q.copy(), qd.copy(), qdd.copy()], [q.copy(), qd.copy(), qdd.copy()]
            plus[arg][:, j] += eps
            minus[arg][:, j] -= eps
            numeric[:, :, j] = (
                kinematics.plant_output(*plus, robot) - kinematics.plant_output(*minus, robot)
            ) / (2 * eps)
        np.testing.assert_allclose(
            getattr(jac, f"dy_d{name}"), numeric, atol=2e-8, rtol=1e-6, err_msg=name
        )


def test_velocity_hessians_are_the_quadratic_forms_of_the_output(robot, rng):
    """y is exactly quadratic in qd, so the polarisation of four outputs at +-e_i +- e_j (unit
    steps, no truncation error) is d^2 y / dqd_i dqd_j; it does not depend on qd or qdd."""
    q, qd, qdd = random_joint_states(rng, robot, 8)
    H = kinematics.output_velocity_hessians(q, robot)
    assert H.shape == (8, 6, 6, 6)
    eye = np.eye(6)
    for i in range(6):
        for j in range(6):

            def y(a, b, i=i, j=j):
                return kinematics.plant_output(q, qd + a * eye[i] + b * eye[j], qdd, robot)

            polar = (y(1, 1) - y(1, -1) - y(-1, 1) + y(-1, -1)) / 4
            np.testing.assert_allclose(H[:, :, i, j], polar, atol=1e-9, err_msg=f"{i},{j}")
    np.testing.assert_array_equal(H[:, :3], 0.0)  # the rates are linear in qd


def test_base_spin_curvature_is_twice_the_centripetal_radius(robot):
    """Closed form: f_x = -w^2 radius for a base spin at q = 0, so d^2 f_x / dqd_1^2 = -2 radius."""
    H = kinematics.output_velocity_hessians(np.zeros(6), robot)
    radius = kinematics.head_pose(np.zeros(6), robot)[0, 3]
    assert H[3, 0, 0] == pytest.approx(-2 * radius, abs=1e-12)
    assert H[4, 0, 0] == pytest.approx(0.0, abs=1e-12)


def test_head_pose_derivatives_are_time_derivatives(robot, rng):
    """dF and ddF equal central differences of F along q(t) = q0 + qd0 t + qdd0 t^2 / 2."""
    q0, qd0, qdd0 = (x[0] for x in random_joint_states(rng, robot, 1))
    h = 1e-4

    def F_at(t):
        return kinematics.head_pose(q0 + qd0 * t + 0.5 * qdd0 * t * t, robot)

    F, dF, ddF = kinematics.head_pose_derivatives(q0, qd0, qdd0, robot)
    np.testing.assert_allclose(F, F_at(0.0), atol=1e-14)
    np.testing.assert_allclose(dF, (F_at(h) - F_at(-h)) / (2 * h), atol=1e-7)
    np.testing.assert_allclose(ddF, (F_at(h) - 2 * F_at(0.0) + F_at(-h)) / h**2, atol=1e-5)


def test_batched_shapes_are_kept(robot, rng):
    q, qd, qdd = (x.reshape(2, 3, 6) for x in random_joint_states(rng, robot, 6))
    assert kinematics.plant_output(q, qd, qdd, robot).shape == (2, 3, 6)
    assert kinematics.head_pose(q, robot).shape == (2, 3, 4, 4)
    jac = kinematics.plant_output_jacobians(q, qd, qdd, robot)
    assert jac.dy_dq.shape == jac.dy_dqd.shape == jac.dy_dqdd.shape == (2, 3, 6, 6)
    flat = kinematics.plant_output(q.reshape(6, 6), qd.reshape(6, 6), qdd.reshape(6, 6), robot)
    np.testing.assert_allclose(flat.reshape(2, 3, 6), kinematics.plant_output(q, qd, qdd, robot))


@pytest.mark.parametrize(
    ("q", "qd", "qdd", "match"),
    [
        (np.zeros(5), np.zeros(6), np.zeros(6), r"q must have shape \(\.\.\., 6\)"),
        (np.zeros(6), np.zeros((2, 6)), np.zeros(6), "shapes must match"),
        (np.zeros(6), np.full(6, np.nan), np.zeros(6), "qd has non-finite"),
        (np.zeros(6), np.zeros(6), [0, 0, np.inf, 0, 0, 0], "qdd has non-finite"),
        ("abc", np.zeros(6), np.zeros(6), "q must be numeric"),
    ],
)
def test_bad_input_is_reported(robot, q, qd, qdd, match):
    with pytest.raises(ValueError, match=match):
        kinematics.plant_output(q, qd, qdd, robot)
    with pytest.raises(ValueError, match=match):
        kinematics.plant_output_jacobians(q, qd, qdd, robot)


def test_output_from_motion_equals_plant_output(robot, rng):
    q, qd, qdd = random_joint_states(rng, robot, 50)
    motion = kinematics.head_motion(q, qd, qdd, robot)
    np.testing.assert_allclose(
        kinematics.output_from_motion(motion),
        kinematics.plant_output(q, qd, qdd, robot),
        atol=1e-12,
    )


def test_turning_joint_1_changes_no_cue(robot, drake_plant, rng):
    """Joint 1's axis is vertical: turning it turns the whole robot about gravity, and the
    head-frame outputs (Drake's) stay as they were; only limits and washout see joint 1."""
    context = drake_plant.CreateDefaultContext()
    for _ in range(50):
        q = rng.uniform(robot.q_min, robot.q_max) * 0.9
        qd, qdd = rng.uniform(-1, 1, 6), rng.uniform(-1, 1, 6)
        turned = q.copy()
        turned[0] = rng.uniform(robot.q_min[0], robot.q_max[0])
        np.testing.assert_allclose(
            drake_plant_output(drake_plant, context, turned, qd, qdd),
            drake_plant_output(drake_plant, context, q, qd, qdd),
            atol=1e-9,
        )
