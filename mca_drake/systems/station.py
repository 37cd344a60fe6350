"""The station: a serial platform's physical robot simulated by Drake, as the MCA sees it.

`AddStation` adds to a DiagramBuilder, for the platform it is given (its URDF, its n joints):

- a discrete MultibodyPlant of the platform's URDF (1 ms by default, no contact: a motion
  simulator touches nothing, so every collision pair of the robot is filtered out);
- `CommandLimiter`: every command passes it before it reaches the robot; it clamps the
  command into the viability interval of the commanded trajectory, so that trajectory never
  leaves the joint limits, and the command computed at t_n enters at the next plant step (a
  one-step, 1 ms, transport delay, as on hardware);
- a desired-trajectory generator: the double integrator of the limited command, stepped at
  the plant rate with the plant's own semi-implicit Euler step (qd += h u, q += h qd), so
  that the inverse-dynamics controller of an exact model tracks it exactly and the measured
  motion is the commanded one (a Drake LinearSystem, so no Python runs at 1 kHz);
- Drake's InverseDynamicsController: tau = M(q) (qdd_d + kp (q_d - q) + kd (qd_d - qd)
  + ki integral) + C(q, qd) qd - tau_g(q), with kp = w^2, kd = 2 zeta w per joint;
- actuator torque limits at the URDF efforts, or ideal actuators (the default);
- Drake's Accelerometer and Gyroscope on the head frame H, optional Gaussian sensor noise,
  and `HeadImuOutput`, which turns their readings into the measured y of `mca_drake.conventions`;
- an optional measurement delay on everything the MCA reads (state and measured y).
"""

import dataclasses

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    DiscreteContactApproximation,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import BasicVector, Context, DiagramBuilder, LeafSystem, OutputPort
from pydrake.systems.primitives import (
    Adder,
    DiscreteTimeDelay,
    Gain,
    LinearSystem,
    Multiplexer,
    RandomSource,
    Saturation,
)
from pydrake.systems.sensors import Accelerometer, Gyroscope

from mca_drake.conventions import CONTROL_PERIOD_S, GRAVITY, NUM_CHANNELS
from mca_drake.input_checks import check_config_numbers, check_range
from mca_drake.platforms.kinematics import plant_output
from mca_drake.platforms.serial import SerialChain
from mca_drake.systems.command_limiter import CommandLimiter


@dataclasses.dataclass
class StationConfig:
    """Settings of the simulated robot, its controller and its sensors."""

    # MultibodyPlant (and controller, sensor) period, s.
    plant_time_step: float = 1e-3
    # Closed-loop bandwidth of the joint tracking error, rad/s: kp = w^2, kd = 2 zeta w.
    # 40 rad/s (6.4 Hz) is well below the 1 kHz rate and well above the cueing band.
    tracking_bandwidth: float = 40.0
    # Damping ratio zeta of the tracking error (1: critically damped).
    tracking_damping: float = 1.0
    # Integral gain ki, 1/s^3 (0: none; the controller's model is exact).
    integral_gain: float = 0.0
    # Saturate joint torques at the effort limits (URDF); off: ideal actuators.
    torque_limits: bool = False
    # Standard deviation of white Gaussian accelerometer noise, m/s^2 (0: none).
    accelerometer_noise_std: float = 0.0
    # Standard deviation of white Gaussian gyroscope noise, rad/s (0: none).
    gyroscope_noise_std: float = 0.0
    # Delay of every measurement the MCA reads (state and measured y), s; rounded to whole
    # plant steps.
    measurement_delay_s: float = 0.0

    def validate(self) -> None:
        """Raises ValueError for values that cannot run."""
        check_config_numbers(self)
        if not 0 < self.plant_time_step <= 0.01:
            raise ValueError(f"plant_time_step must be in (0, 0.01] s; got {self.plant_time_step}")
        if not self.tracking_bandwidth > 0 or not self.tracking_damping > 0:
            raise ValueError("tracking_bandwidth and tracking_damping must be positive")
        # Explicit PD on a sampled loop is stable well below 2 / h.
        if self.tracking_bandwidth * self.plant_time_step > 0.2:
            raise ValueError(
                f"tracking_bandwidth {self.tracking_bandwidth} rad/s is too high for a "
                f"{self.plant_time_step} s plant step (keep w h <= 0.2)"
            )
        for name in ("integral_gain", "accelerometer_noise_std", "gyroscope_noise_std"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0; got {value}")
        # A delay line holds every plant step of the delay: 1 s is 1000 steps, and more is
        # no longer a motion simulator.
        check_range("StationConfig", "measurement_delay_s", self.measurement_delay_s, 0.0, 1.0)

    @property
    def delay_steps(self) -> int:
        """The measurement delay in plant steps."""
        return round(self.measurement_delay_s / self.plant_time_step)

    def gains(self, joints: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(kp, ki, kd) for each of `joints` joints."""
        w, zeta = self.tracking_bandwidth, self.tracking_damping
        ones = np.ones(joints)
        return w * w * ones, self.integral_gain * ones, 2 * zeta * w * ones


class HeadImuOutput(LeafSystem):
    """Measured y from the head IMU: y = [w_H, f_x, f_y, f_z - g R_WH[2, 2]].

    .. pydrake_system::

        name: HeadImuOutput
        input_ports:
        - imu
        - body_poses
        output_ports:
        - inertial_output

    `imu` is [gyroscope (3, rad/s), accelerometer (3, m/s^2)], both expressed in H: the
    angular velocity w_H and the specific force f = R_WH^T (a - g_W). The vertical channel
    of y is the kinematic acceleration a_z = (R_WH^T a)_z = f_z + (R_WH^T g_W)_z, which needs
    the head's orientation: taken from `body_poses` (the MultibodyPlant's, i.e. the forward
    kinematics of the measured joint angles, as a real simulator computes it from its
    encoders).

    Args:
        head_body_index: index of the head body in the plant's body_poses vector.
    """

    def __init__(self, head_body_index: int):
        super().__init__()
        self._head = int(head_body_index)
        self._imu_port = self.DeclareVectorInputPort("imu", 6)
        self._poses_port = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        self.DeclareVectorOutputPort("inertial_output", 6, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        imu = self._imu_port.Eval(context)
        R_WH = self._poses_port.Eval(context)[self._head].rotation().matrix()
        y = imu.copy()
        y[5] -= GRAVITY * R_WH[2, 2]
        output.SetFromVector(y)


@dataclasses.dataclass
class StationHandles:
    """What `AddStation` added, and the ports a closed loop connects to.

    Attributes:
        plant: the simulated MultibodyPlant (discrete).
        scene_graph: its SceneGraph, or None when geometry was not requested.
        controller: the InverseDynamicsController.
        desired: the desired-trajectory LinearSystem (state [q_d, qd_d]).
        limiter: the CommandLimiter every command passes.
        joint_acceleration: input port for the MCA's command, rad/s^2 (n).
        measured_state: output port [q, qd] the MCA reads (after the delay), (2n).
        measured_output: output port measured y the MCA reads (after the delay), (6).
        desired_state: output port [q_d, qd_d] (2n).
        true_state: output port of the plant's state without delay (2n).
        true_output: measured y without delay (6).
        initial_state: [q, qd] at rest that `SetInitialState` applies (2n).
        delay_lines: the measurement delay lines with the value each holds at rest (empty
            without a delay).
    """

    plant: MultibodyPlant
    scene_graph: SceneGraph | None
    controller: InverseDynamicsController
    desired: LinearSystem
    limiter: CommandLimiter
    joint_acceleration: object
    measured_state: OutputPort
    measured_output: OutputPort
    desired_state: OutputPort
    true_state: OutputPort
    true_output: OutputPort
    initial_state: np.ndarray
    delay_lines: list[tuple[DiscreteTimeDelay, np.ndarray]]

    def SetInitialState(self, root_context: Context) -> None:
        """Puts the robot, the desired trajectory and the delay lines at rest at
        `initial_state` (the builder's)."""
        x0 = self.initial_state
        self.plant.SetPositionsAndVelocities(
            self.plant.GetMyMutableContextFromRoot(root_context), x0
        )
        self.desired.GetMyMutableContextFromRoot(root_context).SetDiscreteState(x0)
        for line, value in self.delay_lines:
            state = line.GetMyMutableContextFromRoot(root_context).get_mutable_discrete_state(0)
            state.SetFromVector(np.tile(value, state.size() // value.size))


def _double_integrator(h: float, n: int) -> LinearSystem:
    """x = [q, qd] (2n), u = qdd (n): the semi-implicit Euler step of the discrete
    MultibodyPlant (qd' = qd + h u, q' = q + h qd'), output x."""
    eye = np.eye(n)
    A = np.block([[eye, h * eye], [np.zeros((n, n)), eye]])
    B = np.vstack([h * h * eye, h * eye])
    return LinearSystem(A, B, np.eye(2 * n), np.zeros((2 * n, n)), h)


def _AddRobotPlant(
    builder: DiagramBuilder, robot: SerialChain, h: float, with_geometry: bool
) -> tuple[MultibodyPlant, SceneGraph | None]:
    """The discrete MultibodyPlant of the robot (and its SceneGraph, with geometry)."""
    # TAMSI: with no contact it is plain semi-implicit Euler, 2.5x faster per step than the
    # default (lagged SAP) on this robot (30 against 78 us).
    plant_config = MultibodyPlantConfig(time_step=h, discrete_contact_approximation="tamsi")
    if with_geometry:
        plant, scene_graph = AddMultibodyPlant(plant_config, builder)
    else:
        plant, scene_graph = builder.AddNamedSystem("plant", MultibodyPlant(h)), None
        plant.set_discrete_contact_approximation(DiscreteContactApproximation.kTamsi)
    plant.set_name("plant")
    # One gravity for the physics, the accelerometer and HeadImuOutput: the kinematics'.
    plant.mutable_gravity_field().set_gravity_vector(np.array([0.0, 0.0, -GRAVITY]))
    Parser(plant).AddModels(str(robot.urdf_path))
    plant.Finalize()
    for i, name in enumerate(robot.joint_names):
        joint = plant.GetJointByName(name)
        if joint.position_start() != i or joint.velocity_start() != i:
            raise RuntimeError(f"{name} is not joint {i} of the MultibodyPlant state")
    if scene_graph is not None:
        # A motion simulator touches nothing: filter every collision pair of the robot.
        inspector = scene_graph.model_inspector()
        ids = inspector.GetAllGeometryIds()
        scene_graph.collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeWithin(GeometrySet(ids))
        )
    return plant, scene_graph


def _AddTrackingController(
    builder: DiagramBuilder,
    plant: MultibodyPlant,
    robot: SerialChain,
    config: StationConfig,
    control_period: float,
) -> tuple[InverseDynamicsController, LinearSystem, CommandLimiter]:
    """The command limiter, the desired trajectory it integrates and the inverse-dynamics
    controller that tracks it, wired to `plant` (torques saturated when configured)."""
    h = config.plant_time_step
    # The controller's model: a copy of the same URDF (continuous: it only does inverse
    # dynamics). Kept alive by the controller's binding.
    control_plant = MultibodyPlant(0.0)
    Parser(control_plant).AddModels(str(robot.urdf_path))
    control_plant.Finalize()
    kp, ki, kd = config.gains(robot.num_joints)
    controller = builder.AddNamedSystem(
        "inverse_dynamics",
        InverseDynamicsController(control_plant, kp, ki, kd, has_reference_acceleration=True),
    )
    desired = builder.AddNamedSystem("desired_trajectory", _double_integrator(h, robot.num_joints))
    builder.Connect(desired.get_output_port(), controller.get_input_port_desired_state())
    builder.Connect(plant.get_state_output_port(), controller.get_input_port_estimated_state())
    torque = controller.get_output_port_control()
    if config.torque_limits:
        # The actuation port, which MultibodyPlant clamps at the URDF efforts, behind an
        # explicit saturation at the description's limits (which may be set lower).
        limit = robot.effort_max
        saturation = builder.AddNamedSystem("torque_limits", Saturation(-limit, limit))
        builder.Connect(torque, saturation.get_input_port())
        builder.Connect(saturation.get_output_port(), plant.get_actuation_input_port())
    else:
        # Ideal actuators: generalized forces bypass the actuators' effort clamp.
        builder.Connect(torque, plant.get_applied_generalized_force_input_port())
    # The limited command feeds both the integrator and the controller's feedforward, so
    # the two stay consistent within every plant step.
    limiter = builder.AddNamedSystem("command_limiter", CommandLimiter(robot, control_period, h))
    builder.Connect(desired.get_output_port(), limiter.GetInputPort("desired_state"))
    command_split = limiter.GetOutputPort("limited_command")
    builder.Connect(command_split, desired.get_input_port())
    builder.Connect(command_split, controller.get_input_port_desired_acceleration())
    return controller, desired, limiter


def _AddHeadImu(
    builder: DiagramBuilder, plant: MultibodyPlant, config: StationConfig
) -> HeadImuOutput:
    """Drake's Gyroscope and Accelerometer on the head body (with their noise, when
    configured), read out as the plant output y by a HeadImuOutput."""
    head = plant.GetBodyByName("head")
    gyroscope = builder.AddNamedSystem("gyroscope", Gyroscope(head, RigidTransform()))
    accelerometer = builder.AddNamedSystem(
        "accelerometer",
        Accelerometer(head, RigidTransform(), plant.gravity_field().gravity_vector()),
    )
    for sensor in (gyroscope, accelerometer):
        builder.Connect(plant.get_body_poses_output_port(), sensor.get_body_poses_input_port())
        builder.Connect(
            plant.get_body_spatial_velocities_output_port(), sensor.get_body_velocities_input_port()
        )
    builder.Connect(
        plant.get_body_spatial_accelerations_output_port(),
        accelerometer.get_body_accelerations_input_port(),
    )
    imu = builder.AddNamedSystem("imu_mux", Multiplexer([3, 3]))
    builder.Connect(gyroscope.get_measurement_output_port(), imu.get_input_port(0))
    builder.Connect(accelerometer.get_measurement_output_port(), imu.get_input_port(1))
    imu_out = imu.get_output_port()
    std = np.r_[np.full(3, config.gyroscope_noise_std), np.full(3, config.accelerometer_noise_std)]
    if np.any(std > 0):
        noise = builder.AddNamedSystem(
            "imu_noise",
            RandomSource(RandomDistribution.kGaussian, 6, config.plant_time_step),
        )
        scale = builder.AddNamedSystem("imu_noise_std", Gain(std))
        adder = builder.AddNamedSystem("imu_with_noise", Adder(2, 6))
        builder.Connect(noise.get_output_port(), scale.get_input_port())
        builder.Connect(imu_out, adder.get_input_port(0))
        builder.Connect(scale.get_output_port(), adder.get_input_port(1))
        imu_out = adder.get_output_port()
    measured = builder.AddNamedSystem("head_imu_output", HeadImuOutput(int(head.index())))
    builder.Connect(imu_out, measured.GetInputPort("imu"))
    builder.Connect(plant.get_body_poses_output_port(), measured.GetInputPort("body_poses"))
    return measured


def AddStation(
    builder: DiagramBuilder,
    robot: SerialChain,
    config: StationConfig | None = None,
    initial_state: np.ndarray | None = None,
    with_geometry: bool = False,
    control_period: float = CONTROL_PERIOD_S,
) -> StationHandles:
    """Adds the simulated robot with its controller and head IMU to `builder`.

    Args:
        builder: the diagram builder.
        robot: the serial platform (its URDF is the MultibodyPlant's; n joints).
        config: station settings (default StationConfig()).
        initial_state: [q, qd] at rest to start from, shape (2n,) (default home, at rest). Apply it
            to a context with `StationHandles.SetInitialState`.
        with_geometry: also add a SceneGraph (needed for Meshcat); off, the plant runs
            without geometry, which is faster.
        control_period: the period of the MCA that drives it, s: the command limiter acts
            once per period (a whole number of plant steps).

    Returns:
        StationHandles; connect an MCA's `joint_acceleration` output to
        `handles.joint_acceleration`, and its inputs from `measured_state` and
        `measured_output`.
    """
    config = config if config is not None else StationConfig()
    config.validate()
    h = config.plant_time_step
    n = robot.num_joints
    home = np.concatenate([robot.home, np.zeros(n)])
    x0 = home if initial_state is None else np.asarray(initial_state, float)
    if x0.shape != (2 * n,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"initial_state must be {2 * n} finite numbers; got {x0}")

    plant, scene_graph = _AddRobotPlant(builder, robot, h, with_geometry)
    controller, desired, limiter = _AddTrackingController(
        builder, plant, robot, config, control_period
    )
    measured = _AddHeadImu(builder, plant, config)
    state_out, y_out = plant.get_state_output_port(), measured.GetOutputPort("inertial_output")
    delays = []
    if config.delay_steps > 0:
        state_delay = builder.AddNamedSystem(
            "state_delay", DiscreteTimeDelay(h, config.delay_steps, 2 * n)
        )
        y_delay = builder.AddNamedSystem(
            "output_delay", DiscreteTimeDelay(h, config.delay_steps, NUM_CHANNELS)
        )
        builder.Connect(state_out, state_delay.get_input_port())
        builder.Connect(y_out, y_delay.get_input_port())
        y0 = plant_output(x0[:n], x0[n:], np.zeros(n), robot)
        delays = [(state_delay, x0), (y_delay, y0)]
        state_out, y_out = state_delay.get_output_port(), y_delay.get_output_port()

    handles = StationHandles(
        plant=plant,
        scene_graph=scene_graph,
        controller=controller,
        desired=desired,
        limiter=limiter,
        joint_acceleration=limiter.GetInputPort("command"),
        measured_state=state_out,
        measured_output=y_out,
        desired_state=desired.get_output_port(),
        true_state=plant.get_state_output_port(),
        true_output=measured.GetOutputPort("inertial_output"),
        initial_state=x0,
        delay_lines=delays,
    )
    return handles
