"""KR500 station: MultibodyPlant + inverse dynamics + head IMU, checked against independent
oracles (closed-form integration of the command, the numpy DH kinematics' plant_output)."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource, ZeroOrderHold
from pydrake.trajectories import PiecewisePolynomial

from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform
from mca_drake.platforms.kinematics import plant_output
from mca_drake.platforms.serial import NUM_JOINTS
from mca_drake.systems.station import AddStation, StationConfig

H = 0.01  # control period of the command, s
HOME = np.array([0.0, 0.0, 0.5, 0.0, -0.5, 0.0])


@pytest.fixture(scope="module")
def robot():
    return load_platform(DEFAULT_PLATFORM)


def smooth_command(times: np.ndarray) -> np.ndarray:
    """A smooth joint-acceleration command (T, 6), rad/s^2, well inside Table I limits:
    a sum of sines that starts at zero."""
    freqs = np.array([0.3, 0.5, 0.4, 0.7, 0.6, 0.8])
    amps = np.array([0.3, 0.2, 0.3, 0.2, 0.3, 0.2])
    return amps * np.sin(2 * np.pi * freqs * times[:, None]) * (1 - np.exp(-times[:, None]))


def run_station(robot, config: StationConfig, duration: float, log_period: float):
    """The station driven by `smooth_command` through a 10 ms discrete zero-order hold (as
    an MCA's state output port); logs every `log_period`."""
    times = np.arange(0.0, duration + 2 * H, H)
    command = smooth_command(times)
    builder = DiagramBuilder()
    source = builder.AddSystem(
        TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, command.T))
    )
    hold = builder.AddSystem(ZeroOrderHold(H, NUM_JOINTS))
    builder.Connect(source.get_output_port(), hold.get_input_port())
    station = AddStation(builder, robot, config, np.r_[HOME, np.zeros(6)])
    builder.Connect(hold.get_output_port(), station.joint_acceleration)
    ports = dict(
        x=station.true_state,
        y=station.true_output,
        xd=station.desired_state,
        x_mca=station.measured_state,
        y_mca=station.measured_output,
    )
    logs = {name: LogVectorOutput(port, builder, log_period) for name, port in ports.items()}
    diagram = builder.Build()
    simulator = Simulator(diagram)
    station.SetInitialState(simulator.get_mutable_context())
    simulator.AdvanceTo(duration)
    context = simulator.get_context()
    data = {name: log.FindLog(context).data().T for name, log in logs.items()}
    data["t"] = logs["x"].FindLog(context).sample_times()
    data["command"] = command
    data["command_times"] = times
    return data


def desired_oracle(t_plant: np.ndarray, command: np.ndarray, h_plant: float) -> np.ndarray:
    """[q_d, qd_d] at the plant steps: the command integrated by the plant's semi-implicit
    Euler step (qd += h u, then q += h qd), applied one plant step late (the command
    computed at t_n reaches the robot at t_n + h_plant)."""
    x = np.r_[HOME, np.zeros(6)]
    out = [x]
    for t in t_plant[:-1]:
        # the 10 ms sample held at t - h_plant (zero before the first command arrives)
        k = int(np.floor((t - h_plant) / H + 1e-9))
        u = command[k] if k >= 0 else np.zeros(6)
        q, qd = x[:NUM_JOINTS], x[NUM_JOINTS:]
        qd = qd + h_plant * u
        x = np.r_[q + h_plant * qd, qd]
        out.append(x)
    return np.array(out)


def test_desired_trajectory_is_the_integrated_command_one_step_late(robot):
    config = StationConfig()
    data = run_station(robot, config, 2.0, config.plant_time_step)
    oracle = desired_oracle(data["t"], data["command"], config.plant_time_step)
    np.testing.assert_allclose(data["xd"], oracle, atol=1e-10)


def test_controller_tracks_a_smooth_joint_trajectory(robot):
    """The controller's model is exact and the desired trajectory takes the plant's own
    step, so the robot follows it to round-off: |q - q_d| and |qd - qd_d| <= 1e-9."""
    data = run_station(robot, StationConfig(), 6.0, H)
    error = np.abs(data["x"] - data["xd"])
    assert error[:, :NUM_JOINTS].max() < 1e-9
    assert error[:, NUM_JOINTS:].max() < 1e-9
    # The robot really moved: the command integrates to tenths of a radian.
    assert np.abs(data["x"][:, :NUM_JOINTS] - HOME).max() > 0.05


@pytest.mark.parametrize("bandwidth", [20.0, 40.0])
def test_tracking_error_decays_as_the_designed_critically_damped_loop(robot, bandwidth):
    """Start 0.01 rad off the desired pose with no command: the inverse-dynamics loop makes
    the error obey e'' + 2 w e' + w^2 e = 0, i.e. e(t) = e0 (1 + w t) exp(-w t)."""
    from pydrake.systems.primitives import ConstantVectorSource

    config = StationConfig(tracking_bandwidth=bandwidth)
    builder = DiagramBuilder()
    station = AddStation(builder, robot, config, np.r_[HOME, np.zeros(6)])
    source = builder.AddSystem(ConstantVectorSource(np.zeros(NUM_JOINTS)))
    builder.Connect(source.get_output_port(), station.joint_acceleration)
    log = LogVectorOutput(station.true_state, builder, config.plant_time_step)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    station.SetInitialState(context)
    e0 = np.array([0.01, -0.01, 0.01, 0.01, -0.01, 0.01])
    station.plant.SetPositions(station.plant.GetMyMutableContextFromRoot(context), HOME + e0)
    simulator.AdvanceTo(0.2)
    data = log.FindLog(simulator.get_context())
    t, q = data.sample_times(), data.data().T[:, :NUM_JOINTS]
    expected = e0 * ((1 + bandwidth * t) * np.exp(-bandwidth * t))[:, None]
    # the sampled loop follows the continuous design to a few per cent of e0
    np.testing.assert_allclose(q - HOME, expected, atol=0.06 * 0.01)


def test_measured_y_equals_plant_output_of_the_robot_motion(robot):
    """The IMU chain (Drake Accelerometer/Gyroscope on the MultibodyPlant, HeadImuOutput)
    equals the numpy DH kinematics' y on the robot's own trajectory: at every plant step,
    y_k = plant_output(q_k, qd_k, (qd_k - qd_(k-1)) / h) (a discrete MultibodyPlant reports
    the acceleration of the step that ended at t_k)."""
    config = StationConfig()
    h = config.plant_time_step
    data = run_station(robot, config, 1.5, h)
    x, y = data["x"], data["y"]
    qdd = (x[1:, NUM_JOINTS:] - x[:-1, NUM_JOINTS:]) / h
    expected = plant_output(x[1:, :NUM_JOINTS], x[1:, NUM_JOINTS:], qdd, robot)
    # angular velocity: exact; accelerations: to the O(h) velocity-product terms of a
    # discrete plant's step (which end of the step their velocity is taken at)
    np.testing.assert_allclose(y[1:, :3], expected[:, :3], atol=1e-12)
    np.testing.assert_allclose(y[1:, 3:], expected[:, 3:], atol=1e-3)
    assert np.abs(y[:, 3:]).max() > 0.1  # a real signal, not zeros


def test_measured_y_with_tracking_matches_the_commanded_trajectory(robot):
    """With (near-)perfect tracking, measured y equals plant_output on the commanded
    (desired) trajectory with the commanded acceleration, to the tracking error."""
    config = StationConfig()
    h = config.plant_time_step
    data = run_station(robot, config, 3.0, h)
    xd, y = data["xd"], data["y"]
    # the accelerometer at t reports the plant step [t - h, t), which carried the command
    # sample held at t - 2h (one plant step of transport delay)
    k = np.floor((data["t"] - 2 * h) / H + 1e-9).astype(int)
    u = np.where(k[:, None] >= 0, data["command"][np.maximum(k, 0)], 0.0)
    expected = plant_output(xd[:, :NUM_JOINTS], xd[:, NUM_JOINTS:], u, robot)
    err = np.abs(y - expected)
    assert err[:, :3].max() < 2e-3  # rad/s
    assert err[:, 3:].max() < 2e-2  # m/s^2
    assert np.abs(y[:, 3:]).max() > 0.1  # a real signal, not zeros


def test_sensor_noise_has_the_configured_spread(robot):
    config = StationConfig(accelerometer_noise_std=0.05, gyroscope_noise_std=0.004)
    clean = run_station(robot, StationConfig(), 2.0, H)
    noisy = run_station(robot, config, 2.0, H)
    noise = noisy["y"] - clean["y"]
    np.testing.assert_allclose(noise[:, :3].std(axis=0), 0.004, rtol=0.2)
    np.testing.assert_allclose(noise[:, 3:].std(axis=0), 0.05, rtol=0.2)
    assert np.abs(noise.mean(axis=0)).max() < 0.02


def test_measurement_delay_shifts_what_the_mca_reads(robot):
    config = StationConfig(measurement_delay_s=0.005)
    h = config.plant_time_step
    data = run_station(robot, config, 1.0, h)
    steps = config.delay_steps
    assert steps == 5
    np.testing.assert_allclose(data["x_mca"][steps:], data["x"][:-steps], atol=1e-12)
    np.testing.assert_allclose(data["y_mca"][steps:], data["y"][:-steps], atol=1e-12)
    # before the first measurement arrives the MCA reads the robot at rest at home
    np.testing.assert_allclose(data["x_mca"][0], np.r_[HOME, np.zeros(6)], atol=1e-12)


def test_torque_limits_bound_the_applied_torques(robot):
    """With limits at a tenth of the URDF efforts, a hard command saturates: the applied
    torques never exceed the limits, and tracking suffers."""
    from pydrake.systems.primitives import ConstantVectorSource

    config = StationConfig(torque_limits=True)
    builder = DiagramBuilder()
    weak = robot.__class__(**{**robot.__dict__, "effort_max": 0.1 * robot.effort_max})
    station = AddStation(builder, weak, config, np.r_[HOME, np.zeros(6)])
    source = builder.AddSystem(ConstantVectorSource(np.array([1.5, 1.0, 1.5, 0.5, 1.5, 0.5])))
    builder.Connect(source.get_output_port(), station.joint_acceleration)
    torque_log = LogVectorOutput(
        station.plant.get_net_actuation_output_port(), builder, config.plant_time_step
    )
    command_log = LogVectorOutput(
        station.controller.get_output_port_control(), builder, config.plant_time_step
    )
    diagram = builder.Build()
    simulator = Simulator(diagram)
    station.SetInitialState(simulator.get_mutable_context())
    simulator.AdvanceTo(0.5)
    tau = torque_log.FindLog(simulator.get_context()).data().T[1:]
    wanted = command_log.FindLog(simulator.get_context()).data().T[1:]
    assert np.all(np.abs(tau) <= weak.effort_max + 1e-6)
    assert np.any(np.abs(wanted) > 1.01 * weak.effort_max)  # the controller asked for more
    assert np.any(np.isclose(np.abs(tau), weak.effort_max, rtol=1e-9))


def test_bad_station_settings_fail_clearly():
    for config, match in (
        (StationConfig(plant_time_step=0.0), "plant_time_step"),
        (StationConfig(tracking_bandwidth=400.0), "too high"),
        (StationConfig(accelerometer_noise_std=float("nan")), "accelerometer_noise_std"),
        (StationConfig(measurement_delay_s=-0.1), "measurement_delay_s"),
    ):
        with pytest.raises(ValueError, match=match):
            config.validate()
