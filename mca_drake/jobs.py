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
from mca_drake.diagrams import MakePlantDemoDiagram, PlantDemoScenario
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
