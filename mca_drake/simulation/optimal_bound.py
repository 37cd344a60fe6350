"""The offline-optimal bound of a reference, as a result like every closed loop's.

`run_optimal_bound` solves the whole-recording problem of `mca_drake.cueing.optimal` on the
analytical plant and returns a `ClosedLoopResult` with the same summary as every run (PI,
perceived block, limits, plots), `mca: optimal`, and a `solver` block (KKT residual,
iterations, time, where it started). It starts from the cheapest of the trajectories of
the causal MCAs it is given (`starts`, run here in closed loop) and of not moving: the
solver only descends, so the bound's tracking cost is never above theirs.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_json, check_writable
from mca_drake.cueing import as_mca_config, mca_name
from mca_drake.cueing.optimal import OptimalConfig, OptimalCueing
from mca_drake.perception.models import PerceptionConfig
from mca_drake.platforms.kinematics import plant_output
from mca_drake.platforms.serial import SerialChain
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import (
    ClosedLoopResult,
    checked_duration,
    closed_loop_summary,
    run_closed_loop,
)

# The causal MCAs whose closed-loop trajectories the bound may start from by default: the
# NMPC minimises the same objective causally, so its trajectory is the closest start.
DEFAULT_STARTS = ("nmpc-rti",)


def run_optimal_bound(
    *,
    reference: Reference,
    config: OptimalConfig | None = None,
    starts=DEFAULT_STARTS,
    duration_s: float | None = None,
    robot: SerialChain,
    progress: bool = True,
    json_path: str | Path | None = None,
    plot_dir: str | Path | None = None,
    perception: PerceptionConfig | None = None,
) -> ClosedLoopResult:
    """The offline-optimal bound of `reference` as a closed-loop result (`mca: optimal`).

    Args:
        reference: the target outputs; its time step is the control period.
        config: the bound's settings (default OptimalConfig(): the shipped NMPC's weights).
        starts: causal MCAs (configs or names) whose closed-loop trajectories on the
            analytical plant are candidate starts; the cheapest of them and of no motion is
            used. Empty: start from no motion.
        duration_s: the span of the reference to solve, s (default all of it).
        robot: the platform whose limits and kinematics bound the cue.
        progress: print each Gauss-Newton iteration's cost and KKT residual.
        json_path: optional result summary (JSON), written atomically.
        plot_dir: optional folder for `tracking.png`, `perceived.png`, `joint_usage.png`.
        perception: the vestibular model of the summary's perceived block.
    """
    if json_path:
        check_writable(json_path)
    if plot_dir:
        check_writable(plot_dir, folder=True)
    config = config or OptimalConfig(time_step=reference.time_step)
    if abs(config.time_step - reference.time_step) > 1e-12:
        raise ValueError(
            f"OptimalConfig.time_step {config.time_step} s differs from the reference's "
            f"{reference.time_step} s"
        )
    duration = checked_duration(reference, duration_s)
    n = min(round(duration / reference.time_step) + 1, reference.y.shape[0])
    target = np.asarray(reference.y[:n], dtype=float)
    ocp = OptimalCueing(n, config, robot)
    joints = robot.num_joints
    rest = np.zeros(2 * joints)
    candidates = {"no motion": np.zeros((n, joints))}
    for mca in starts:
        mca = as_mca_config(mca)
        causal = run_closed_loop(
            mca=mca, reference=reference, duration_s=duration, robot=robot, progress=False
        )
        candidates[mca_name(mca)] = causal.commands[:n]
    start_costs = {name: ocp.cost(rest, U, target) for name, U in candidates.items()}
    start = min(start_costs, key=start_costs.get)

    def report(iteration, cost, kkt, step):
        print(
            f"iteration {iteration}: cost {cost:.6g}, KKT residual {kkt:.2e}, step {step:g}",
            flush=True,
        )

    solution = ocp.solve(target, U_start=candidates[start], progress=report if progress else None)
    states = solution.states[:n]
    outputs = plant_output(states[:, :joints], states[:, joints:], solution.U, robot)
    summary, _ = closed_loop_summary(
        mca="optimal",
        mca_config={"type": "OptimalConfig", **dataclasses.asdict(config)},
        plant="analytical",
        reference_name=reference.name,
        duration_s=duration,
        reference=target,
        outputs=outputs,
        states=states,
        accelerations=solution.U,
        statistics=None,  # an offline solve: no control steps
        wall_s=solution.solve_time_s,
        robot=robot,
        time_step=reference.time_step,
        perception=perception,
    )
    summary |= {
        "solver": {
            "cost": solution.cost,
            "kkt_residual": solution.kkt_residual,
            "converged": solution.converged,
            "iterations": solution.iterations,
            "solve_time_s": solution.solve_time_s,
            "start": start,
            "start_costs": start_costs,
        },
    }
    result = ClosedLoopResult(
        times=np.arange(n) * reference.time_step,
        reference=target,
        outputs=outputs,
        commands=solution.U,
        states=states,
        accelerations=solution.U,
        step_times_s=np.zeros(0),
        summary=summary,
    )
    if json_path:
        atomic_write_json(json_path, summary)
    if plot_dir:
        from mca_drake.simulation.plots import write_closed_loop_plots  # matplotlib: only here

        write_closed_loop_plots(result, plot_dir, robot)
    return result
