"""Runnable jobs: keyword-only functions that build a diagram, simulate it and summarise.

The CLI is a thin shell over these; notebooks and scripts call them directly.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, MeshcatParams
from pydrake.systems.analysis import Simulator

from mca_drake.app.scenarios import (
    ClosedLoopScenario,
    DatasetScenario,
    EvaluationScenario,
    LiveScenario,
    PlantDemoScenario,
    Scenario,
)
from mca_drake.atomic_io import atomic_write_json, check_writable
from mca_drake.conventions import CHANNELS
from mca_drake.cueing import mca_config_record, mca_name, on_platform
from mca_drake.platforms.files import load_platform, packaged_name
from mca_drake.platforms.usage import joint_usage
from mca_drake.plotting import plot_outputs, save_figure
from mca_drake.references.drives import motion_reference
from mca_drake.segments import SegmentDataset
from mca_drake.simulation.builders import MakePlantDemoDiagram
from mca_drake.simulation.closed_loop import (
    ClosedLoopResult,
    run_closed_loop,
    simulate_with_progress,
)
from mca_drake.simulation.trajectory import write_trajectory
from mca_drake.studies.closed_loop_dataset import generate_closed_loop_dataset
from mca_drake.studies.evaluation import run_evaluation


@dataclasses.dataclass
class PlantDemoResult:
    """Logged signals of the plant demo (T samples at the control period)."""

    times: np.ndarray  # (T,), s
    outputs: np.ndarray  # (T, 6), y
    states: np.ndarray  # (T, 12), [q, qd]
    accelerations: np.ndarray  # (T, 6), qdd
    summary: dict  # the result summary (README, "Result summary")


def run_plant_demo(
    *,
    scenario: PlantDemoScenario,
    json_path: str | Path | None = None,
    plot_path: str | Path | None = None,
    progress: bool = True,
) -> PlantDemoResult:
    """Simulates the analytical plant on the demo motion; optionally writes JSON and a plot."""
    scenario.validate()
    robot = load_platform(scenario.platform)
    diagram, handles = MakePlantDemoDiagram(
        duration_s=scenario.duration_s, time_step=scenario.time_step, robot=robot
    )
    simulator = Simulator(diagram)
    simulator.Initialize()
    wall_s = simulate_with_progress(simulator, scenario.duration_s, progress)
    context = simulator.get_context()
    out = handles["output_log"].FindLog(context)
    states = handles["state_log"].FindLog(context).data().T
    accelerations = handles["input_log"].FindLog(context).data().T
    outputs = out.data().T
    n = robot.num_joints
    usage = joint_usage(states[:, :n], states[:, n:], accelerations, robot)
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
        save_figure(
            plot_outputs(out.sample_times(), outputs, title="Analytical plant, demo joint motion"),
            plot_path,
        )
    return PlantDemoResult(out.sample_times(), outputs, states, accelerations, summary)


def start_meshcat() -> Meshcat:
    """A Meshcat server that listens on localhost only (Drake's default is every
    interface), its address printed."""
    meshcat = Meshcat(MeshcatParams(host="localhost"))
    print(f"Meshcat: open {meshcat.web_url()} in a browser")
    return meshcat


def closed_loop_outputs(
    scenario: ClosedLoopScenario,
    json_path: str | Path | None = None,
    plot_dir: str | Path | None = None,
) -> tuple[Path | None, Path | None]:
    """Where a closed-loop scenario writes its summary and its plots: `json_path` and
    `plot_dir` when given ("" for none), else `output_dir/summary.json` and `output_dir`."""
    out = Path(scenario.output_dir)
    json_path = out / "summary.json" if json_path is None else json_path or None
    plot_dir = out if plot_dir is None else plot_dir or None
    return (Path(json_path) if json_path else None, Path(plot_dir) if plot_dir else None)


def run_closed_loop_scenario(
    scenario: ClosedLoopScenario,
    *,
    progress: bool = True,
    meshcat=None,
    json_path: str | Path | None = None,
    plot_dir: str | Path | None = None,
) -> ClosedLoopResult:
    """Runs a ClosedLoopScenario on its plant (KR500 station or analytical plant).

    Args:
        meshcat: a Meshcat to draw in (default: one is started when the scenario has a
            `visualization`).
        json_path: the result summary (default `output_dir/summary.json`; "" for none).
        plot_dir: folder of tracking.png, perceived.png and joint_usage.png (default
            `output_dir`; "" for none).

    The scenario's `trajectory` (a CSV path) gets the run's time series
    (`simulation.trajectory`).
    """
    scenario.validate()
    json_path, plot_dir = closed_loop_outputs(scenario, json_path, plot_dir)
    if json_path:  # before the flight is flown: a long run is not lost at its end
        check_writable(json_path)
    if plot_dir:
        check_writable(plot_dir, folder=True)
    if scenario.trajectory:
        check_writable(scenario.trajectory)
    reference = motion_reference(scenario.flight, scenario.duration_s)
    multibody = scenario.plant == "multibody"
    if multibody and scenario.visualization is not None and meshcat is None:
        meshcat = start_meshcat()
    robot = load_platform(scenario.platform)
    result = run_closed_loop(
        mca=on_platform(scenario.mca, packaged_name(scenario.platform)),
        reference=reference,
        plant=scenario.plant,
        robot=robot,
        duration_s=min(scenario.duration_s, reference.duration_s),
        station=scenario.station if multibody else None,
        meshcat=meshcat if multibody else None,
        visualization=scenario.visualization,
        simulator_config=scenario.simulator_config,
        random_seed=scenario.random_seed,
        progress=progress,
        json_path=json_path,
        plot_dir=plot_dir,
        perception=scenario.perception,
        plausibility=scenario.plausibility,
        comfort=scenario.comfort,
        scaling=scenario.scaling,
    )
    if scenario.trajectory:
        write_trajectory(scenario.trajectory, result, robot)
    return result


def run_scenario(
    scenario: Scenario, *, progress: bool = True, json_path: str | Path | None = None
) -> dict:
    """Runs any scenario of a diagrams/*.yaml file; returns its result summary (a dict),
    also written to `json_path` when given."""
    if isinstance(scenario, PlantDemoScenario):
        summary = run_plant_demo(scenario=scenario, progress=progress).summary
    elif isinstance(scenario, ClosedLoopScenario):
        summary = run_closed_loop_scenario(scenario, progress=progress).summary
    elif isinstance(scenario, EvaluationScenario):
        scenario.validate()
        report = run_evaluation(
            scenario.to_config(),
            scenario.output_dir,
            workers=scenario.workers,
            address=scenario.address or None,
            progress=progress,
        )
        summary = {"report": str(Path(scenario.output_dir) / "evaluation.md")} | {
            k: v for k, v in report.items() if k != "runs"
        }
    elif isinstance(scenario, DatasetScenario):
        scenario.validate()
        path = generate_closed_loop_dataset(
            scenario.to_config(),
            scenario.output_dir,
            workers=scenario.workers,
            progress=progress,
            address=scenario.address or None,
        )
        data = SegmentDataset.load(path)
        summary = {
            "dataset": str(path),
            "segments": len(data),
            "horizon": data.horizon,
            "mca": mca_name(scenario.mca),
            "mca_config": mca_config_record(scenario.mca),
        }
    elif isinstance(scenario, LiveScenario):
        summary = run_live_scenario(scenario, on_listening=_print_listening)
    else:
        raise TypeError(f"not a scenario: {type(scenario).__name__}")
    if json_path:
        atomic_write_json(json_path, summary)
    return summary


def _print_listening(address) -> None:
    print(f"listening on udp://{address[0]}:{address[1]}", flush=True)


def run_live_scenario(
    scenario: LiveScenario, *, on_listening=None, meshcat=None, keyboard_fd: int | None = None
) -> dict:
    """Runs a LiveScenario: cues the telemetry arriving on its port in real time (and
    drives its robot over RSI, if it has one); returns the summary with its live block,
    also written to `output_json` unless that is "".

    Args:
        on_listening: called with the bound (host, port) once the socket listens (the CLI
            prints `listening on udp://HOST:PORT`; the demo starts its sender).
        meshcat: a Meshcat to draw the station in (plant multibody), with the operator page.
        keyboard_fd: a terminal whose keys control the run (the CLI's stdin), when the
            scenario's controls allow the keyboard.
    """
    # the live layer (sockets, the live diagram, the RSI driver) only for live jobs
    from mca_drake.live.loop import make_decoder, run_live
    from mca_drake.live.receiver import ReceiverConfig
    from mca_drake.live.rsi.link import parse_robot_url

    scenario.validate()
    if scenario.output_json:
        check_writable(scenario.output_json)
    if scenario.trajectory:
        check_writable(scenario.trajectory)
    decoder = make_decoder(
        scenario.protocol,
        xplane_version=scenario.xplane_version or None,
        fgnetfdm_time_resolution_s=scenario.fgnetfdm_time_resolution_s or None,
        beamng=scenario.beamng,
        outsim=scenario.outsim,
        f1=scenario.f1,
    )
    rsi = None
    if scenario.robot:
        host, port = parse_robot_url(scenario.robot)
        motion = dataclasses.replace(scenario.rsi.motion, cycle_s=scenario.rsi_cycle_ms * 1e-3)
        rsi = dataclasses.replace(scenario.rsi, host=host, port=port, motion=motion)
    summary = run_live(
        decoder,
        on_platform(scenario.mca, packaged_name(scenario.platform)),
        scenario.duration_s,
        robot=load_platform(scenario.platform),
        receiver=ReceiverConfig(
            host=scenario.host, port=scenario.port, allowed_senders=scenario.allowed_senders
        ),
        realtime_rate=scenario.realtime_rate,
        on_listening=on_listening,
        plant=scenario.plant,
        meshcat=meshcat,
        rsi=rsi,
        plausibility=scenario.plausibility,
        scaling=scenario.scaling,
        comfort=scenario.comfort,
        trajectory=scenario.trajectory or None,
        controls=scenario.controls,
        keyboard_fd=keyboard_fd,
        rig=scenario.rig,
        pose_stream=scenario.pose_stream,
    )
    if scenario.output_json:
        atomic_write_json(scenario.output_json, summary)
    return summary
