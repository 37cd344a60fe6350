"""Runnable jobs: keyword-only functions that build a diagram, simulate it and summarise.

The CLI is a thin shell over these; notebooks and scripts call them directly.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator
from tqdm.auto import tqdm

from mca_drake.atomic_io import atomic_write_json
from mca_drake.diagrams import (
    ClosedLoopScenario,
    DatasetScenario,
    EvaluationScenario,
    FlightSpec,
    MakePlantDemoDiagram,
    PlantDemoScenario,
)
from mca_drake.metrics import CHANNELS, joint_usage
from mca_drake.robot import NUM_JOINTS


@dataclasses.dataclass
class PlantDemoResult:
    """Logged signals of the plant demo (T samples at the control period)."""

    times: np.ndarray  # (T,), s
    outputs: np.ndarray  # (T, 6), y
    states: np.ndarray  # (T, 12), [q, qd]
    accelerations: np.ndarray  # (T, 6), qdd
    summary: dict  # the result summary (see `summary` keys in ARCHITECTURE.md)


def simulate_with_progress(simulator: Simulator, duration_s: float, progress: bool) -> float:
    """Advances `simulator` to `duration_s` in chunks with a progress bar; returns wall s."""
    start = time.perf_counter()
    t0 = simulator.get_context().get_time()
    chunk = max(duration_s / 100, 0.1)
    with tqdm(total=round(duration_s, 3), unit="sim s", disable=not progress, leave=False) as bar:
        t = t0
        while t < t0 + duration_s - 1e-9:
            t_next = min(t + chunk, t0 + duration_s)
            simulator.AdvanceTo(t_next)
            bar.update(round(t_next - t, 3))
            t = t_next
    return time.perf_counter() - start


def run_plant_demo(
    *,
    scenario: PlantDemoScenario,
    json_path: str | Path | None = None,
    plot_path: str | Path | None = None,
    progress: bool = True,
) -> PlantDemoResult:
    """Simulates the analytical plant on the demo motion; optionally writes JSON and a plot."""
    diagram, handles = MakePlantDemoDiagram(scenario)
    simulator = Simulator(diagram)
    simulator.Initialize()
    wall_s = simulate_with_progress(simulator, scenario.duration_s, progress)
    context = simulator.get_context()
    out = handles["output_log"].FindLog(context)
    states = handles["state_log"].FindLog(context).data().T
    accelerations = handles["input_log"].FindLog(context).data().T
    outputs = out.data().T
    usage = joint_usage(states[:, :NUM_JOINTS], states[:, NUM_JOINTS:], accelerations)
    summary = {
        "mca": "none",
        "plant": "analytical",
        "reference": "demo joint motion",
        "duration_s": scenario.duration_s,
        "output_peak": {
            c: float(v) for c, v in zip(CHANNELS, np.abs(outputs).max(axis=0), strict=True)
        },
        "output_rms": {
            c: float(v) for c, v in zip(CHANNELS, np.sqrt((outputs**2).mean(axis=0)), strict=True)
        },
        "violations": usage.violations(),
        "limit_usage_peak": {k: v.round(4).tolist() for k, v in usage.peak().items()},
        "realtime_factor": scenario.duration_s / max(wall_s, 1e-9),
    }
    if json_path:
        atomic_write_json(json_path, summary)
    if plot_path:
        from mca_drake.plotting import plot_outputs, save_figure

        save_figure(
            plot_outputs(out.sample_times(), outputs, title="Analytical plant, demo joint motion"),
            plot_path,
        )
    return PlantDemoResult(out.sample_times(), outputs, states, accelerations, summary)


def flight_reference(flight: FlightSpec, duration_s: float, progress: bool = False):
    """The motion-cueing reference of `flight`: its recording, or the built-in JSBSim flight
    of `duration_s` seconds (deterministic for its seed)."""
    from mca_drake.references.reference import reference_from_recording

    if flight.recording:
        from mca_drake.references.recording import load_recording

        return reference_from_recording(load_recording(flight.recording), name=flight.recording)
    from mca_drake.references.jsbsim_flight import fly

    recording = fly(flight.vehicle, duration_s, flight.seed, progress=progress)
    return reference_from_recording(
        recording, name=f"built-in {flight.vehicle} flight, seed {flight.seed}"
    )


def run_closed_loop_scenario(
    scenario: ClosedLoopScenario,
    *,
    progress: bool = True,
    meshcat=None,
    json_path: str | Path | None = None,
    plot_dir: str | Path | None = None,
):
    """Runs a ClosedLoopScenario on its plant (KR500 station or analytical plant).

    Args:
        meshcat: a Meshcat to draw in (default: one is started when `scenario.meshcat`).
        json_path: the result summary (default `output_dir/summary.json`; "" for none).
        plot_dir: folder of tracking.png and joint_usage.png (default `output_dir`; "" for
            none).

    Returns:
        The StationResult (multibody plant) or ClosedLoopResult (analytical plant).
    """
    scenario.validate()
    reference = flight_reference(scenario.flight, scenario.duration_s)
    duration = min(scenario.duration_s, reference.duration_s)
    out = Path(scenario.output_dir)
    json_path = out / "summary.json" if json_path is None else json_path or None
    plot_dir = out if plot_dir is None else plot_dir or None
    policy = scenario.policy or None
    if scenario.plant == "multibody":
        from mca_drake.station_simulation import run_station_closed_loop

        if scenario.meshcat and meshcat is None:
            from pydrake.geometry import StartMeshcat

            meshcat = StartMeshcat()
            print(f"Meshcat: open {meshcat.web_url()} in a browser")
        return run_station_closed_loop(
            mca=scenario.mca,
            reference=reference,
            duration_s=duration,
            station=scenario.station,
            policy=policy,
            meshcat=meshcat,
            realtime_rate=scenario.realtime_rate,
            progress=progress,
            json_path=json_path,
            plot_dir=plot_dir,
        )
    from mca_drake.evaluation import run_closed_loop
    from mca_drake.station_simulation import write_station_plots

    result = run_closed_loop(
        mca=scenario.mca,
        reference=reference,
        duration_s=duration,
        progress=progress,
        json_path=json_path,
        policy=policy,
    )
    if plot_dir:
        write_station_plots(result, plot_dir)
    return result


def run_scenario(scenario, *, progress: bool = True, json_path: str | Path | None = None):
    """Runs any scenario of a diagrams/*.yaml file; returns its result summary (a dict),
    also written to `json_path` when given."""
    if isinstance(scenario, PlantDemoScenario):
        summary = run_plant_demo(scenario=scenario, progress=progress).summary
    elif isinstance(scenario, ClosedLoopScenario):
        summary = run_closed_loop_scenario(scenario, progress=progress).summary
    elif isinstance(scenario, EvaluationScenario):
        from mca_drake.scenario_evaluation import run_evaluation

        scenario.validate()
        report = run_evaluation(
            scenario.to_config(), scenario.output_dir, workers=scenario.workers, progress=progress
        )
        summary = {"report": str(Path(scenario.output_dir) / "evaluation.md")} | {
            k: v for k, v in report.items() if k != "runs"
        }
    elif isinstance(scenario, DatasetScenario):
        from mca_drake.closed_loop_dataset import generate_closed_loop_dataset

        scenario.validate()
        path = generate_closed_loop_dataset(
            scenario.to_config(), scenario.output_dir, workers=scenario.workers, progress=progress
        )
        from mca_drake.segments import SegmentDataset

        data = SegmentDataset.load(path)
        summary = {"dataset": str(path), "segments": len(data), "horizon": data.horizon}
    else:
        raise TypeError(f"not a scenario: {type(scenario).__name__}")
    if json_path:
        atomic_write_json(json_path, summary)
    return summary
