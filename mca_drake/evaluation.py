"""Closed-loop evaluation of a motion cueing algorithm on the analytical plant.

`run_closed_loop` simulates ReferenceSource -> MCA -> MotionCueingPlant over a reference and
returns aligned signals (the reference r_n, state x_n, command u_n and output
y_n = y(x_n, u_n) at t_n = n h) with the result summary of ARCHITECTURE.md.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator

from mca_drake.atomic_io import atomic_write_json
from mca_drake.diagrams import MakeAnalyticalClosedLoop
from mca_drake.jobs import simulate_with_progress
from mca_drake.kinematics import plant_output
from mca_drake.metrics import joint_usage, tracking_score
from mca_drake.references.reference import Reference
from mca_drake.robot import KR500, NUM_JOINTS, load_kr500

# Tolerance of the timing self-check x_(n+1) = step(x_n, u_n).
_CONSISTENCY_TOL = 1e-9


@dataclasses.dataclass
class ClosedLoopResult:
    """Aligned closed-loop signals (T samples at t_n = n h) and the result summary."""

    times: np.ndarray  # (T,), s
    reference: np.ndarray  # (T, 6), r_n
    states: np.ndarray  # (T, 12), x_n = [q_n, qd_n]
    commands: np.ndarray  # (T, 6), u_n, rad/s^2
    outputs: np.ndarray  # (T, 6), y(x_n, u_n)
    step_times_s: np.ndarray  # (T,), MCA compute time per control step
    summary: dict


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
    plant: str,
    reference_name: str,
    duration_s: float,
    reference: np.ndarray,
    outputs: np.ndarray,
    states: np.ndarray,
    accelerations: np.ndarray,
    statistics: np.ndarray | None,
    wall_s: float,
    robot: KR500,
) -> tuple[dict, np.ndarray]:
    """The result summary of ARCHITECTURE.md for n aligned samples, and the MCA step times.

    Args:
        reference, outputs: r_n and y_n, shape (n, 6).
        states, accelerations: x_n (n, 12) and the joint accelerations over each step (n, 6).
        statistics: the MCA's `statistics` log (row k published at t_k, so row n holds the
            totals after n steps), or None for an MCA without statistics.
        wall_s: wall time of the simulation, s.
    """
    n = reference.shape[0]
    step_times = statistics[1 : n + 1, 0] if statistics is not None else np.array([])
    score = tracking_score(reference, outputs)
    usage = joint_usage(states[:, :NUM_JOINTS], states[:, NUM_JOINTS:], accelerations, robot)
    summary = {
        "mca": mca,
        "plant": plant,
        "reference": reference_name,
        "duration_s": duration_s,
        "pi": score.pi,
        "rmse": score.rmse.tolist(),
        "cc": score.cc.tolist(),
        "step_time_s": step_time_summary(step_times),
        "violations": usage.violations(),
        "safety_interventions": int(statistics[n, 2]) if statistics is not None else 0,
        "solver_failures": int(statistics[n, 1]) if statistics is not None else 0,
        "realtime_factor": duration_s / max(wall_s, 1e-9),
        "wall_time_s": wall_s,
    }
    return summary, step_times


def run_closed_loop(
    *,
    mca: str,
    reference: Reference,
    duration_s: float | None = None,
    robot: KR500 | None = None,
    progress: bool = True,
    json_path: str | Path | None = None,
    plot_path: str | Path | None = None,
    policy: str | Path | None = None,
) -> ClosedLoopResult:
    """Runs the closed loop of `mca` on the analytical plant over `reference`.

    Args:
        mca: an MCA name (`mca_drake.diagrams.MCA_NAMES`).
        reference: the target outputs (its time step is the control period).
        duration_s: simulated time, default the whole reference.
        json_path, plot_path: optional result summary (JSON) and target-vs-achieved PNG.
        policy: the policy file of mca "dpc" (default: the one shipped with the package).
    """
    robot = robot if robot is not None else load_kr500()
    h = reference.time_step
    duration = checked_duration(reference, duration_s)
    diagram, handles = MakeAnalyticalClosedLoop(reference, mca, robot, h, policy)
    simulator = Simulator(diagram)
    simulator.Initialize()
    # One period past the end so that the command of the last kept sample is logged.
    wall_s = simulate_with_progress(simulator, duration + 1.5 * h, progress)
    context = simulator.get_context()

    def log(name):
        return handles[name].FindLog(context).data().T

    n = round(duration / h) + 1
    states, commands = log("state_log")[:n], log("command_log")[1 : n + 1]
    ref = log("reference_log")[:n]
    step = np.concatenate(
        [
            states[:-1, :NUM_JOINTS] + h * states[:-1, NUM_JOINTS:] + 0.5 * h * h * commands[:-1],
            states[:-1, NUM_JOINTS:] + h * commands[:-1],
        ],
        axis=1,
    )
    if not np.allclose(step, states[1:], rtol=0, atol=_CONSISTENCY_TOL):
        raise RuntimeError("closed-loop logs are not aligned: x_(n+1) != step(x_n, u_n)")
    outputs = plant_output(states[:, :NUM_JOINTS], states[:, NUM_JOINTS:], commands, robot)
    statistics = log("statistics_log") if "statistics_log" in handles else None
    summary, step_times = closed_loop_summary(
        mca=mca,
        plant="analytical",
        reference_name=reference.name,
        duration_s=duration,
        reference=ref,
        outputs=outputs,
        states=states,
        accelerations=commands,
        statistics=statistics,
        wall_s=wall_s,
        robot=robot,
    )
    result = ClosedLoopResult(np.arange(n) * h, ref, states, commands, outputs, step_times, summary)
    if json_path:
        atomic_write_json(json_path, summary)
    if plot_path:
        from mca_drake.plotting import plot_outputs, save_figure

        title = f"{mca} on the analytical plant: PI {summary['pi']:.3f}"
        save_figure(plot_outputs(result.times, outputs, ref, title=title), plot_path)
    return result
