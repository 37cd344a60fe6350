"""Viability clamp: random and adversarial commands never drive the plant out of limits."""

from __future__ import annotations

import numpy as np

from mca_drake.safety import is_stoppable, viable_acceleration_bounds

H = 0.01


def step(q, qd, u, h=H):
    return q + h * qd + 0.5 * h * h * u, qd + h * u


def run_clamped(robot, commands, q, qd):
    """Applies commands (T, n, 6) through the clamp; returns the worst normalised excursion."""
    worst = 0.0
    for u in commands:
        lo, hi, viable = viable_acceleration_bounds(
            q, qd, robot.q_min, robot.q_max, robot.qd_max, robot.qdd_max, H
        )
        assert viable.all()
        assert np.all(lo <= hi)
        q, qd = step(q, qd, np.clip(u, lo, hi))
        worst = max(
            worst,
            np.max(np.maximum(q - robot.q_max, robot.q_min - q)),
            np.max(np.abs(qd) - robot.qd_max),
        )
        assert is_stoppable(q, qd, robot.q_min, robot.q_max, robot.qdd_max).all()
    return worst


def test_random_commands_stay_in_limits(robot, rng):
    n = 64
    q = rng.uniform(0.5 * robot.q_min, 0.5 * robot.q_max, size=(n, 6))
    qd = np.zeros((n, 6))
    commands = rng.uniform(-3, 3, size=(2000, n, 6)) * robot.qdd_max  # beyond the limits too
    assert run_clamped(robot, commands, q, qd) <= 1e-9


def test_adversarial_full_throttle_into_the_limits(robot):
    """Always accelerate towards the nearest limit as hard as possible (bang-bang)."""
    q = np.zeros((2, 6))
    qd = np.zeros((2, 6))
    towards_upper = np.tile(np.array([[10.0] * 6, [-10.0] * 6])[None], (3000, 1, 1))
    assert run_clamped(robot, towards_upper, q, qd) <= 1e-9


def test_adversarial_chattering_at_the_limit(robot, rng):
    """Alternate full accelerations near the limit, the worst case for a discrete clamp."""
    q = np.tile(robot.q_max - 0.05, (4, 1))
    qd = np.zeros((4, 6))
    commands = np.where(rng.uniform(size=(3000, 4, 6)) < 0.7, 100.0, -100.0)
    assert run_clamped(robot, commands, q, qd) <= 1e-9


def test_clamp_leaves_harmless_commands_alone(robot):
    q, qd = np.zeros(6), np.zeros(6)
    lo, hi, _ = viable_acceleration_bounds(
        q, qd, robot.q_min, robot.q_max, robot.qd_max, robot.qdd_max, H
    )
    np.testing.assert_allclose(lo, -robot.qdd_max)
    np.testing.assert_allclose(hi, robot.qdd_max)


def test_bound_is_tight_against_the_stoppability_boundary(robot):
    """At the computed hi, the next state sits exactly on the stopping parabola."""
    qd = 0.6 * robot.qd_max
    q = robot.q_max - qd**2 / (2 * robot.qdd_max) - 0.5 * H * qd  # coasting would overshoot
    _, hi, _ = viable_acceleration_bounds(
        q, qd, robot.q_min, robot.q_max, robot.qd_max, robot.qdd_max, H
    )
    q1, qd1 = step(q, qd, hi)
    reach = q1 + np.maximum(qd1, 0) ** 2 / (2 * robot.qdd_max)
    binding = hi < robot.qdd_max - 1e-9
    assert binding.any()
    np.testing.assert_allclose(reach[binding], robot.q_max[binding], atol=1e-9)


def test_non_viable_state_gets_full_braking(robot):
    q = robot.q_max - 0.01
    qd = robot.qd_max * 0.9  # cannot stop in 0.01 rad
    lo, hi, viable = viable_acceleration_bounds(
        q, qd, robot.q_min, robot.q_max, robot.qd_max, robot.qdd_max, H
    )
    assert not viable.any()
    np.testing.assert_allclose(lo, -robot.qdd_max)
    np.testing.assert_allclose(hi, -robot.qdd_max)


def test_clamp_call_equals_clipping_into_the_bounds(robot, rng):
    from mca_drake.safety import ViabilityClamp

    clamp = ViabilityClamp.for_robot(robot, 0.01)
    # Everywhere (mostly near or past a limit), and near neutral, where the clamp's
    # far-from-limits shortcut answers; and on the shortcut's edge: slow joints just inside
    # their stopping distance of a limit.
    middle = 0.5 * (robot.q_min + robot.q_max)
    half = 0.5 * (robot.q_max - robot.q_min)
    for k in range(4000):
        if k < 2000:
            q = rng.uniform(1.1 * robot.q_min, 1.1 * robot.q_max)
            qd = rng.uniform(-1.2 * robot.qd_max, 1.2 * robot.qd_max)
        elif k < 3000:
            q = middle + rng.uniform(-0.8, 0.8, 6) * half
            qd = rng.uniform(-0.5, 0.5, 6) * robot.qd_max
        else:
            qd = rng.uniform(-0.2, 0.2, 6) * robot.qd_max
            reach = qd * np.abs(qd) / (2 * robot.qdd_max) + 0.01 * qd
            side = np.where(qd > 0, robot.q_max, robot.q_min)
            q = side - reach - rng.uniform(-2e-3, 2e-3, 6) * np.sign(qd)
        u = rng.uniform(-3 * robot.qdd_max, 3 * robot.qdd_max)
        lo, hi, viable = viable_acceleration_bounds(
            q, qd, robot.q_min, robot.q_max, robot.qd_max, robot.qdd_max, 0.01
        )
        safe, intervened = clamp(np.concatenate([q, qd]), u)
        expected = np.clip(u, lo, hi)
        np.testing.assert_allclose(safe, expected, rtol=0, atol=1e-9)
        assert intervened == bool(np.any(np.abs(expected - u) > 1e-9) or not viable.all())


def test_torch_bounds_equal_numpy(robot, rng):
    import torch

    from mca_drake.learning.torch_plant import viable_acceleration_bounds_torch

    q = rng.uniform(1.1 * robot.q_min, 1.1 * robot.q_max, size=(500, 6))
    qd = rng.uniform(-1.2 * robot.qd_max, 1.2 * robot.qd_max, size=(500, 6))
    lo, hi, _ = viable_acceleration_bounds(
        q, qd, robot.q_min, robot.q_max, robot.qd_max, robot.qdd_max, 0.01
    )
    limits = [torch.tensor(getattr(robot, n)) for n in ("q_min", "q_max", "qd_max", "qdd_max")]
    lo_t, hi_t = viable_acceleration_bounds_torch(
        torch.tensor(np.concatenate([q, qd], 1)), *limits, 0.01
    )
    np.testing.assert_allclose(lo_t.numpy(), lo, rtol=0, atol=1e-9)
    np.testing.assert_allclose(hi_t.numpy(), hi, rtol=0, atol=1e-9)
