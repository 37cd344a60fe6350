"""Classical washout: filters against continuous-time oracles, and tilt coordination in the
closed loop with Drake's differential IK."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from mca_drake.conventions import GRAVITY
from mca_drake.cueing.washout import WashoutConfig, WashoutFilters
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.kinematics import head_pose
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")

H = 0.01


def _run_filters(reference: np.ndarray, config: WashoutConfig | None = None):
    filters = WashoutFilters(config or WashoutConfig(), H)
    state, out = np.zeros(filters.state_size), []
    for r in reference:
        state, target = filters.step(state, r)
        out.append(target)
    return {k: np.array([o[k] for o in out]) for k in out[0]}


def test_translation_channel_matches_the_continuous_filter(rng):
    """The discretised displacement equals the continuous third-order washout's response to
    the same zero-order-hold input at the sample instants (scipy.signal.lsim oracle)."""
    cfg = WashoutConfig()
    a = np.repeat(rng.normal(size=60), 10)  # piecewise-constant heave acceleration
    reference = np.zeros((a.size, 6))
    reference[:, 5] = a
    out = _run_filters(reference, cfg)
    w, z, wb = cfg.translation_frequency, cfg.translation_damping, cfg.translation_washout_frequency
    den = np.polymul([1, 2 * z * w, w * w], [1, wb])
    t = H * np.arange(a.size)
    # k_t s^3 / den on acceleration, integrated twice: k_t s / den to the displacement
    _, y, _ = signal.lsim(([cfg.translation_gain, 0.0], den), a, t, interp=False)
    np.testing.assert_allclose(out["position"][:, 2], y, rtol=0, atol=1e-9)


def test_washout_returns_to_neutral_and_tilt_holds_a_sustained_force():
    """The final-value theorem on every channel; 30 s is long enough for the classic
    cut-offs (the tuned rotation high-pass is slower)."""
    reference = np.zeros((3000, 6))
    reference[:, 3] = 1.0  # sustained surge specific force, m/s^2
    reference[:, 0] = 0.2  # sustained roll rate, rad/s
    out = _run_filters(reference, WashoutConfig.classic())
    # translation and rotation wash out (final value theorem: zero)
    assert np.abs(out["position"][-1]).max() < 1e-3
    assert abs(out["rpy"][-1, 0]) < 1e-3
    # the tilt settles at the angle whose gravity component renders the force
    assert out["rpy"][-1, 1] == pytest.approx(-np.arcsin(1.0 / GRAVITY), abs=1e-6)


@pytest.fixture(scope="module")
def surge_run():
    steps, on = 2000, 800
    y = np.zeros((steps, 6))
    y[:on, 3] = 1.0  # 8 s of sustained surge
    result = run_closed_loop(
        mca="washout", reference=Reference(y, H, "surge"), progress=False, robot=KR500
    )
    return result, on


def test_sustained_surge_is_rendered_by_pitch_within_the_rate_limit(surge_run, robot):
    result, on = surge_run
    limit = WashoutConfig().tilt_rate_limit
    pitch_rate = result.outputs[:, 1]
    # the tilt builds up at the rate limit (after the onset transient of the translation)
    build = slice(30, 190)
    assert np.abs(pitch_rate[build]).max() <= 1.05 * limit
    assert np.mean(np.abs(pitch_rate[build])) == pytest.approx(limit, rel=0.05)
    # once tilted, the force is rendered by gravity: pitch angle and specific force
    R = head_pose(result.states[:, :6], robot)[:, :3, :3]
    pitch = np.arcsin(-R[:, 2, 0])
    hold = slice(400, on)
    np.testing.assert_allclose(pitch[hold], -np.arcsin(1.0 / GRAVITY), atol=np.deg2rad(0.3))
    np.testing.assert_allclose(result.outputs[hold, 3], 1.0, atol=0.05)
    assert result.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert result.summary["solver_failures"] == 0


def test_robot_returns_to_neutral(surge_run, robot):
    """Back at rest at its home pose (where it started), with the head level."""
    result, _ = surge_run
    home = robot.washout_home
    np.testing.assert_allclose(result.states[0, :6], home, atol=1e-12)
    final = result.states[-1]
    assert np.abs(final[:6] - home).max() < 2e-3 and np.abs(final[6:]).max() < 1e-3
    R = head_pose(final[:6], robot)[:3, :3]
    np.testing.assert_allclose(R, np.eye(3), atol=2e-3)


def test_bad_washout_settings_are_rejected():
    with pytest.raises(ValueError, match="tilt_rate_limit"):
        WashoutFilters(WashoutConfig(tilt_rate_limit=0.0), H)


def test_a_joint_inside_the_ik_reserve_band_does_not_stall_the_ik(robot):
    """The IK keeps 2 % of each range in reserve; the clipped, clamped command can carry a
    joint into that band. From there the IK must still solve (no failure, no frozen robot)
    and may only move the joint back towards the middle. The state is one met on light
    flight 1006: joint 3 is 1.6e-4 rad inside the band and still moving outwards, where
    fixed IK position bounds make the QP infeasible (step 21021 of that flight's 30000)."""
    from pydrake.systems.analysis import Simulator

    from mca_drake.systems.washout import ClassicalWashout

    washout = ClassicalWashout(robot=robot)
    q = np.array([0.1858, -0.0323, 0.857, 0.9902, -0.7994, 0.0278])
    qd = np.array([0.1378, 0.0707, 0.2048, 0.1479, -0.3253, -0.067])
    band_edge = robot.q_max[2] - 0.02 * (robot.q_max[2] - robot.q_min[2])
    assert q[2] > band_edge and qd[2] > 0
    for velocity in (qd, np.zeros(6)):
        context = washout.CreateDefaultContext()
        washout.get_input_port(0).FixValue(context, np.zeros(6))
        washout.get_input_port(1).FixValue(context, np.concatenate([q, velocity]))
        Simulator(washout, context).AdvanceTo(0.5 * H)  # the update at t = 0
        u = washout.get_output_port(0).Eval(context)
        assert washout.statistics(context)["solver_failures"] == 0
        assert u[2] < 0.0  # joint 3 is driven back from its upper band
        assert np.all(np.abs(u) <= robot.qdd_max + 1e-12)
