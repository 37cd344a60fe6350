"""MotionCueingPlant: the analytical joint-space motion-cueing plant as a Drake system."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from mca_drake.conventions import CONTROL_PERIOD_S, NUM_CHANNELS
from mca_drake.input_checks import as_float_array
from mca_drake.platforms.kinematics import head_pose, plant_output
from mca_drake.platforms.serial import SerialChain


class MotionCueingPlant(LeafSystem):
    """The exact plant of equation (1) of a platform: one double integrator per joint, output
    y in H.

    .. pydrake_system::

        name: MotionCueingPlant
        input_ports:
        - joint_acceleration
        output_ports:
        - state
        - inertial_output
        - head_pose

    Discrete state x = [q, qd] (2n for n joints), updated every `time_step` with the exact
    zero-order-hold step q += h qd + h^2/2 u, qd += h u, where u is `joint_acceleration`
    (rad/s^2, m/s^2 for a prismatic joint; n) sampled
    at the update time. `state` is x; `inertial_output` is y(q, qd, u) =
    [w_x, w_y, w_z, f_x, f_y, a_z] (rad/s, m/s^2; direct feedthrough of u); `head_pose` is
    X_WH as a RigidTransform. The plant is ideal: it does not enforce joint limits, so
    evaluations can count violations.

    Args:
        robot: the platform (`mca_drake.platforms.files.load_platform`).
        time_step: control period h, s (default 0.01).
        initial_state: default [q, qd], shape (2n,); default the platform's home, at rest.
        update_offset_s: the updates come at t_n + this (s, in [0, time_step)); the live
            loop delays them past the moment its command is sent, so that the plant's work
            is not between a sample and its command (the state still changes once per
            period; an MCA at t_(n+1) reads the same x_(n+1)).
    """

    def __init__(
        self,
        robot: SerialChain,
        time_step: float = CONTROL_PERIOD_S,
        initial_state: np.ndarray | None = None,
        update_offset_s: float = 0.0,
    ):
        super().__init__()
        if not time_step > 0:
            raise ValueError(f"time_step must be positive; got {time_step}")
        if not 0 <= update_offset_s < time_step:
            raise ValueError(f"update_offset_s must be in [0, time_step); got {update_offset_s}")
        self._robot = robot
        self._n = n = robot.num_joints
        self._time_step = float(time_step)
        home = np.concatenate([robot.home, np.zeros(n)])
        x0 = home if initial_state is None else initial_state
        x0 = as_float_array("initial_state", x0, last_dim=2 * n)
        if x0.shape != (2 * n,):
            raise ValueError(f"initial_state must have shape ({2 * n},); got {x0.shape}")

        self._joint_acceleration_port = self.DeclareVectorInputPort("joint_acceleration", n)
        self._state_index = self.DeclareDiscreteState(x0)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self._time_step, offset_sec=update_offset_s, update=self._update
        )
        self._state_port = self.DeclareStateOutputPort("state", self._state_index)
        # y depends on x and u only (not on time): a value computed before an instant's
        # events stays cached through them (the live loop reads it before its poll)
        self._inertial_output_port = self.DeclareVectorOutputPort(
            "inertial_output",
            NUM_CHANNELS,
            self._calc_inertial_output,
            {self.xd_ticket(), self.all_input_ports_ticket()},
        )
        self._head_pose_port = self.DeclareAbstractOutputPort(
            "head_pose",
            lambda: AbstractValue.Make(RigidTransform()),
            self._calc_head_pose,
            prerequisites_of_calc={self.xd_ticket()},
        )

    @property
    def robot(self) -> SerialChain:
        """The robot description this plant was built with."""
        return self._robot

    @property
    def time_step(self) -> float:
        """The control period, s."""
        return self._time_step

    def SetJointState(self, context: Context, q: np.ndarray, qd: np.ndarray) -> None:
        """Sets x = [q, qd] in this system's `context` (rad, rad/s, shape (n,) each)."""
        q = as_float_array("q", q, last_dim=self._n).reshape(self._n)
        qd = as_float_array("qd", qd, last_dim=self._n).reshape(self._n)
        context.SetDiscreteState(self._state_index, np.concatenate([q, qd]))

    def _acceleration(self, context: Context) -> np.ndarray:
        u = self._joint_acceleration_port.Eval(context)
        if not np.all(np.isfinite(u)):
            raise RuntimeError(
                f"MotionCueingPlant: joint_acceleration is not finite at t = {context.get_time()}"
                f" s: {u}"
            )
        return u

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        x = context.get_discrete_state(self._state_index).value()
        u = self._acceleration(context)
        h = self._time_step
        q, qd = x[: self._n], x[self._n :]
        discrete_state.set_value(
            self._state_index, np.concatenate([q + h * qd + (0.5 * h * h) * u, qd + h * u])
        )

    def _calc_inertial_output(self, context: Context, output: BasicVector) -> None:
        x = context.get_discrete_state(self._state_index).value()
        u = self._acceleration(context)
        output.SetFromVector(plant_output(x[: self._n], x[self._n :], u, self._robot))

    def _calc_head_pose(self, context: Context, output: AbstractValue) -> None:
        q = context.get_discrete_state(self._state_index).value()[: self._n]
        output.set_value(RigidTransform(head_pose(q, self._robot)))
