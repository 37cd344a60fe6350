"""MotionCueingPlant: FixValue/CalcOutput against the kinematics oracle (Drake), and a
Simulator run against the closed-form double integrator."""

from __future__ import annotations

import numpy as np
import pytest
from drake_oracle import drake_plant_output
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from mca_drake.systems import MotionCueingPlant


def test_ports(robot):
    plant = MotionCueingPlant(robot)
    assert plant.GetInputPort("joint_acceleration").size() == 6
    assert plant.GetOutputPort("state").size() == 12
    assert plant.GetOutputPort("inertial_output").size() == 6
    assert plant.time_step == 0.01
    # y depends on qdd (direct feedthrough); the state output does not.
    assert plant.HasDirectFeedthrough(0, plant.GetOutputPort("inertial_output").get_index())
    assert not plant.HasDirectFeedthrough(0, plant.GetOutputPort("state").get_index())


def test_outputs_match_drake(robot, drake_plant, rng):
    plant = MotionCueingPlant(robot)
    context = plant.CreateDefaultContext()
    drake_context = drake_plant.CreateDefaultContext()
    for _ in range(10):
        q = rng.uniform(robot.q_min, robot.q_max)
        qd = rng.uniform(-robot.qd_max, robot.qd_max)
        qdd = rng.uniform(-robot.qdd_max, robot.qdd_max)
        plant.SetJointState(context, q, qd)
        plant.GetInputPort("joint_acceleration").FixValue(context, qdd)
        np.testing.assert_array_equal(plant.GetOutputPort("state").Eval(context), np.r_[q, qd])
        np.testing.assert_allclose(
            plant.GetOutputPort("inertial_output").Eval(context),
            drake_plant_output(drake_plant, drake_context, q, qd, qdd),
            atol=1e-8,
        )
        X_WH = plant.GetOutputPort("head_pose").Eval(context)
        assert isinstance(X_WH, RigidTransform)
        drake_plant.SetPositions(drake_context, q)
        expected = drake_plant.GetFrameByName("head").CalcPoseInWorld(drake_context)
        np.testing.assert_allclose(X_WH.GetAsMatrix4(), expected.GetAsMatrix4(), atol=1e-9)


def test_default_and_custom_initial_state(robot):
    default = MotionCueingPlant(robot).CreateDefaultContext()
    np.testing.assert_array_equal(default.get_discrete_state_vector().value(), np.zeros(12))
    x0 = np.linspace(-0.1, 0.1, 12)
    custom = MotionCueingPlant(robot, initial_state=x0).CreateDefaultContext()
    np.testing.assert_array_equal(custom.get_discrete_state_vector().value(), x0)


def closed_form(q0, qd0, segments, t):
    """Double integrator under piecewise-constant acceleration [(t_start, u), ...]."""
    q, qd, t_now = np.array(q0, float), np.array(qd0, float), 0.0
    bounds = [s for s, _ in segments[1:]] + [np.inf]
    for (_, u), t_end in zip(segments, bounds, strict=True):
        tau = min(t, t_end) - t_now
        if tau <= 0:
            break
        q, qd, t_now = q + qd * tau + 0.5 * u * tau**2, qd + u * tau, t_now + tau
    return q, qd


def test_simulation_matches_closed_form_double_integrator(robot):
    """Piecewise-constant accelerations switching on control ticks: the discrete plant is
    exact at the sample times."""
    u1 = np.array([0.3, -0.2, 0.1, 0.05, -0.4, 0.6])
    u2 = np.array([-0.5, 0.25, -0.3, 0.0, 0.2, -0.6])
    q0 = np.array([0.1, 0.2, -0.3, 0.0, 0.5, -1.0])
    qd0 = np.array([0.05, -0.05, 0.0, 0.1, 0.0, 0.2])
    t_switch, duration = 1.5, 3.0
    builder = DiagramBuilder()
    # Breaks at t_switch; Drake's ZOH is right-continuous, so the tick at 1.5 s sees u2.
    source = builder.AddSystem(
        TrajectorySource(
            PiecewisePolynomial.ZeroOrderHold([0.0, t_switch, duration + 1], np.c_[u1, u2, u2])
        )
    )
    plant = builder.AddSystem(MotionCueingPlant(robot, initial_state=np.r_[q0, qd0]))
    builder.Connect(source.get_output_port(), plant.GetInputPort("joint_acceleration"))
    log = LogVectorOutput(plant.GetOutputPort("state"), builder, 0.01)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(duration)
    data = log.FindLog(simulator.get_context())
    for t, x in zip(data.sample_times(), data.data().T, strict=True):
        q, qd = closed_form(q0, qd0, [(0.0, u1), (t_switch, u2)], t)
        np.testing.assert_allclose(x, np.r_[q, qd], atol=1e-11, err_msg=f"t = {t}")
    assert data.sample_times()[-1] == pytest.approx(duration)


def test_nan_input_fails_with_time(robot):
    plant = MotionCueingPlant(robot)
    context = plant.CreateDefaultContext()
    plant.GetInputPort("joint_acceleration").FixValue(context, np.full(6, np.nan))
    with pytest.raises(RuntimeError, match=r"joint_acceleration is not finite at t = 0"):
        plant.GetOutputPort("inertial_output").Eval(context)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(time_step=0.0), "time_step must be positive"),
        (dict(initial_state=np.zeros(6)), r"shape \(\.\.\., 12\)"),
        (dict(initial_state=np.full(12, np.nan)), "non-finite"),
    ],
)
def test_bad_construction(robot, kwargs, match):
    with pytest.raises(ValueError, match=match):
        MotionCueingPlant(robot, **kwargs)
