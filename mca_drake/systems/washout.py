"""ClassicalWashout: the classical washout MCA with Drake's differential inverse kinematics."""

from __future__ import annotations

import time

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.multibody.inverse_kinematics import (
    DifferentialInverseKinematicsParameters,
    DifferentialInverseKinematicsStatus,
    DoDifferentialInverseKinematics,
)
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem, ValueProducer

from mca_drake.conventions import CONTROL_PERIOD_S, MCA_STATISTICS
from mca_drake.cueing.washout import WashoutConfig, WashoutFilters
from mca_drake.platforms.clamp import platform_clamp
from mca_drake.platforms.serial import SerialChain
from mca_drake.systems.mca_update import DeclareMcaUpdate


class ClassicalWashout(LeafSystem):
    """Classical washout motion cueing (`mca_drake.cueing.washout`) mapped to joint accelerations.

    .. pydrake_system::

        name: ClassicalWashout
        input_ports:
        - reference
        - state
        output_ports:
        - joint_acceleration
        - statistics

    Every `time_step` an unrestricted update advances the washout filters with the
    reference, forms the desired head pose (the home head pose, level, plus the filtered
    displacement; roll-pitch-yaw of the filtered rotation plus tilt coordination) and a head
    velocity command (the filters' velocities plus `pose_feedback_gain` times the pose
    error), and calls Drake's `DoDifferentialInverseKinematics` on a MultibodyPlant of the
    KR500 with the joint position, velocity and acceleration limits. The joint velocity it
    returns becomes the acceleration u = (v_next - qd) / h, which passes the viability clamp
    (`mca_drake.safety.ViabilityClamp`). `statistics` has the layout of
    `mca_drake.conventions.MCA_STATISTICS`: step time, differential-IK failures, safety
    interventions, 0. The plant context and IK parameters each step overwrites are kept per
    context (a cache entry), so contexts can be cloned and run side by side.

    Args:
        config: filter cut-offs, gains and the tilt-rate limit.
        robot: the platform (its URDF is parsed into the MultibodyPlant).
        time_step: control period, s.
        update_event: the phase of t_k the step runs in (`mca_update.MCA_UPDATE_EVENTS`):
            "unrestricted" offline, "discrete" in the live loop (after its telemetry poll).
    """

    def __init__(
        self,
        config: WashoutConfig | None = None,
        *,
        robot: SerialChain,
        time_step: float = CONTROL_PERIOD_S,
        update_event: str = "unrestricted",
    ):
        super().__init__()
        self._config = config or WashoutConfig()
        self._robot = robot
        self._h = float(time_step)
        self._filters = WashoutFilters(self._config, self._h)
        self._clamp = platform_clamp(self._robot, self._h)
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModels(str(self._robot.urdf_path))
        plant.Finalize()
        self._plant = plant  # finalized: never changed again, so shared by every context
        self._head = plant.GetFrameByName("head")
        r = self._robot
        self._n = n = r.num_joints
        self._home = np.array(self._config.home_position or r.washout_home, dtype=float)
        if self._home.shape != (n,):
            raise ValueError(
                f"home_position {self._home.tolist()} needs {n} values for platform '{r.name}'"
            )
        if np.any(self._home < r.q_min) or np.any(self._home > r.q_max):
            raise ValueError(f"home_position {self._home} is outside the joint limits")
        home_context = plant.CreateDefaultContext()
        plant.SetPositions(home_context, self._home)
        X_WH0 = self._head.CalcPoseInWorld(home_context)
        self._p_neutral = X_WH0.translation().copy()
        self._R_neutral = X_WH0.rotation()
        margin = 0.02 * (r.q_max - r.q_min)
        # The IK keeps 2 % of every range in reserve; _update widens these bounds to the
        # current position when the robot is already inside the reserve (see there).
        self._ik_lower, self._ik_upper = r.q_min + margin, r.q_max - margin
        # The plant context and IK parameters that each step overwrites live in a cache
        # entry, one per context (not on self), so contexts can be cloned and diagrams run
        # in parallel. Nothing invalidates it: every step sets all it reads.
        self._scratch_entry = self.DeclareCacheEntry(
            description="differential IK scratch",
            value_producer=ValueProducer(
                allocate=lambda: AbstractValue.Make(_IkScratch(self)),
                calc=lambda context, value: None,
            ),
            prerequisites_of_calc={self.nothing_ticket()},
        )

        self._reference_port = self.DeclareVectorInputPort("reference", 6)
        self._state_port = self.DeclareVectorInputPort("state", 2 * n)
        self._filter_index = self.DeclareDiscreteState(self._filters.state_size)
        self._command_index = self.DeclareDiscreteState(n)
        self._statistics_index = self.DeclareDiscreteState(len(MCA_STATISTICS))
        DeclareMcaUpdate(self, self._h, self._update, update_event)
        self.DeclareStateOutputPort("joint_acceleration", self._command_index)
        self.DeclareStateOutputPort("statistics", self._statistics_index)

    @property
    def config(self) -> WashoutConfig:
        """The filter's cut-offs, gains and limits."""
        return self._config

    @property
    def home_position(self) -> np.ndarray:
        """The joint positions (rad) this MCA holds at rest; diagrams start the robot here."""
        return self._home.copy()

    def statistics(self, context: Context) -> dict[str, float]:
        """The `statistics` values in `context`, by name."""
        values = context.get_discrete_state(self._statistics_index).value()
        return dict(zip(MCA_STATISTICS, (float(v) for v in values), strict=True))

    def _update(self, context: Context, discrete: DiscreteValues) -> None:
        x = self._state_port.Eval(context)
        reference = self._reference_port.Eval(context)
        # Timed from here: evaluating the inputs computes upstream systems (the plant's
        # output), which is simulation, not this MCA's work.
        start = time.perf_counter()
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(reference))):
            raise RuntimeError(
                f"ClassicalWashout: non-finite state or reference at t = {context.get_time()} s"
            )
        q, qd = x[: self._n], x[self._n :]
        filters = context.get_discrete_state(self._filter_index).value()
        filters, target = self._filters.step(filters, reference)
        _, failures, interventions, _ = context.get_discrete_state(self._statistics_index).value()

        scratch = self._scratch_entry.Eval(context)
        plant, pc, params = self._plant, scratch.plant_context, scratch.parameters
        plant.SetPositions(pc, q)
        plant.SetVelocities(pc, qd)
        X_WH = self._head.CalcPoseInWorld(pc)
        rpy = RollPitchYaw(target["rpy"])
        R_des = RotationMatrix(rpy) @ self._R_neutral
        omega_ff = rpy.CalcAngularVelocityInParentFromRpyDt(target["rpy_rate"])
        k = self._config.pose_feedback_gain
        error = (R_des @ X_WH.rotation().inverse()).ToAngleAxis()
        omega = omega_ff + k * error.angle() * error.axis()
        p_des = self._p_neutral + target["position"]
        v = target["velocity"] + k * (p_des - X_WH.translation())
        # The clipped acceleration and the viability clamp can carry a joint into the
        # reserve band; fixed IK position bounds then make the QP infeasible (the joint
        # cannot get back inside in one step at its velocity limit) and the IK keeps failing.
        # Widened to the current q, the bounds admit v = 0, the QP stays feasible, and a
        # joint in the band can only move back towards the middle.
        params.set_joint_position_limits(
            (np.minimum(self._ik_lower, q), np.maximum(self._ik_upper, q))
        )
        result = DoDifferentialInverseKinematics(
            plant, pc, np.concatenate([omega, v]), self._head, params
        )
        if result.status == DifferentialInverseKinematicsStatus.kNoSolutionFound:
            failures += 1
            v_next = np.zeros(self._n)  # brake towards rest
        else:
            v_next = np.asarray(result.joint_velocities).reshape(-1)
        u = np.clip((v_next - qd) / self._h, -self._robot.qdd_max, self._robot.qdd_max)
        command, intervened = self._clamp(x, u)
        discrete.set_value(self._filter_index, filters)
        discrete.set_value(self._command_index, command)
        discrete.set_value(
            self._statistics_index,
            [time.perf_counter() - start, failures, interventions + intervened, 0.0],
        )


def tracked_velocity_components(robot) -> list[bool]:
    """Which components of the head's spatial velocity [w; v] the washout's IK tracks: those
    the platform can follow (`SerialChain.head_velocity_components`: all six on a serial
    robot or hexapod, those of its coordinates on a rig)."""
    return list(robot.head_velocity_components)


class _IkScratch:
    """What one ClassicalWashout step overwrites: a MultibodyPlant context set to the
    measured state and the differential-IK parameters with that step's position bounds.
    A copy is a fresh scratch (each step sets everything it reads before use)."""

    def __init__(self, washout: ClassicalWashout):
        self._washout = washout
        r, h = washout._robot, washout._h
        self.plant_context = washout._plant.CreateDefaultContext()
        n = washout._n
        params = DifferentialInverseKinematicsParameters(n, n)
        params.set_time_step(h)
        params.set_joint_position_limits((washout._ik_lower, washout._ik_upper))
        params.set_joint_velocity_limits((-r.qd_max, r.qd_max))
        # No acceleration limits here: with them, v_next = 0 is infeasible whenever a joint
        # moves faster than qdd_max h, and the QP reports no solution at ordinary speeds.
        # The acceleration is clipped afterwards and then passes the viability clamp.
        params.set_nominal_joint_position(washout._home)
        params.set_joint_centering_gain(np.zeros((n, n)))
        # A rig moves in fewer than six coordinates: the IK tracks the head's velocity in
        # those it has (a pitch/roll seat its roll and pitch rates: the tilt coordination),
        # not the whole spatial velocity it cannot follow.
        params.set_end_effector_velocity_flag(tracked_velocity_components(r))
        self.parameters = params

    def __deepcopy__(self, memo) -> _IkScratch:
        return _IkScratch(self._washout)
