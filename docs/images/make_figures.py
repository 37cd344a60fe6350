"""The documentation's figures, made by the code that the pages describe.

    .venv/bin/python docs/images/make_figures.py [--only NAME,...]

writes every figure of this folder (about ten minutes on two cores, most of it the quick
training; `--only platforms` one group), and `meshcat_replay.html`, a Meshcat recording.
The platforms are rendered by Drake (RenderEngineVtk, the geometry Meshcat draws) with the
frames and legs drawn over them; the runs are the package's own plots of short runs; the
diagrams are laid out from the Drake diagrams the runs build (their systems and
connections, loggers left out). The figures are committed: the site's build does not run
simulations. Flights here are evaluation seeds (1000 on), never trained or tuned on.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from mca_drake.plotting import save_figure  # noqa: E402

# The flight of the run figures: the main job's (an evaluation flight), cut short.
FLIGHT_SECONDS = 40.0


# -- platforms -------------------------------------------------------------------------


def _look_at(eye, target):
    """X_WC of a camera at `eye` looking at `target` (Drake's camera: x right, y down, z
    along the view), the world's z up."""
    from pydrake.math import RigidTransform, RotationMatrix

    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return RigidTransform(RotationMatrix(np.column_stack([x, np.cross(z, x), z])), eye)


def render_platform(robot, q, eye, target, size=(720, 540)):
    """(image (h, w, 3), project): Drake's VTK rendering of the platform's station at
    coordinates q, seen from `eye`; project maps world points (..., 3) to pixels (..., 2)."""
    from pydrake.common.schema import Transform
    from pydrake.geometry import MakeRenderEngineVtk, RenderEngineVtkParams
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.sensors import ApplyCameraConfig, CameraConfig

    from mca_drake.systems.station import AddStation

    builder = DiagramBuilder()
    n = robot.num_joints
    station = AddStation(builder, robot, initial_state=np.r_[q, np.zeros(n)], with_geometry=True)
    station.scene_graph.AddRenderer(
        "vtk", MakeRenderEngineVtk(RenderEngineVtkParams(default_clear_color=[1.0, 1.0, 1.0]))
    )
    X_WC = _look_at(eye, target)
    camera = CameraConfig(width=size[0], height=size[1], renderer_name="vtk")
    camera.X_PB = Transform(X_WC)
    ApplyCameraConfig(config=camera, builder=builder)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    station.SetInitialState(context)
    sensor = next(s for s in diagram.GetSystems() if s.HasOutputPort("color_image"))
    image = sensor.GetOutputPort("color_image").Eval(sensor.GetMyContextFromRoot(context))
    fov_y = np.radians(camera.focal.y)
    focal = 0.5 * size[1] / np.tan(0.5 * fov_y)
    X_CW = X_WC.inverse()

    def project(points):
        p = X_CW.multiply(np.asarray(points, float).reshape(-1, 3).T).T
        pixels = focal * p[:, :2] / p[:, 2:] + 0.5 * np.array(size)
        return pixels.reshape(*np.shape(points)[:-1], 2)

    return np.asarray(image.data)[..., :3], project


def _triad(ax, project, X, label, length):
    """The frame X (4, 4) drawn as x (red), y (green), z (blue) arrows with its label."""
    origin = X[:3, 3]
    o = project(origin)
    for axis, colour in zip(range(3), ("#d62728", "#2ca02c", "#1f77b4"), strict=True):
        tip = project(origin + length * X[:3, axis])
        ax.annotate(
            "", tip, o, arrowprops=dict(arrowstyle="-|>", color=colour, lw=2.2, mutation_scale=14)
        )
        ax.text(*tip, "xyz"[axis], color=colour, fontsize=10, fontweight="bold")
    ax.text(o[0] - 14, o[1] + 18, label, fontsize=12, fontweight="bold")


def platform_figure(name, eye, target, q=None, axis_length=0.8, title=""):
    """The platform at home (or q): Drake's render, the world frame W and head frame H;
    a legged platform's legs drawn between their joints."""
    from mca_drake.platforms.files import load_platform
    from mca_drake.platforms.kinematics import head_pose
    from mca_drake.platforms.leg_platform import LegPlatform
    from mca_drake.systems.meshcat_legs import leg_segments

    robot = load_platform(name)
    q = robot.home if q is None else np.asarray(q, float)
    image, project = render_platform(robot, q, eye, target)
    fig, ax = plt.subplots(figsize=(7.2, 5.4))
    ax.imshow(image)
    if isinstance(robot, LegPlatform):
        for leg in leg_segments(robot, q):
            pixels = project(leg)
            ax.plot(pixels[:, 0], pixels[:, 1], color="#444444", lw=3, solid_capstyle="round")
    _triad(ax, project, np.eye(4), "W", axis_length)
    _triad(ax, project, head_pose(q, robot), "H", 0.6 * axis_length)
    ax.set_axis_off()
    ax.set_title(title or name)
    fig.tight_layout()
    return fig


def make_platforms(out: Path) -> None:
    save_figure(
        platform_figure(
            "kr500",
            eye=[5.0, -5.4, 3.3],
            target=[1.6, 0.0, 1.5],
            title="KR500 and cabin at home: world frame W, head frame H",
        ),
        out / "platform_kr500.png",
    )
    save_figure(
        platform_figure(
            "kr500-rail",
            eye=[7.5, -3.0, 4.5],
            target=[1.5, 1.5, 1.2],
            q=[2.0, 0.4, -0.2, 0.3, 0.3, 0.2, -0.3],
            title="KR500 on its rail (rail at +2 m)",
        ),
        out / "platform_kr500_rail.png",
    )
    save_figure(
        platform_figure(
            "hexapod",
            eye=[3.2, -3.0, 2.4],
            target=[0.0, 0.0, 0.9],
            q=[0.1, 0.0, 0.05, 0.0, -0.12, 0.1],
            axis_length=0.5,
            title="hexapod, surged, pitched and rolled: its six legs",
        ),
        out / "platform_hexapod.png",
    )
    save_figure(
        platform_figure(
            "rig-3dof",
            eye=[1.9, -1.7, 1.45],
            target=[0.0, 0.0, 0.5],
            q=[0.03, -0.1, 0.12],
            axis_length=0.4,
            title="3-DOF rig, pitched and rolled: its three actuators",
        ),
        out / "platform_rig_3dof.png",
    )


# -- runs ------------------------------------------------------------------------------


def _flight(seconds=FLIGHT_SECONDS, vehicle="light", seed=1000):
    from mca_drake.references.flights import FlightSpec, flight_reference

    return flight_reference(FlightSpec(vehicle=vehicle, seed=seed), seconds)


def _finish(fig, axes, title: str, path: Path, **legend) -> None:
    """A figure of stacked panels over time: legend and title on the first, the time axis on
    the last; saved to `path`."""
    axes[0].legend(fontsize=8, **legend)
    axes[0].set_title(title)
    axes[-1].set_xlabel("t, s")
    fig.tight_layout()
    save_figure(fig, path)


def make_runs(out: Path) -> None:
    """The main job's three plots (a 40 s cut of its flight, analytical plant), and the
    three MCAs on the same flight side by side."""
    from mca_drake.platforms.files import load_platform
    from mca_drake.simulation.closed_loop import run_closed_loop
    from mca_drake.simulation.plots import write_closed_loop_plots

    robot = load_platform("kr500")
    reference = _flight()
    results = {}
    for mca in ("dpc", "nmpc-rti", "washout"):
        results[mca] = run_closed_loop(
            mca=mca, reference=reference, robot=robot, plant="analytical", progress=False
        )
    with tempfile.TemporaryDirectory() as tmp:
        paths = write_closed_loop_plots(results["dpc"], tmp, robot)
        for path in paths:
            shutil.copy(path, out / f"run_{path.name}")
    fig, axes = plt.subplots(2, 1, figsize=(8.0, 5.0), sharex=True)
    times = results["dpc"].times
    for ax, channel, unit in zip(axes, (3, 1), ("f_x, m/s²", "w_y, rad/s"), strict=True):
        ax.plot(times, results["dpc"].reference[:, channel], color="black", lw=2, label="reference")
        for mca, result in results.items():
            pi = result.summary["pi"]
            ax.plot(times, result.outputs[:, channel], lw=1.2, label=f"{mca} (PI {pi:.2f})")
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
    title = "Surge force and pitch rate: the three MCAs on one flight"
    _finish(fig, axes, title, out / "mcas_compared.png", ncol=2)


def make_recording(out: Path) -> None:
    """A flight's recording as `mca-drake plot-recording` draws it."""
    from mca_drake.plotting import plot_recording
    from mca_drake.references.flights import FlightSpec, flight_recording

    recording = flight_recording(FlightSpec(vehicle="jet", seed=2000), 120.0)
    save_figure(plot_recording(recording, "jet flight, seed 2000, 120 s"), out / "recording.png")


def make_plausibility(out: Path) -> None:
    """A spike in the reference: cued as it is and behind the input plausibility guard."""
    from mca_drake.cueing.plausibility import PlausibilityConfig
    from mca_drake.platforms.files import load_platform
    from mca_drake.references.reference import Reference
    from mca_drake.simulation.closed_loop import run_closed_loop

    robot = load_platform("kr500")
    clean = _flight(20.0)
    y = clean.y.copy()
    k = round(8.0 / clean.time_step)
    y[k : k + 3, 3] += 40.0  # a 30 ms spike of 40 m/s^2 on f_x: a bad sample, not motion
    spiked = Reference(y, clean.time_step, "spiked", clean.vehicle)
    fig, ax = plt.subplots(figsize=(8.0, 3.4))
    window = slice(k - 100, k + 200)
    times = np.arange(y.shape[0])[window] * clean.time_step
    ax.plot(times, np.clip(y[window, 3], -3, 3), color="black", lw=1.5, label="reference (clipped)")
    for label, enabled in (("cued as it is", False), ("behind the guard", True)):
        result = run_closed_loop(
            mca="nmpc-rti",
            reference=spiked,
            robot=robot,
            plant="analytical",
            progress=False,
            plausibility=PlausibilityConfig(enabled=enabled),
        )
        ax.plot(result.times[window], result.outputs[window, 3], lw=1.4, label=label)
    ax.set_xlabel("t, s")
    ax.set_ylabel("f_x, m/s²")
    ax.set_title("A 30 ms spike of 40 m/s² at t = 8 s, NMPC-rti")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, out / "plausibility_spike.png")


def make_bound(out: Path) -> None:
    """The offline-optimal bound against the NMPC-rti on 20 s of the flight."""
    from mca_drake.platforms.files import load_platform
    from mca_drake.simulation.closed_loop import run_closed_loop
    from mca_drake.simulation.optimal_bound import run_optimal_bound

    robot = load_platform("kr500")
    reference = _flight(20.0)
    bound = run_optimal_bound(
        reference=reference, robot=robot, starts=("nmpc-rti",), progress=False
    )

    nmpc = run_closed_loop(
        mca="nmpc-rti", reference=reference, robot=robot, plant="analytical", progress=False
    )
    fig, axes = plt.subplots(2, 1, figsize=(8.0, 4.6), sharex=True)
    for ax, channel, unit in zip(axes, (0, 1), ("w_x, rad/s", "w_y, rad/s"), strict=True):
        ax.plot(nmpc.times, nmpc.reference[:, channel], color="black", lw=2, label="reference")
        ax.plot(
            nmpc.times, nmpc.outputs[:, channel], label=f"NMPC-rti (PI {nmpc.summary['pi']:.2f})"
        )
        ax.plot(
            bound.times,
            bound.outputs[:, channel],
            label=f"offline-optimal bound (PI {bound.summary['pi']:.2f})",
        )
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
    title = "Roll and pitch rate: the bound knows the whole flight"
    _finish(fig, axes, title, out / "bound.png")


def make_drive(out: Path) -> None:
    """A car's drive as a recording (a lap of a seeded track)."""
    from mca_drake.plotting import plot_recording
    from mca_drake.references.drives import DriveSpec, motion_recording

    recording = motion_recording(DriveSpec(manoeuvre="lap", seed=4000), 90.0)
    save_figure(plot_recording(recording, "bmw-320i, a lap, seed 4000, 90 s"), out / "drive.png")


# -- diagrams --------------------------------------------------------------------------


# Inputs that read what the loop's plant did: the edges into them close the loop's feedback.
FEEDBACK_INPUTS = ("state", "estimated_state", "inertial_output")


def _layers(systems, edges, feedback):
    """Column of each system: the longest path to it over the edges that are not
    `feedback` (nor close a cycle in a depth-first walk from the sources)."""
    children = {s: [] for s in systems}
    for a, b in edges:
        if (a, b) not in feedback:
            children[a].append(b)
    state, forward = {}, set()

    def walk(s):
        state[s] = "open"
        for c in children[s]:
            if state.get(c) is None:
                forward.add((s, c))
                walk(c)
            elif state[c] == "done":
                forward.add((s, c))
        state[s] = "done"

    starts = [s for s in systems if not any(b == s for a, b in edges if (a, b) not in feedback)]
    for s in [*starts, *systems]:
        if state.get(s) is None:
            walk(s)
    column = {s: 0 for s in systems}
    for _ in systems:
        for a, b in forward:
            column[b] = max(column[b], column[a] + 1)
    return column, forward


def _label(system) -> str:
    """A system's name, and its class where the name does not already say it."""
    name, kind = system.get_name(), type(system).__name__
    if kind.lower().replace("_", "") == name.lower().replace("_", ""):
        return name
    if len(kind) > 16:  # a long class name on two lines, at a capital near its middle
        capitals = [i for i, c in enumerate(kind) if c.isupper() and i > 0]
        if capitals:
            cut = min(capitals, key=lambda i: abs(i - len(kind) / 2))
            kind = f"{kind[:cut]}\n{kind[cut:]}"
    return f"{name}\n({kind})"


def diagram_figure(diagram, title, skip=("VectorLogSink",)):
    """Drake `diagram`'s systems as boxes in columns and its connections as arrows
    (feedback arrows curved below); systems whose class is in `skip` left out."""
    connections = diagram.connection_map()
    systems = [s for s in diagram.GetSystems() if type(s).__name__ not in skip]
    kept = set(systems)
    edges, feedback = [], set()
    for (to_system, port), (from_system, _) in connections.items():
        if from_system in kept and to_system in kept and (from_system, to_system) not in edges:
            edges.append((from_system, to_system))
        if to_system.get_input_port(port).get_name() in FEEDBACK_INPUTS:
            feedback.add((from_system, to_system))
    return blocks_figure(systems, _label, edges, feedback, title)


def blocks_figure(systems, label_of, edges, feedback, title):
    """Boxes (`label_of(node)`) in columns by the longest path to each, `edges` (a, b) as
    arrows, those in `feedback` curved over the boxes."""
    _label = label_of
    column, forward = _layers(systems, edges, feedback)
    rows: dict[int, list] = {}
    for s in systems:
        rows.setdefault(column[s], []).append(s)
    height = max(len(v) for v in rows.values())
    longest = max(len(line) for s in systems for line in _label(s).splitlines())
    spacing = 0.075 * longest + 0.55  # columns as far apart as the widest box needs (in)
    position = {}
    for c, members in rows.items():
        for r, s in enumerate(members):
            position[s] = (c * spacing, -(r - 0.5 * (len(members) - 1)) * 1.3)
    columns = max(column.values()) + 1
    fig, ax = plt.subplots(figsize=(max(6.0, 1.15 * spacing * columns), 1.6 + 0.75 * height))
    xs = [p[0] for p in position.values()]
    ys = [p[1] for p in position.values()]
    ax.set_xlim(min(xs) - 0.6 * spacing, max(xs) + 0.6 * spacing)
    ax.set_ylim(min(ys) - 0.9, max(ys) + 2.0)
    boxes = {}
    for s, (x, y) in position.items():
        boxes[s] = ax.text(
            x,
            y,
            _label(s),
            ha="center",
            va="center",
            fontsize=8,
            bbox=dict(boxstyle="round,pad=0.4", fc="#e8eef8", ec="#3b5b92"),
        )
    ax.set_axis_off()
    legend = "  (grey: data flow; brown: feedback)" if len(forward) < len(edges) else ""
    ax.set_title(title + legend, fontsize=10)
    fig.tight_layout()
    fig.canvas.draw()  # the boxes' extents, to start and end the arrows at their edges
    to_data = ax.transData.inverted()
    extent = {
        s: to_data.transform(t.get_bbox_patch().get_window_extent()) for s, t in boxes.items()
    }
    for a, b in edges:
        (ax0, ay0), (ax1, ay1) = extent[a]
        (bx0, by0), (bx1, by1) = extent[b]
        if (a, b) in forward:
            start, end = (ax1, 0.5 * (ay0 + ay1)), (bx0, 0.5 * (by0 + by1))
            style, colour = "arc3,rad=0.0", "#555555"
        else:  # feedback: from the top of its source over to the top of its target
            start, end = (0.5 * (ax0 + ax1), ay1), (0.5 * (bx0 + bx1), by1)
            # long spans bend less, so that every arc stays inside the figure
            bend = 0.3 * min(1.0, 2.5 * spacing / max(abs(bx0 - ax0), 1e-9))
            style, colour = f"arc3,rad={bend:.3f}", "#b5651d"
        ax.annotate(
            "",
            end,
            start,
            arrowprops=dict(arrowstyle="-|>", color=colour, lw=1.1, connectionstyle=style),
        )
    return fig


def make_ray(out: Path) -> None:
    """How a study runs on Ray: small task configs out, one result file per task back."""
    nodes = [
        "study config\n(suite, dataset,\ntuning)",
        "tasks: small\npicklable configs",
        "Ray worker 1\nbuilds its diagram",
        "Ray worker N\nbuilds its diagram",
        "one result file\nper task (atomic)",
        "report, merged\ndataset, best config",
    ]
    edges = [
        (nodes[0], nodes[1]),
        (nodes[1], nodes[2]),
        (nodes[1], nodes[3]),
        (nodes[2], nodes[4]),
        (nodes[3], nodes[4]),
        (nodes[4], nodes[5]),
    ]
    fig = blocks_figure(
        nodes, str, edges, set(), "A study on Ray: a killed run resumes from the files"
    )
    save_figure(fig, out / "ray_tasks.png")


def _mca_drake(*arguments: str) -> None:
    """Runs the `mca-drake` command of this environment."""
    import subprocess

    command = [str(Path(sys.executable).with_name("mca-drake")), *arguments]
    subprocess.run(command, check=True)


def make_tuning(out: Path) -> None:
    """A small tune of the washout (6 trials on one 30 s training flight): its convergence."""
    with tempfile.TemporaryDirectory() as tmp:
        _mca_drake(
            *("tune", "--mca", "washout", "--trials", "6", "--flights", "light:100"),
            *("--duration", "30", "--out-dir", tmp, "--quiet"),
        )
        shutil.copy(Path(tmp) / "convergence.png", out / "tuning_convergence.png")


# The training guide's quick path: a small dataset and a small policy, a few minutes.
QUICK_DATASET = (
    *("dataset", "closed-loop", "--vehicle", "light", "--flights", "6", "--first-seed", "100"),
    *("--minutes", "3", "--horizon", "128"),
)
QUICK_TRAINING = (
    *("train-policy", "--hidden", "64", "--horizons", "128,256", "--max-epochs", "200"),
    *("--learning-rate", "0.003"),
)


def make_training(out: Path) -> None:
    """The training guide's quick path (about 7 minutes on two cores): its loss curves."""
    with tempfile.TemporaryDirectory() as tmp:
        _mca_drake(*QUICK_DATASET, "--out-dir", f"{tmp}/quick", "--quiet")
        _mca_drake(
            *QUICK_TRAINING,
            *("--dataset", f"{tmp}/quick/dataset.npz", "--out-dir", f"{tmp}/policy", "--quiet"),
        )
        shutil.copy(Path(tmp) / "policy" / "policy_loss.png", out / "training_loss.png")


def make_prediction(out: Path) -> None:
    """What the predictors see and forecast at a few instants of the main job's flight."""
    from mca_drake.cueing.learned_predictor import load_forecast_model
    from mca_drake.cueing.predictor import constant_forecast

    linear, learned = load_forecast_model("linear"), load_forecast_model("learned")
    y = _flight(120.0).y
    h = 0.01
    fig, axes = plt.subplots(2, 1, figsize=(8.0, 5.0), sharex=True)
    for ax, channel, unit in zip(axes, (4, 0), ("f_y, m/s²", "w_x, rad/s"), strict=True):
        ax.plot(np.arange(y.shape[0]) * h, y[:, channel], color="black", lw=1.6, label="reference")
        for i, k in enumerate(range(2000, 11000, 1500)):
            history = y[k - learned.history + 1 : k + 1]
            times = (k + np.arange(1, 256)) * h
            forecasts = (
                ("constant", constant_forecast(history, 255), "#999999"),
                ("linear", linear.forecast(history, 255), "#1f77b4"),
                ("learned", learned.forecast(history, 255), "#d62728"),
            )
            for name, forecast, color in forecasts:
                label = name if i == 0 else None
                ax.plot(times, forecast[:, channel], color=color, lw=1.3, label=label)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.set_xlim(15, 115)
    title = "2.56 s forecasts from the past alone, every 15 s of the main job's flight"
    _finish(fig, axes, title, out / "prediction.png", loc="upper left")


def make_meshcat(out: Path) -> None:
    """A Meshcat view to open in the browser: 10 s of the main job on the station, recorded
    and saved by Drake as one self-contained HTML file (`Meshcat.StaticHtml`)."""
    from pydrake.geometry import Meshcat, MeshcatParams

    from mca_drake.platforms.files import load_platform
    from mca_drake.simulation.builders import default_visualization
    from mca_drake.simulation.closed_loop import run_closed_loop

    meshcat = Meshcat(MeshcatParams(host="localhost", port=0))
    run_closed_loop(
        mca="dpc",
        reference=_flight(10.0),
        robot=load_platform("kr500"),
        plant="multibody",
        meshcat=meshcat,
        visualization=default_visualization(),
        progress=False,
    )
    (out / "meshcat_replay.html").write_text(meshcat.StaticHtml())


def make_suite(out: Path) -> None:
    """The suite's box plot of PIs per case and MCA, from its current result file."""
    import json

    from mca_drake.plotting import plot_pi_boxes

    report = json.loads(
        (HERE.parents[1] / "benchmarks/results/evaluation/evaluation.json").read_text()
    )
    save_figure(plot_pi_boxes(report), out / "suite.png")


def make_diagrams(out: Path) -> None:
    """The closed loop on the analytical plant and on the station, and the live loop."""
    from mca_drake.live.csv_udp import CsvDecoder
    from mca_drake.live.loop import MakeLiveClosedLoop
    from mca_drake.live.receiver import ReceiverConfig
    from mca_drake.platforms.files import load_platform
    from mca_drake.simulation.builders import MakeAnalyticalClosedLoop, MakeMultibodyClosedLoop

    robot = load_platform("kr500")
    reference = _flight(2.0)
    diagram, _ = MakeAnalyticalClosedLoop(reference, "nmpc-rti", robot)
    save_figure(
        diagram_figure(diagram, "MakeAnalyticalClosedLoop: the analytical plant"),
        out / "diagram_analytical.png",
    )
    diagram, _ = MakeMultibodyClosedLoop(reference, "dpc", robot)
    save_figure(
        diagram_figure(diagram, "MakeMultibodyClosedLoop: the KR500 station"),
        out / "diagram_station.png",
    )
    diagram, handles = MakeLiveClosedLoop(
        CsvDecoder(), "dpc", robot=robot, receiver=ReceiverConfig(port=0)
    )
    handles["receiver"].close()
    save_figure(
        diagram_figure(
            diagram,
            "MakeLiveClosedLoop: telemetry to the robot",
            skip=("VectorLogSink", "LiveRecorder"),
        ),
        out / "diagram_live.png",
    )


GROUPS = {
    "platforms": make_platforms,
    "runs": make_runs,
    "recording": make_recording,
    "plausibility": make_plausibility,
    "bound": make_bound,
    "drive": make_drive,
    "diagrams": make_diagrams,
    "ray": make_ray,
    "suite": make_suite,
    "tuning": make_tuning,
    "training": make_training,
    "meshcat": make_meshcat,
    "prediction": make_prediction,
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help=f"comma-separated groups of {', '.join(GROUPS)}")
    parser.add_argument("--out", type=Path, default=HERE, help="folder (default: this one)")
    args = parser.parse_args()
    chosen = args.only.split(",") if args.only else list(GROUPS)
    unknown = [g for g in chosen if g not in GROUPS]
    if unknown:
        parser.error(f"unknown group {unknown}; valid: {', '.join(GROUPS)}")
    args.out.mkdir(parents=True, exist_ok=True)
    for group in chosen:
        print(f"{group} ...", flush=True)
        GROUPS[group](args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
