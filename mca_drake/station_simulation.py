"""Closed-loop motion cueing on the physical KR500 model (the paper's last experiment).

`run_station_closed_loop` simulates ReferenceSource -> MCA -> KR500 station (MultibodyPlant
at 1 kHz, inverse-dynamics control, head IMU) and returns aligned 100 Hz signals with the
result summary of ARCHITECTURE.md (plant "multibody").

Alignment with the analytical plant's convention y_n = y(x_n, u_n): the angular velocity
of sample n is the gyroscope at t_n; the specific force and vertical acceleration are the
accelerometer at t_(n+1), whose plant step is the first that carries the command u_n
(the command reaches the robot one plant step after it is computed).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator

from mca_drake.atomic_io import atomic_write_json
from mca_drake.diagrams import MakeMultibodyClosedLoop
from mca_drake.evaluation import checked_duration, closed_loop_summary
from mca_drake.jobs import simulate_with_progress
from mca_drake.metrics import joint_usage
from mca_drake.references.reference import Reference
from mca_drake.robot import KR500, NUM_JOINTS, load_kr500
from mca_drake.systems.kr500_station import StationConfig


@dataclasses.dataclass
class StationResult:
    """Aligned closed-loop signals on the KR500 station (T samples at t_n = n h)."""

    times: np.ndarray  # (T,), s
    reference: np.ndarray  # (T, 6), r_n
    outputs: np.ndarray  # (T, 6), measured y_n (head IMU)
    commands: np.ndarray  # (T, 6), u_n, the MCA's joint accelerations, rad/s^2
    desired_states: np.ndarray  # (T, 12), [q_d, qd_d] the controller tracks at t_n
    states: np.ndarray  # (T, 12), measured [q, qd] at t_n
    accelerations: np.ndarray  # (T, 6), measured mean joint acceleration over [t_n, t_n+1)
    step_times_s: np.ndarray  # (T,), MCA compute time per control step
    summary: dict


def run_station_closed_loop(
    *,
    mca: str,
    reference: Reference,
    duration_s: float | None = None,
    robot: KR500 | None = None,
    station: StationConfig | None = None,
    policy: str | Path | None = None,
    meshcat=None,
    realtime_rate: float = 0.0,
    progress: bool = True,
    json_path: str | Path | None = None,
    plot_dir: str | Path | None = None,
) -> StationResult:
    """Runs `mca` in closed loop with the KR500 station over `reference`.

    Args:
        mca: an MCA name (`mca_drake.diagrams.MCA_NAMES`).
        reference: the target outputs (its time step is the control period).
        duration_s: simulated time, default the whole reference.
        station: the station settings (plant step, gains, torque limits, noise, delay).
        policy: the policy file of "dpc" (default: the one shipped with the package).
        meshcat: a pydrake Meshcat to watch the run in (None: none).
        realtime_rate: target simulated/wall rate (1 for live use; 0: as fast as possible).
        json_path: optional result summary (JSON).
        plot_dir: optional folder for `tracking.png` (Fig. 4) and `joint_usage.png` (Fig. 5).
    """
    robot = robot if robot is not None else load_kr500()
    station = station if station is not None else StationConfig()
    h = reference.time_step
    duration = checked_duration(reference, duration_s)
    ratio = h / station.plant_time_step
    if abs(ratio - round(ratio)) > 1e-9:
        raise ValueError(
            f"the control period {h} s must be a whole number of plant steps "
            f"({station.plant_time_step} s)"
        )
    if not (np.isfinite(realtime_rate) and realtime_rate >= 0):
        raise ValueError(f"realtime_rate must be >= 0; got {realtime_rate}")
    diagram, handles = MakeMultibodyClosedLoop(
        reference, mca, robot, h, policy, station=station, meshcat=meshcat
    )
    simulator = Simulator(diagram)
    handles["station"].SetInitialState(simulator.get_mutable_context())
    simulator.set_target_realtime_rate(realtime_rate)
    if meshcat is not None:
        meshcat.StartRecording(frames_per_second=30)
    simulator.Initialize()
    # One period past the end so that the sample after the last kept one is logged.
    wall_s = simulate_with_progress(simulator, duration + 1.5 * h, progress)
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
    context = simulator.get_context()

    def log(name):
        return handles[name].FindLog(context).data().T

    n = round(duration / h) + 1
    measured_y = log("measured_output_log")
    outputs = np.concatenate([measured_y[:n, :3], measured_y[1 : n + 1, 3:]], axis=1)
    states = log("measured_state_log")
    accelerations = (states[1 : n + 1, NUM_JOINTS:] - states[:n, NUM_JOINTS:]) / h
    states = states[:n]
    desired = log("desired_state_log")[:n]
    commands = log("command_log")[1 : n + 1]
    ref = log("reference_log")[:n]
    statistics = log("statistics_log") if "statistics_log" in handles else None
    summary, step_times = closed_loop_summary(
        mca=mca,
        plant="multibody",
        reference_name=reference.name,
        duration_s=duration,
        reference=ref,
        outputs=outputs,
        states=states,
        accelerations=accelerations,
        statistics=statistics,
        wall_s=wall_s,
        robot=robot,
    )
    tracking_error = np.abs(states[:, :NUM_JOINTS] - desired[:, :NUM_JOINTS])
    summary["plant_time_step_s"] = station.plant_time_step
    summary["joint_tracking_error_rad"] = {
        "rms": float(np.sqrt(np.mean(tracking_error**2))),
        "max": float(tracking_error.max()),
    }
    summary["station"] = dataclasses.asdict(station)
    result = StationResult(
        np.arange(n) * h,
        ref,
        outputs,
        commands,
        desired,
        states,
        accelerations,
        step_times,
        summary,
    )
    if json_path:
        atomic_write_json(json_path, summary)
    if plot_dir:
        write_station_plots(result, plot_dir, robot)
    return result


def write_station_plots(result, folder: str | Path, robot: KR500 | None = None):
    """Writes `tracking.png` (target vs measured per channel, RMSE and CC in the titles:
    the paper's Fig. 4) and `joint_usage.png` (normalised joint positions, velocities and
    accelerations as strip charts: Fig. 5) into `folder`; returns their paths.

    `result`: a StationResult or an analytical-plant `ClosedLoopResult` (whose joint
    accelerations are its commands)."""
    from mca_drake.plotting import plot_joint_usage, plot_tracking, save_figure

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    s = result.summary
    plant = "KR500 MultibodyPlant" if s["plant"] == "multibody" else "analytical plant"
    title = f"{s['mca']} on the {plant}: PI {s['pi']:.3f}"
    accelerations = getattr(result, "accelerations", None)
    accelerations = result.commands if accelerations is None else accelerations
    tracking = folder / "tracking.png"
    save_figure(plot_tracking(result.times, result.reference, result.outputs, title), tracking)
    usage = joint_usage(
        result.states[:, :NUM_JOINTS],
        result.states[:, NUM_JOINTS:],
        accelerations,
        robot,
    )
    usage_path = folder / "joint_usage.png"
    save_figure(plot_joint_usage(usage, title=f"{s['mca']}: normalised joint usage"), usage_path)
    return tracking, usage_path
