"""The legs' limits in the NMPC: their linearisation against finite differences of the legs'
exact motion, and plans that keep a legged platform's legs within their stroke and speed
where the coordinates' box alone would run them past it."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.cueing.nmpc import MotionCueingOcp
from mca_drake.cueing.nmpc_config import NmpcConfig
from mca_drake.cueing.nmpc_legs import FIRST_NODE, LegRows
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.legs import leg_linearisation, leg_motion

# A sustained push in every channel at once (specific forces m/s^2, angular rates rad/s):
# each coordinate alone stays inside its box, together they reach past the legs.
FAR_REFERENCE = np.array([4.0, 3.0, 9.81 + 2.0, 0.3, 0.3, 0.3])


@pytest.mark.parametrize("name", ["hexapod", "rig-3dof"])
def test_leg_linearisation_is_the_derivative_of_the_legs_motion(name):
    # Oracle: central differences of `leg_motion`'s exact lengths and speeds.
    platform = load_platform(name)
    rng = np.random.default_rng(3)
    k = platform.num_joints
    q = rng.uniform(0.5 * platform.q_min, 0.5 * platform.q_max, size=(4, k))
    qd = rng.uniform(-0.5, 0.5, size=(4, k)) * platform.qd_max
    lengths, speeds, J, S = platform.actuator_linearisation(q, qd)
    zero = np.zeros_like(q)
    exact = platform.actuator_motion(q, qd, zero)
    np.testing.assert_allclose(lengths, exact[0], atol=1e-14)
    np.testing.assert_allclose(speeds, exact[1], atol=1e-14)
    step = 1e-6
    for j in range(k):
        e = np.zeros(k)
        e[j] = step
        up = platform.actuator_motion(q + e, qd, zero)
        down = platform.actuator_motion(q - e, qd, zero)
        np.testing.assert_allclose(J[..., j], (up[0] - down[0]) / (2 * step), atol=1e-8)
        np.testing.assert_allclose(S[..., j], (up[1] - down[1]) / (2 * step), atol=1e-8)
        up = platform.actuator_motion(q, qd + e, zero)
        down = platform.actuator_motion(q, qd - e, zero)
        np.testing.assert_allclose(J[..., j], (up[1] - down[1]) / (2 * step), atol=1e-8)


def test_one_pose_linearises_as_the_batch_does():
    geometry = load_platform("hexapod").actuators
    rng = np.random.default_rng(4)
    pose, rate = rng.uniform(-0.2, 0.2, (3, 6)), rng.uniform(-0.4, 0.4, (3, 6))
    batch = leg_linearisation(pose, rate, geometry)
    for i in range(3):
        single_pose = leg_linearisation(pose[i], rate[i], geometry)
        for single, batched in zip(single_pose, batch, strict=True):
            np.testing.assert_allclose(single, batched[i], atol=1e-14)
    # and the lengths and speeds are the legs' own
    lengths, speeds, _ = leg_motion(pose, rate, np.zeros_like(pose), geometry)
    np.testing.assert_allclose(batch[0], lengths, atol=1e-14)
    np.testing.assert_allclose(batch[1], speeds, atol=1e-14)


def _closed_loop_plans(platform, config: NmpcConfig, steps: int):
    """Solves `steps` control periods from rest towards FAR_REFERENCE, each step's first
    command applied exactly; yields (ocp, x0, result) per step."""
    ocp = MotionCueingOcp(config, platform)
    refs = np.tile(FAR_REFERENCE, (ocp.N, 1))
    n, h = platform.num_joints, config.time_step
    x0, U, active = np.zeros(2 * n), None, None
    for _ in range(steps):
        result = ocp.solve(x0, refs, U_guess=U, active_guess=active)
        yield ocp, x0, result
        u = result.U[0]
        x0 = np.r_[x0[:n] + h * x0[n:] + 0.5 * h * h * u, x0[n:] + h * u]
        U, active = ocp.shift(result.U), result.active


def _leg_excess(platform, ocp, x0, U, rows: LegRows) -> float:
    q, qd = ocp.states(x0, U)
    return rows.violation(q, qd)


@pytest.mark.parametrize("name", ["hexapod", "rig-3dof"])
def test_converged_plans_keep_the_legs_within_their_stroke_and_speed(name):
    platform = load_platform(name)
    config = NmpcConfig(mode="converged")
    boxed = NmpcConfig(mode="converged", leg_constraints=False)
    # the same rows measure both: the legs' planned stroke and speed at nodes 2..N
    rows = None
    worst_boxed = 0.0
    for ocp, x0, result in _closed_loop_plans(platform, boxed, 6):
        rows = rows or LegRows(platform, ocp._Gq, ocp._Gqd, boxed.limit_margin, 2)
        worst_boxed = max(worst_boxed, _leg_excess(platform, ocp, x0, result.U, rows))
    # without the legs' rows the plan runs a leg centimetres past its stroke or speed
    assert worst_boxed > 0.01
    for step, (ocp, x0, result) in enumerate(_closed_loop_plans(platform, config, 6)):
        # (the first solve starts cold, from a plan of zeros far from this reference's
        # optimum, and may use all its iterations; the warm-started ones end at KKT points)
        assert result.success and (step == 0 or result.stop == "kkt")
        q, qd = ocp.states(x0, result.U)
        lengths, speeds, _, _ = platform.actuator_linearisation(q, qd)
        low, high = ocp._legs.length_range
        assert np.all(lengths[FIRST_NODE:] >= low - 1e-5)
        assert np.all(lengths[FIRST_NODE:] <= high + 1e-5)
        assert np.all(np.abs(speeds[FIRST_NODE:]) <= ocp._legs.max_speed + 1e-5)
        if step > 0:
            assert ocp.is_feasible(x0, result.U, tol=1e-7)


def test_rti_plans_stay_near_the_legs_limits_and_serial_robots_have_no_leg_rows():
    platform = load_platform("hexapod")
    config = NmpcConfig(mode="rti")
    worst = 0.0
    for ocp, x0, result in _closed_loop_plans(platform, config, 20):
        assert result.success
        q, qd = ocp.states(x0, result.U)
        lengths, _, _, _ = platform.actuator_linearisation(q, qd)
        low, high = ocp._legs.length_range
        # the next few nodes (what the clamp meets soonest) hold to the linearisation's
        # remainder; the far end of a one-iteration plan may miss by centimetres
        near = lengths[FIRST_NODE : FIRST_NODE + 4]
        worst = max(worst, float(np.max(np.maximum(low - near, near - high))))
    assert worst < 1e-3
    kr500 = MotionCueingOcp(NmpcConfig(), load_platform("kr500"))
    assert kr500._legs is None and kr500._leg_rows.stop == kr500._leg_rows.start


def test_dpc_leg_limit_term_is_the_legs_excess_and_its_gradient_pulls_back():
    # Oracle: the numpy legs' lengths and the definition of the excess, and a finite
    # difference of the term.
    import torch

    from mca_drake.learning.legs import LegLimits
    from mca_drake.platforms.leg_clamp import POSITION_RESERVE, RATE_RESERVE

    platform = load_platform("rig-3dof")
    limits = LegLimits(platform, 0.01)
    rng = np.random.default_rng(5)
    k = platform.num_joints
    q = rng.uniform(1.3 * platform.q_min, 1.3 * platform.q_max, size=(2, 5, k))
    X = np.concatenate([q, np.zeros_like(q)], axis=-1)
    lengths = platform.actuator_positions(q)
    g = platform.actuators
    low, high = g.min_position + POSITION_RESERVE, g.max_position - POSITION_RESERVE
    stroke = np.maximum(lengths[:, 1:] - high, 0) + np.maximum(low - lengths[:, 1:], 0)
    speed = np.abs(np.diff(lengths, axis=1)) / 0.01 - g.max_speed * (1 - RATE_RESERVE)
    expected = (stroke**2 + np.maximum(speed, 0) ** 2).sum(-1)
    X_torch = torch.tensor(X, dtype=torch.float64, requires_grad=True)
    excess = limits.excess(X_torch)
    np.testing.assert_allclose(excess.detach().numpy(), expected, rtol=1e-10, atol=1e-12)
    assert expected.max() > 0  # the draw reaches past the legs
    excess.sum().backward()
    grad = X_torch.grad.numpy()
    step, (b, t, j) = 1e-7, (0, 3, 0)
    bumped = X.copy()
    bumped[b, t, j] += step
    ahead = limits.excess(torch.tensor(bumped, dtype=torch.float64)).sum().item()
    behind_x = X.copy()
    behind_x[b, t, j] -= step
    behind = limits.excess(torch.tensor(behind_x, dtype=torch.float64)).sum().item()
    assert grad[b, t, j] == pytest.approx((ahead - behind) / (2 * step), rel=1e-5, abs=1e-6)
