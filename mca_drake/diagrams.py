"""Diagram builders (Make*/Add*) and the typed scenarios that YAML files load into.

Each scenario is a dataclass with a comment on every field; `load_scenario` reads one from
YAML with `pydrake.common.yaml.yaml_load_typed`, so a misspelt key fails loudly.
(No `from __future__ import annotations` here: the YAML loader needs real type objects.)
"""

import dataclasses
from pathlib import Path

import numpy as np
from pydrake.common.yaml import yaml_load_typed
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from mca_drake.demo_motion import demo_joint_motion
from mca_drake.robot import KR500, load_kr500
from mca_drake.systems import MotionCueingPlant
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
class ScenarioFile:
    """What a diagrams/*.yaml file holds. `scenario` becomes a tagged union (`!Name`) as
    more jobs (evaluation, closed loop, dataset generation) arrive."""

    # The job to run and its settings.
    scenario: PlantDemoScenario = dataclasses.field(default_factory=PlantDemoScenario)


def load_scenario(path: str | Path, overrides: str | None = None) -> PlantDemoScenario:
    """Loads the `scenario` of a YAML file in diagrams/, with optional text overrides.

    Args:
        path: the YAML file.
        overrides: optional YAML text applied on top of the file, for quick changes,
            e.g. '{scenario: {duration_s: 5}}'.

    Raises:
        FileNotFoundError: no such file.
        ValueError: unknown field, a value of the wrong type, or a value out of range.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"scenario file not found: {path}")
    try:
        loaded = yaml_load_typed(schema=ScenarioFile, filename=str(path))
        if overrides:
            loaded = yaml_load_typed(schema=ScenarioFile, data=overrides, defaults=loaded)
    except (RuntimeError, ValueError, TypeError, AssertionError) as err:
        raise ValueError(f"{path}: {type(err).__name__}: {err}") from err
    loaded.scenario.validate()
    return loaded.scenario


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
    from mca_drake.systems import ReferenceSource

    robot = robot if robot is not None else load_kr500()
    builder = DiagramBuilder()
    source = builder.AddNamedSystem("reference_source", ReferenceSource(reference))
    controller = AddMca(builder, mca, robot, time_step, policy)
    # The robot starts at rest at the MCA's home pose (q = 0 unless the MCA says otherwise).
    home = getattr(controller, "home_position", np.zeros(len(robot.joint_names)))
    initial_state = np.concatenate([home, np.zeros_like(home)])
    plant = builder.AddNamedSystem(
        "plant", MotionCueingPlant(robot=robot, time_step=time_step, initial_state=initial_state)
    )
    if controller.HasInputPort("inertial_output"):
        builder.Connect(
            plant.GetOutputPort("inertial_output"), controller.GetInputPort("inertial_output")
        )
    builder.Connect(source.GetOutputPort("reference"), controller.GetInputPort("reference"))
    builder.Connect(plant.GetOutputPort("state"), controller.GetInputPort("state"))
    builder.Connect(
        controller.GetOutputPort("joint_acceleration"), plant.GetInputPort("joint_acceleration")
    )
    handles = dict(source=source, mca=controller, plant=plant)
    for name, port in (
        ("reference_log", source.GetOutputPort("reference")),
        ("state_log", plant.GetOutputPort("state")),
        ("command_log", controller.GetOutputPort("joint_acceleration")),
    ):
        handles[name] = LogVectorOutput(port, builder, time_step)
        handles[name].set_name(name)
    if controller.HasOutputPort("statistics"):
        handles["statistics_log"] = LogVectorOutput(
            controller.GetOutputPort("statistics"), builder, time_step
        )
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
    from mca_drake.systems import ReferenceSource
    from mca_drake.systems.kr500_station import AddKR500Station

    robot = robot if robot is not None else load_kr500()
    builder = DiagramBuilder()
    source = builder.AddNamedSystem("reference_source", ReferenceSource(reference))
    controller = AddMca(builder, mca, robot, time_step, policy)
    home = getattr(controller, "home_position", np.zeros(len(robot.joint_names)))
    initial_state = np.concatenate([home, np.zeros_like(home)])
    station_handles = AddKR500Station(
        builder, robot, station, initial_state, with_geometry=meshcat is not None
    )
    builder.Connect(source.GetOutputPort("reference"), controller.GetInputPort("reference"))
    builder.Connect(station_handles.measured_state, controller.GetInputPort("state"))
    if controller.HasInputPort("inertial_output"):
        builder.Connect(station_handles.measured_output, controller.GetInputPort("inertial_output"))
    builder.Connect(
        controller.GetOutputPort("joint_acceleration"), station_handles.joint_acceleration
    )
    handles = dict(source=source, mca=controller, station=station_handles)
    for name, port in (
        ("reference_log", source.GetOutputPort("reference")),
        ("command_log", controller.GetOutputPort("joint_acceleration")),
        ("desired_state_log", station_handles.desired_state),
        ("measured_state_log", station_handles.true_state),
        ("measured_output_log", station_handles.true_output),
    ):
        handles[name] = LogVectorOutput(port, builder, time_step)
        handles[name].set_name(name)
    if controller.HasOutputPort("statistics"):
        handles["statistics_log"] = LogVectorOutput(
            controller.GetOutputPort("statistics"), builder, time_step
        )
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

        from mca_drake.systems.meshcat_traces import MeshcatOutputTraces

        MeshcatVisualizer.AddToBuilder(
            builder,
            station_handles.scene_graph,
            meshcat,
            MeshcatVisualizerParams(publish_period=1 / 30),
        )
        traces = builder.AddNamedSystem(
            "output_traces", MeshcatOutputTraces(meshcat, sample_period=time_step)
        )
        builder.Connect(source.GetOutputPort("reference"), traces.GetInputPort("reference"))
        builder.Connect(station_handles.true_output, traces.GetInputPort("measured_output"))
        handles["traces"] = traces
    diagram = builder.Build()
    diagram.set_name(f"multibody_closed_loop_{mca}")
    return diagram, handles
