"""Diagram builders (Make*/Add*) and the typed scenarios that YAML files load into.

Each scenario is a dataclass with a comment on every field; `load_scenario` reads one from
YAML with `pydrake.common.yaml.yaml_load_typed`, so a misspelt key fails loudly.
(No `from __future__ import annotations` here: the YAML loader needs real type objects.)
"""

import dataclasses
from pathlib import Path
from typing import Union

import numpy as np
from pydrake.common.yaml import yaml_dump, yaml_load, yaml_load_typed
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from mca_drake.demo_motion import demo_joint_motion
from mca_drake.robot import KR500, load_kr500
from mca_drake.systems import MotionCueingPlant
from mca_drake.systems.kr500_station import StationConfig
from mca_drake.torch_plant import DEFAULT_DT


@dataclasses.dataclass
class PlantDemoScenario:
    """The analytical plant driven by the built-in demo joint motion (no MCA yet)."""

    # Simulated time, s.
    duration_s: float = 20.0
    # Control period of the plant and of the logged signals, s.
    time_step: float = DEFAULT_DT
    # URDF of the robot; empty means the packaged models/kr500.urdf.
    robot_urdf: str = ""

    def validate(self) -> None:
        """Raises ValueError for values that cannot run."""
        if not self.duration_s > 0:
            raise ValueError(f"duration_s must be positive; got {self.duration_s}")
        if not 0 < self.time_step <= 0.1:
            raise ValueError(f"time_step must be in (0, 0.1] s; got {self.time_step}")


@dataclasses.dataclass
class FlightSpec:
    """The vehicle motion a scenario cues."""

    # Recording CSV (columns t, omega_x, omega_y, omega_z, f_x, f_y, f_z); empty: fly the
    # built-in JSBSim flight below.
    recording: str = ""
    # Built-in flight: "light" (c172p) or "jet" (global5000).
    vehicle: str = "light"
    # Seed of the built-in flight's scripted pilot (training used 100-104).
    seed: int = 1000

    def validate(self) -> None:
        if not self.recording and self.vehicle not in ("light", "jet"):
            raise ValueError(f"flight.vehicle must be light or jet; got {self.vehicle!r}")
        if self.recording and not Path(self.recording).is_file():
            raise ValueError(f"flight.recording {self.recording!r} not found")


@dataclasses.dataclass
class ClosedLoopScenario:
    """Closed-loop motion cueing on the KR500 (MultibodyPlant station or analytical plant)."""

    # Motion cueing algorithm: dpc, nmpc-rti, nmpc-converged or washout.
    mca: str = "dpc"
    # "multibody" (KR500 MultibodyPlant, inverse dynamics, head IMU) or "analytical".
    plant: str = "multibody"
    # The flight to cue.
    flight: FlightSpec = dataclasses.field(default_factory=FlightSpec)
    # Simulated time, s.
    duration_s: float = 60.0
    # Policy file of "dpc"; empty: the policy shipped with the package.
    policy: str = ""
    # The simulated robot, its controller and sensors (multibody plant only).
    station: StationConfig = dataclasses.field(default_factory=StationConfig)
    # Watch it in Meshcat (multibody plant only).
    meshcat: bool = False
    # Target simulated/wall rate: 1 for live use, 0 as fast as possible (multibody only).
    realtime_rate: float = 0.0
    # Folder for summary.json, tracking.png (Fig. 4) and joint_usage.png (Fig. 5).
    output_dir: str = "results/closed_loop"

    def validate(self) -> None:
        if self.mca not in MCA_NAMES:
            raise ValueError(f"mca must be one of {', '.join(MCA_NAMES)}; got {self.mca!r}")
        if self.plant not in ("multibody", "analytical"):
            raise ValueError(f"plant must be multibody or analytical; got {self.plant!r}")
        if not self.duration_s > 0:
            raise ValueError(f"duration_s must be positive; got {self.duration_s}")
        if self.plant == "analytical" and (self.meshcat or self.realtime_rate):
            raise ValueError("meshcat and realtime_rate need plant multibody")
        if self.policy and not Path(self.policy).is_file():
            raise ValueError(f"policy file {self.policy!r} not found")
        self.flight.validate()
        self.station.validate()


@dataclasses.dataclass
class EvaluationScenario:
    """The scenario evaluation of the MCAs (Case A light aircraft, Case B jet)."""

    # MCAs compared (DPC is tested against each other one).
    mcas: list[str] = dataclasses.field(
        default_factory=lambda: ["dpc", "nmpc-converged", "nmpc-rti", "washout"]
    )
    # Case A flight seeds (light aircraft); empty: skip the case.
    light_seeds: list[int] = dataclasses.field(default_factory=lambda: list(range(1000, 1010)))
    # Case B flight seeds (jet); empty: skip the case.
    jet_seeds: list[int] = dataclasses.field(default_factory=lambda: list(range(2000, 2010)))
    # Simulated seconds per flight.
    duration_s: float = 300.0
    # Policy file of "dpc"; empty: the shipped one.
    policy: str = ""
    # Parallel worker processes.
    workers: int = 1
    # Folder of the per-run JSON files (resumable), evaluation.md/json and the box plot.
    output_dir: str = "results/evaluation"

    def validate(self) -> None:
        if not (self.light_seeds or self.jet_seeds):
            raise ValueError("light_seeds and jet_seeds are both empty: nothing to evaluate")
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1; got {self.workers}")
        self.to_config().validate()

    def to_config(self):
        """The `mca_drake.scenario_evaluation.EvaluationConfig` of this scenario."""
        from mca_drake.scenario_evaluation import EvaluationCase, EvaluationConfig

        cases = []
        if self.light_seeds:
            cases.append(EvaluationCase("A", "light", tuple(self.light_seeds)))
        if self.jet_seeds:
            cases.append(EvaluationCase("B", "jet", tuple(self.jet_seeds)))
        return EvaluationConfig(
            mcas=tuple(self.mcas),
            cases=tuple(cases),
            duration_s=self.duration_s,
            policy=self.policy or None,
        )


@dataclasses.dataclass
class DatasetScenario:
    """Closed-loop dataset generation (the training data of the plant models and DPC)."""

    # Vehicle class flown by JSBSim: "light" or "jet".
    vehicle: str = "light"
    # Flight seeds (evaluation uses 1000 on; keep these apart).
    flight_seeds: list[int] = dataclasses.field(default_factory=lambda: [100, 101, 102, 103, 104])
    # Length of each flight, s.
    flight_duration_s: float = 900.0
    # Segment length n_p, steps.
    horizon: int = 256
    # MCA that generates the trajectories.
    mca: str = "nmpc-rti"
    # Seed of the shuffle before the 70/20/10 split.
    split_seed: int = 0
    # Parallel worker processes (one flight each).
    workers: int = 1
    # Folder of the per-flight files and the merged dataset.npz (resumable).
    output_dir: str = "datasets/closed_loop"

    def validate(self) -> None:
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1; got {self.workers}")
        self.to_config().validate()

    def to_config(self):
        """The `mca_drake.closed_loop_dataset.ClosedLoopDatasetConfig` of this scenario."""
        from mca_drake.closed_loop_dataset import ClosedLoopDatasetConfig

        return ClosedLoopDatasetConfig(
            vehicle=self.vehicle,
            flight_seeds=tuple(self.flight_seeds),
            flight_duration_s=self.flight_duration_s,
            horizon=self.horizon,
            mca=self.mca,
            split_seed=self.split_seed,
        )


Scenario = PlantDemoScenario | ClosedLoopScenario | EvaluationScenario | DatasetScenario


@dataclasses.dataclass
class ScenarioFile:
    """What a diagrams/*.yaml file holds: one job, tagged with its type, e.g.
    `scenario: !ClosedLoopScenario {mca: dpc, duration_s: 600}`."""

    # The job to run and its settings.
    scenario: Union[  # noqa: UP007 (the YAML loader needs typing.Union)
        PlantDemoScenario, ClosedLoopScenario, EvaluationScenario, DatasetScenario
    ] = dataclasses.field(default_factory=PlantDemoScenario)


def load_scenario(path: str | Path, overrides: str | None = None) -> Scenario:
    """Loads the `scenario` of a YAML file in diagrams/, with optional text overrides.

    Args:
        path: the YAML file.
        overrides: optional YAML text applied on top of the file's scenario, for quick
            changes: '{scenario: {duration_s: 5}}' or just '{duration_s: 5}'.

    Raises:
        FileNotFoundError: no such file.
        ValueError: unknown field, a value of the wrong type, or a value out of range.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"scenario file not found: {path}")
    try:
        scenario = yaml_load_typed(schema=ScenarioFile, filename=str(path)).scenario
        if overrides:
            raw = yaml_load(data=overrides)
            if not isinstance(raw, dict):
                raise ValueError(f"an override must be a YAML mapping; got {overrides!r}")
            if set(raw) == {"scenario"}:
                raw = raw["scenario"]
            # Applied to the loaded scenario's own type, so a tagged file needs no tag here.
            scenario = yaml_load_typed(
                schema=type(scenario), data=yaml_dump(raw), defaults=scenario
            )
    except (RuntimeError, ValueError, TypeError, AssertionError) as err:
        raise ValueError(f"{path}: {type(err).__name__}: {err}") from err
    try:
        scenario.validate()
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err
    return scenario


def MakePlantDemoDiagram(
    scenario: PlantDemoScenario, robot: KR500 | None = None
) -> tuple[Diagram, dict]:
    """Demo joint accelerations -> MotionCueingPlant, with 100 Hz logs.

    Returns:
        (diagram, handles): handles has the `plant` system and the `output_log` and
        `state_log` VectorLogSinks (inertial_output y and state [q, qd]).
    """
    scenario.validate()
    robot = robot if robot is not None else load_kr500(scenario.robot_urdf or None)
    h = scenario.time_step
    times = np.arange(0.0, scenario.duration_s + 2 * h, h)
    _, _, qdd = demo_joint_motion(times, robot)
    builder = DiagramBuilder()
    source = builder.AddNamedSystem(
        "demo_motion", TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, qdd.T))
    )
    plant = builder.AddNamedSystem("plant", MotionCueingPlant(robot=robot, time_step=h))
    builder.Connect(source.get_output_port(), plant.GetInputPort("joint_acceleration"))
    output_log = LogVectorOutput(plant.GetOutputPort("inertial_output"), builder, h)
    state_log = LogVectorOutput(plant.GetOutputPort("state"), builder, h)
    output_log.set_name("output_log")
    state_log.set_name("state_log")
    input_log = LogVectorOutput(source.get_output_port(), builder, h)
    input_log.set_name("input_log")
    diagram = builder.Build()
    diagram.set_name("plant_demo")
    handles = dict(plant=plant, output_log=output_log, state_log=state_log, input_log=input_log)
    return diagram, handles


MCA_NAMES = ("dpc", "nmpc-rti", "nmpc-converged", "washout")


def AddMca(
    builder: DiagramBuilder,
    mca: str,
    robot: KR500,
    time_step: float = DEFAULT_DT,
    policy: str | Path | None = None,
):
    """Adds the motion cueing algorithm named `mca` to `builder` and returns it.

    Every MCA has input ports `state` (12) and `reference` (6), the output ports
    `joint_acceleration` (6) and `statistics`, and "dpc" also the input `inertial_output`
    (6). Valid names: MCA_NAMES.

    Args:
        policy: the policy file of "dpc" (default: the policy shipped with the package).
    """
    from mca_drake.nmpc import NmpcConfig
    from mca_drake.systems.nmpc_controller import NmpcController

    if mca in ("nmpc-rti", "nmpc-converged"):
        config = NmpcConfig(mode=mca.removeprefix("nmpc-"), time_step=time_step)
        return builder.AddNamedSystem("mca", NmpcController(config, robot))
    if mca == "dpc":
        from mca_drake.policy_inference import default_policy_path
        from mca_drake.systems.dpc_policy import DpcPolicy

        path = Path(policy) if policy is not None else default_policy_path()
        return builder.AddNamedSystem("mca", DpcPolicy(path, robot, time_step))
    if mca == "washout":
        from mca_drake.systems.classical_washout import ClassicalWashout

        return builder.AddNamedSystem("mca", ClassicalWashout(robot=robot, time_step=time_step))
    raise ValueError(f"unknown MCA '{mca}'; valid: {', '.join(MCA_NAMES)}")


def _add_source_and_mca(builder, reference, mca, robot, time_step, policy):
    """ReferenceSource and the MCA, wired together; returns (source, mca, initial_state):
    the robot starts at rest at the MCA's home pose (q = 0 unless the MCA has one)."""
    from mca_drake.systems import ReferenceSource

    source = builder.AddNamedSystem("reference_source", ReferenceSource(reference))
    controller = AddMca(builder, mca, robot, time_step, policy)
    builder.Connect(source.GetOutputPort("reference"), controller.GetInputPort("reference"))
    home = getattr(controller, "home_position", np.zeros(len(robot.joint_names)))
    return source, controller, np.concatenate([home, np.zeros_like(home)])


def _connect_mca(builder, controller, state, inertial_output, joint_acceleration) -> None:
    """Feeds the MCA the robot's `state` (and `inertial_output` where it reads one) and
    drives the robot's `joint_acceleration` input with its command."""
    builder.Connect(state, controller.GetInputPort("state"))
    if controller.HasInputPort("inertial_output"):
        builder.Connect(inertial_output, controller.GetInputPort("inertial_output"))
    builder.Connect(controller.GetOutputPort("joint_acceleration"), joint_acceleration)


def _add_logs(builder: DiagramBuilder, ports: dict, controller, time_step: float) -> dict:
    """Named VectorLogSinks of `ports` (name -> output port), plus the MCA's
    `statistics_log` where it has statistics, all sampled every `time_step`."""
    if controller.HasOutputPort("statistics"):
        ports = ports | {"statistics_log": controller.GetOutputPort("statistics")}
    logs = {}
    for name, port in ports.items():
        logs[name] = LogVectorOutput(port, builder, time_step)
        logs[name].set_name(name)
    return logs


def MakeAnalyticalClosedLoop(
    reference,
    mca: str,
    robot: KR500 | None = None,
    time_step: float = DEFAULT_DT,
    policy: str | Path | None = None,
) -> tuple[Diagram, dict]:
    """ReferenceSource -> MCA -> MotionCueingPlant, the MCA fed the plant state, with logs.

    Logs (100 Hz VectorLogSinks): `reference_log`, `state_log` (x_n at t_n) and
    `command_log`. Publishing happens before the control update at the same instant, so
    the command logged at t_(n+1) is u_n, the one applied over [t_n, t_(n+1)).

    Returns:
        (diagram, handles) with the systems `source`, `mca`, `plant` and the three logs.
    """
    robot = robot if robot is not None else load_kr500()
    builder = DiagramBuilder()
    source, controller, initial_state = _add_source_and_mca(
        builder, reference, mca, robot, time_step, policy
    )
    plant = builder.AddNamedSystem(
        "plant", MotionCueingPlant(robot=robot, time_step=time_step, initial_state=initial_state)
    )
    _connect_mca(
        builder,
        controller,
        plant.GetOutputPort("state"),
        plant.GetOutputPort("inertial_output"),
        plant.GetInputPort("joint_acceleration"),
    )
    handles = dict(source=source, mca=controller, plant=plant)
    ports = {
        "reference_log": source.GetOutputPort("reference"),
        "state_log": plant.GetOutputPort("state"),
        "command_log": controller.GetOutputPort("joint_acceleration"),
    }
    handles |= _add_logs(builder, ports, controller, time_step)
    diagram = builder.Build()
    diagram.set_name(f"closed_loop_{mca}")
    return diagram, handles


def MakeMultibodyClosedLoop(
    reference,
    mca: str,
    robot: KR500 | None = None,
    time_step: float = DEFAULT_DT,
    policy: str | Path | None = None,
    station=None,
    meshcat=None,
) -> tuple[Diagram, dict]:
    """ReferenceSource -> MCA -> KR500 station (MultibodyPlant, inverse dynamics, head IMU),
    the MCA fed the station's measured state (and measured y where it reads one).

    Logs (every `time_step`): `reference_log`, `command_log` (the MCA's joint
    accelerations), `desired_state_log` ([q_d, qd_d] the controller tracks),
    `measured_state_log` ([q, qd] of the MultibodyPlant) and `measured_output_log` (y from
    the head IMU, without the measurement delay: what the occupant felt), and
    `statistics_log` where the MCA has statistics.

    Args:
        reference: the target outputs (a `Reference`).
        mca: an MCA name (MCA_NAMES).
        station: a `StationConfig` (default: 1 ms plant, 40 rad/s tracking, no limits,
            no noise, no delay).
        meshcat: a pydrake Meshcat to draw the robot, the cabin and live target/measured
            strip charts in; None for none.

    Returns:
        (diagram, handles): handles has `source`, `mca`, `station` (StationHandles) and the
        logs; call `handles["station"].SetInitialState(root_context)` before simulating
        (the robot starts at rest at the MCA's home pose).
    """
    from mca_drake.systems.kr500_station import AddKR500Station

    robot = robot if robot is not None else load_kr500()
    builder = DiagramBuilder()
    source, controller, initial_state = _add_source_and_mca(
        builder, reference, mca, robot, time_step, policy
    )
    station_handles = AddKR500Station(
        builder, robot, station, initial_state, with_geometry=meshcat is not None
    )
    _connect_mca(
        builder,
        controller,
        station_handles.measured_state,
        station_handles.measured_output,
        station_handles.joint_acceleration,
    )
    handles = dict(source=source, mca=controller, station=station_handles)
    ports = {
        "reference_log": source.GetOutputPort("reference"),
        "command_log": controller.GetOutputPort("joint_acceleration"),
        "desired_state_log": station_handles.desired_state,
        "measured_state_log": station_handles.true_state,
        "measured_output_log": station_handles.true_output,
    }
    handles |= _add_logs(builder, ports, controller, time_step)
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

        from mca_drake.systems.meshcat_traces import MeshcatOutputTraces

        MeshcatVisualizer.AddToBuilder(
            builder,
            station_handles.scene_graph,
            meshcat,
            MeshcatVisualizerParams(publish_period=1 / 30),
        )
        # A view of the whole robot with the strip-chart board behind it, to its left.
        meshcat.SetCameraPose(np.array([3.5, -4.5, 3.2]), np.array([-0.5, 1.5, 1.6]))
        traces = builder.AddNamedSystem(
            "output_traces", MeshcatOutputTraces(meshcat, sample_period=time_step)
        )
        builder.Connect(source.GetOutputPort("reference"), traces.GetInputPort("reference"))
        builder.Connect(station_handles.true_output, traces.GetInputPort("measured_output"))
        handles["traces"] = traces
    diagram = builder.Build()
    diagram.set_name(f"multibody_closed_loop_{mca}")
    return diagram, handles
