"""The closed-loop runner for both plants, its one result type and its summary.

`run_closed_loop` simulates ReferenceSource -> MCA -> plant over a reference and returns
aligned signals at the control period (t_n = n h) with the result summary (README,
"Result summary"). The plant is

- "analytical": the exact joint-space plant of the paper (`MotionCueingPlant`); y_n =
  y(x_n, u_n) is computed from the logged state and command, and the logs are checked to
  satisfy x_(n+1) = step(x_n, u_n) exactly;
- "multibody": the KR500 station (MultibodyPlant at 1 kHz, inverse-dynamics control, head
  IMU). Alignment with the analytical convention: the angular velocity of sample n is the
  gyroscope at t_n; the specific force and vertical acceleration are the accelerometer at
  t_(n+1), whose plant step is the first that carries the command u_n (the command reaches
  the robot one plant step after it is computed).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from tqdm.auto import tqdm

from mca_drake.atomic_io import atomic_write_json, check_writable
from mca_drake.comfort import ComfortConfig, comfort_block
from mca_drake.cueing import McaConfig, as_mca_config, mca_config_record, mca_name
from mca_drake.cueing.dpc import DpcConfig, for_vehicle, policy_record
from mca_drake.cueing.plausibility import PlausibilityConfig
from mca_drake.metrics import false_rotation, jolts, tracking_score
from mca_drake.perception.models import PerceptionConfig
from mca_drake.perception.scores import perceived_run
from mca_drake.platforms.kinematics import head_pose, plant_output
from mca_drake.platforms.serial import SerialChain
from mca_drake.platforms.usage import joint_range_used, joint_usage
from mca_drake.references.reference import Reference, ReferenceScaling
from mca_drake.simulation.builders import MakeAnalyticalClosedLoop, MakeMultibodyClosedLoop
from mca_drake.systems.station import StationConfig

# The plants a closed loop runs on: the paper's joint-space plant, or the KR500 station.
PLANTS = ("analytical", "multibody")
# Tolerance of the timing self-check x_(n+1) = step(x_n, u_n) on the analytical plant.
_CONSISTENCY_TOL = 1e-9


@dataclasses.dataclass
class ClosedLoopResult:
    """Aligned closed-loop signals (T samples at t_n = n h) and the result summary."""

    times: np.ndarray  # (T,), s
    reference: np.ndarray  # (T, 6), r_n
    outputs: np.ndarray  # (T, 6), y_n (analytical: y(x_n, u_n); multibody: the head IMU)
    commands: np.ndarray  # (T, 6), u_n, the MCA's joint accelerations, rad/s^2
    states: np.ndarray  # (T, 12), x_n = [q_n, qd_n] (multibody: measured)
    accelerations: np.ndarray  # (T, 6), joint accelerations over [t_n, t_(n+1)), rad/s^2
    step_times_s: np.ndarray  # (T,), MCA compute time per control step, s
    summary: dict
    # (T, 12), [q_d, qd_d] the station's controller tracks at t_n; None on the analytical plant.
    desired_states: np.ndarray | None = None
    # (T,), what the input plausibility guard did in each period (index in
    # `cueing.plausibility.REACTIONS`); None without the guard.
    reactions: np.ndarray | None = None


def simulate_with_progress(simulator: Simulator, duration_s: float, progress: bool) -> float:
    """Advances `simulator` by `duration_s` in chunks with a progress bar; returns wall s."""
    start = time.perf_counter()
    t0 = simulator.get_context().get_time()
    chunk = max(duration_s / 100, 0.1)
    with tqdm(total=round(duration_s, 2), unit="sim s", disable=not progress, leave=False) as bar:
        t = t0
        while t < t0 + duration_s - 1e-9:
            t_next = min(t + chunk, t0 + duration_s)
            simulator.AdvanceTo(t_next)
            # set, not add: summed float steps would show as 5.999999999999999
            bar.n = round(t_next - t0, 2)
            bar.refresh()
            t = t_next
    return time.perf_counter() - start


def step_time_summary(step_times_s: np.ndarray) -> dict[str, float]:
    """Median, 99th percentile and maximum of per-step compute times, s."""
    if step_times_s.size == 0:
        return {"median": float("nan"), "p99": float("nan"), "max": float("nan")}
    return {
        "median": float(np.median(step_times_s)),
        "p99": float(np.percentile(step_times_s, 99)),
        "max": float(np.max(step_times_s)),
    }


def checked_duration(reference: Reference, duration_s: float | None) -> float:
    """The simulated time of a closed loop over `reference`: `duration_s`, or the whole
    reference when None; raises ValueError outside (0, reference duration]."""
    duration = reference.duration_s if duration_s is None else float(duration_s)
    if not 0 < duration <= reference.duration_s + 1e-9:
        raise ValueError(
            f"duration_s must be in (0, {reference.duration_s:g}] s (the reference); got "
            f"{duration_s}"
        )
    return duration


def closed_loop_summary(
    *,
    mca: str,
    mca_config: dict,
    plant: str,
    reference_name: str,
    duration_s: float,
    reference: np.ndarray,
    outputs: np.ndarray,
    states: np.ndarray,
    accelerations: np.ndarray,
    statistics: np.ndarray | None,
    wall_s: float,
    robot: SerialChain,
    time_step: float,
    perception: PerceptionConfig | None = None,
) -> tuple[dict, np.ndarray]:
    """The result summary (README, "Result summary") for n aligned samples, and the MCA step times.

    Args:
        mca: the name of what ran (`mca_drake.cueing.mca_name`; "optimal" for the bound).
        mca_config: the full config that ran, as a record (`mca_config_record`).
        reference: r_n, shape (n, 6).
        outputs: y_n, shape (n, 6).
        states: x_n, shape (n, 2j) for the platform's j joints.
        accelerations: the joint accelerations over each step, rad/s^2, shape (n, j).
        statistics: the MCA's `statistics` log (row k published at t_k, so row n holds the
            totals after n steps), shape (n + 1 or more, 4); None for an offline solve
            (the optimal bound), which has no control steps: `step_time_s` is then None
            and no failure or intervention is counted.
        wall_s: wall time of the simulation, s.
        time_step: the sample period of the signals, s.
        perception: the vestibular model of the `perceived` block (default
            PerceptionConfig()).
    """
    n = reference.shape[0]
    offline = statistics is None
    if offline:
        statistics = np.zeros((n + 1, 4))
    step_times = statistics[1 : n + 1, 0]
    score = tracking_score(reference, outputs)
    # Not moving at all renders y = 0 (at rest, the head is level at every home pose).
    zero_motion = tracking_score(reference, np.zeros_like(reference))
    joints = robot.num_joints
    usage = joint_usage(states[:, :joints], states[:, joints:], accelerations, robot)
    # the vertical specific force needs the head's tilt: R_WH[2, 2] from the joint positions
    head_z_up = head_pose(states[:, :joints], robot)[:, 2, 2]
    perceived = perceived_run(reference, outputs, time_step, perception, head_z_up)
    summary = {
        "mca": mca,
        "mca_config": mca_config,
        "plant": plant,
        "platform": robot.summary(),
        "reference": reference_name,
        "duration_s": duration_s,
        "pi": score.pi,
        "pi_zero_motion": zero_motion.pi,
        "rmse": score.rmse.tolist(),
        "cc": score.cc.tolist(),
        # rotation felt that the vehicle did not make (metrics.false_rotation)
        "false_rotation": dataclasses.asdict(false_rotation(reference, outputs)),
        # how hard the cabin's motion changed between two periods (metrics.jolts)
        "jolts": dataclasses.asdict(jolts(outputs, time_step)),
        # what the occupant perceives (vestibular models), scored the same way
        "perceived": perceived.summary(),
        "step_time_s": None if offline else step_time_summary(step_times),
        "violations": usage.violations(),
        "joint_range_used": joint_range_used(states[:, :joints], robot).round(4).tolist(),
        "safety_interventions": int(statistics[n, 2]),
        "solver_failures": int(statistics[n, 1]),
        "realtime_factor": duration_s / max(wall_s, 1e-9),
        "wall_time_s": wall_s,
    }
    return summary, step_times


def run_closed_loop(
    *,
    mca: McaConfig | str,
    reference: Reference,
    plant: str = "analytical",
    duration_s: float | None = None,
    robot: SerialChain,
    station: StationConfig | None = None,
    meshcat=None,
    visualization=None,
    simulator_config: SimulatorConfig | None = None,
    random_seed: int | None = None,
    progress: bool = True,
    json_path: str | Path | None = None,
    plot_dir: str | Path | None = None,
    perception: PerceptionConfig | None = None,
    plausibility: PlausibilityConfig | None = None,
    comfort: ComfortConfig | None = None,
    scaling: ReferenceScaling | None = None,
) -> ClosedLoopResult:
    """Runs the closed loop of an MCA over `reference` on the analytical or multibody plant.

    Args:
        mca: an MCA config (`mca_drake.cueing`: DpcConfig, NmpcConfig, WashoutConfig) or the
            name of a default one (`mca_drake.cueing.MCA_NAMES`). A DpcConfig without a
            vehicle takes the reference's (`cueing.dpc.for_vehicle`), and with it the
            policy of that vehicle's envelope.
        reference: the target outputs; its time step is the control period.
        plant: "analytical" (the paper's joint-space plant) or "multibody" (the platform's
            MultibodyPlant station).
        duration_s: simulated time, s; default the whole reference.
        robot: the platform cued (`mca_drake.platforms.files.load_platform`).
        station: the station settings (multibody only; default StationConfig()).
        meshcat: a pydrake Meshcat to watch the run in (multibody only; None: none); the
            run is recorded into it for replay.
        visualization: Drake's VisualizationConfig of the Meshcat drawing (multibody only).
        simulator_config: Drake's SimulatorConfig (target_realtime_rate 1 for live use;
            default: as fast as possible).
        random_seed: seed of the diagram's random sources (the IMU noise); None keeps Drake's
            default seeds.
        json_path: optional result summary (JSON), written atomically.
        plot_dir: optional folder for `tracking.png` (Fig. 4), `perceived.png` and
            `joint_usage.png` (Fig. 5).
        perception: the vestibular model and thresholds of the summary's perceived figures
            (default PerceptionConfig()).
        plausibility: the reference guard in front of the MCA (`cueing.plausibility`;
            default PlausibilityConfig()); its counts are the summary's `plausibility`
            block (absent where `enabled` is false).
        scaling: the scaling the MCA cues at (`references.reference.ReferenceScaling`;
            default: the default scaling; `reference` is at the default scaling, and the run
            is scored against it); the summary's `scaling` block records it.
        comfort: the cabin comfort bound between the MCA and the robot (`mca_drake.comfort`;
            default none); where it acts, the summary's `comfort` block counts the periods
            it scaled and those over it.

    Raises:
        ValueError: an unknown plant or MCA, a bad duration, or settings the plant cannot
            take (Meshcat on the analytical plant, a control period that is not a whole
            number of plant steps).
    """
    if plant not in PLANTS:
        raise ValueError(f"unknown plant '{plant}'; valid: {', '.join(PLANTS)}")
    # Outputs are checked before the run, so that a long simulation is not lost at its end.
    if json_path:
        check_writable(json_path)
    if plot_dir:
        check_writable(plot_dir, folder=True)
    # The DPC runs the policy of the reference's vehicle where the config names none.
    config = for_vehicle(as_mca_config(mca), reference.vehicle)
    duration = checked_duration(reference, duration_s)
    if plant == "analytical":
        if meshcat is not None or station is not None or visualization is not None:
            raise ValueError("meshcat, visualization and station need plant 'multibody'")
        diagram, handles = MakeAnalyticalClosedLoop(
            reference, config, robot, plausibility, comfort, scaling
        )
    else:
        station = station if station is not None else StationConfig()
        diagram, handles = MakeMultibodyClosedLoop(
            reference,
            config,
            robot,
            station,
            meshcat=meshcat,
            visualization=visualization,
            plausibility=plausibility,
            comfort=comfort,
            scaling=scaling,
        )
    simulator = Simulator(diagram)
    if simulator_config is not None:
        ApplySimulatorConfig(simulator_config, simulator)
    context = simulator.get_mutable_context()
    if random_seed is not None:
        diagram.SetRandomContext(context, RandomGenerator(int(random_seed)))
    if plant == "multibody":
        handles["station"].SetInitialState(context)
    if meshcat is not None:
        meshcat.StartRecording(frames_per_second=30)
    simulator.Initialize()
    # One period past the end so that the sample after the last kept one is logged.
    wall_s = simulate_with_progress(simulator, duration + 1.5 * reference.time_step, progress)
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
    result = _collect_result(
        handles, context, config, plant, reference, duration, wall_s, robot, station, perception
    )
    if random_seed is not None:
        result.summary["random_seed"] = int(random_seed)
    result.summary["scaling"] = (scaling or ReferenceScaling()).record()
    guard = handles.get("guard")
    if guard is not None:
        result.summary["plausibility"] = guard.summary(guard.GetMyContextFromRoot(context))
    bound = handles.get("comfort_bound")
    if bound is not None:
        scaled = bound.bounded_periods(bound.GetMyContextFromRoot(context))
        result.summary["comfort"] = comfort_block(result.outputs, bound.config, scaled)
    if isinstance(config, DpcConfig):
        mca = handles["mca"]
        changes = mca.policy_changes(mca.GetMyContextFromRoot(context))
        result.summary |= policy_record(
            config, robot.name, changes, result.reference, reference.time_step
        )
    if json_path:
        atomic_write_json(json_path, result.summary)
    if plot_dir:
        from mca_drake.simulation.plots import write_closed_loop_plots  # matplotlib: only here

        write_closed_loop_plots(result, plot_dir, robot)
    return result


def _collect_result(
    handles: dict,
    context,
    config: McaConfig,
    plant: str,
    reference: Reference,
    duration: float,
    wall_s: float,
    robot: SerialChain,
    station: StationConfig | None,
    perception: PerceptionConfig | None = None,
) -> ClosedLoopResult:
    """The aligned signals and the summary of a finished run, from the diagram's logs."""
    h = reference.time_step

    def log(name):
        return handles[name].FindLog(context).data().T

    n = round(duration / h) + 1
    commands = log("command_log")[1 : n + 1]
    desired = None
    if plant == "analytical":
        states = log("state_log")[:n]
        check_alignment(states, commands, h)
        accelerations = commands
        joints = robot.num_joints
        outputs = plant_output(states[:, :joints], states[:, joints:], commands, robot)
    else:
        states, accelerations, outputs = station_signals(
            log("measured_state_log"), log("measured_output_log"), n, h
        )
        desired = log("desired_state_log")[:n]
    ref = log("reference_log")[:n]
    summary, step_times = closed_loop_summary(
        mca=mca_name(config),
        mca_config=mca_config_record(config),
        plant=plant,
        reference_name=reference.name,
        duration_s=duration,
        reference=ref,
        outputs=outputs,
        states=states,
        accelerations=accelerations,
        statistics=log("statistics_log"),
        wall_s=wall_s,
        robot=robot,
        time_step=h,
        perception=perception,
    )
    if plant == "multibody":
        summary |= _station_summary(handles, context, station, states, desired)
    return ClosedLoopResult(
        times=np.arange(n) * h,
        reference=ref,
        outputs=outputs,
        commands=commands,
        states=states,
        accelerations=accelerations,
        step_times_s=step_times,
        summary=summary,
        desired_states=desired,
        # the reaction port shows the step on the sample of t_n: logged at t_n
        reactions=log("reaction_log")[:n, 0] if "reaction_log" in handles else None,
    )


def _station_summary(
    handles: dict, context, station: StationConfig, states: np.ndarray, desired: np.ndarray
) -> dict:
    """The station's own figures: its step, joint tracking error (rad) and interventions."""
    joints = states.shape[1] // 2
    tracking_error = np.abs(states[:, :joints] - desired[:, :joints])
    limiter = handles["station"].limiter
    return {
        "plant_time_step_s": station.plant_time_step,
        "joint_tracking_error_rad": {
            "rms": float(np.sqrt(np.mean(tracking_error**2))),
            "max": float(tracking_error.max()),
        },
        "station": dataclasses.asdict(station),
        # Commands the station's limiter had to change: 0 when the MCA's own clamp held.
        "station_interventions": limiter.interventions(limiter.GetMyContextFromRoot(context)),
    }


def station_signals(
    measured_state: np.ndarray, measured_output: np.ndarray, n: int, h: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(states x_n (n, 2j), joint accelerations over each period (n, j), outputs y_n (n, 6))
    of the station of a j-joint platform from its logs at the control period (at least n + 1
    rows each): the MultibodyPlant's state and the head IMU without its delay, what the
    occupant felt. The IMU's accelerometer rows reflect the period before their sample, so y_n
    takes the angular rates of row n and the specific force of row n + 1."""
    outputs = np.concatenate([measured_output[:n, :3], measured_output[1 : n + 1, 3:]], axis=1)
    joints = measured_state.shape[1] // 2
    accelerations = (measured_state[1 : n + 1, joints:] - measured_state[:n, joints:]) / h
    return measured_state[:n], accelerations, outputs


def check_alignment(states: np.ndarray, commands: np.ndarray, h: float) -> None:
    """Raises RuntimeError unless x_(n+1) = step(x_n, u_n) on the analytical plant (the logs
    are aligned). states: (m, 2j); commands: (m - 1 or more, j), u_n in row n."""
    joints = states.shape[1] // 2
    q, qd = states[:-1, :joints], states[:-1, joints:]
    u = commands[: states.shape[0] - 1]
    step = np.concatenate([q + h * qd + 0.5 * h * h * u, qd + h * u], axis=1)
    if not np.allclose(step, states[1:], rtol=0, atol=_CONSISTENCY_TOL):
        raise RuntimeError("closed-loop logs are not aligned: x_(n+1) != step(x_n, u_n)")
