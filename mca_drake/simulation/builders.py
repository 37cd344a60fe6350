"""Diagram builders (Make*/Add*): the plant demo and the closed loops on both plants.

`AddMca` adds any MCA from its typed config (`mca_drake.cueing.McaConfig`);
`MakeAnalyticalClosedLoop` wires ReferenceSource -> ReferenceGuard -> MCA -> MotionCueingPlant
and `MakeMultibodyClosedLoop` ReferenceSource -> ReferenceGuard -> MCA -> SerialChain station,
each with 100 Hz logs (`AddReferenceGuard`: the input plausibility guard every MCA reads
through).
`mca_drake.simulation.closed_loop.run_closed_loop` simulates either and summarises it.
"""

import numpy as np
from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams, Rgba, Role
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial
from pydrake.visualization import VisualizationConfig

from mca_drake.comfort import ComfortConfig
from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.cueing import DpcConfig, McaConfig, NmpcConfig, WashoutConfig, as_mca_config
from mca_drake.cueing.plausibility import PlausibilityConfig
from mca_drake.platforms.demo_motion import demo_joint_motion
from mca_drake.platforms.leg_platform import LegPlatform
from mca_drake.platforms.serial import SerialChain
from mca_drake.references.reference import Reference, ReferenceScaling
from mca_drake.safety import substep_position_coefficient
from mca_drake.systems import MotionCueingPlant, ReferenceSource
from mca_drake.systems.comfort_bound import CabinComfortBound
from mca_drake.systems.dpc import DpcPolicy
from mca_drake.systems.meshcat_legs import MeshcatLegs
from mca_drake.systems.meshcat_traces import MeshcatOutputTraces
from mca_drake.systems.nmpc import NmpcController
from mca_drake.systems.plausibility import ReferenceGuard
from mca_drake.systems.predictor import AddReferencePredictor
from mca_drake.systems.reference_scaling import AddReferenceScaling
from mca_drake.systems.station import AddStation, StationConfig
from mca_drake.systems.washout import ClassicalWashout


def MakePlantDemoDiagram(
    *,
    duration_s: float,
    time_step: float = CONTROL_PERIOD_S,
    robot: SerialChain,
) -> tuple[Diagram, dict]:
    """Demo joint accelerations -> MotionCueingPlant, with 100 Hz logs.

    Returns:
        (diagram, handles): handles has the `plant` system and the `output_log` and
        `state_log` VectorLogSinks (inertial_output y and state [q, qd]).
    """
    if not duration_s > 0 or not 0 < time_step <= 0.1:
        raise ValueError(
            f"duration_s must be positive and time_step in (0, 0.1] s; got {duration_s}, "
            f"{time_step}"
        )
    h = time_step
    times = np.arange(0.0, duration_s + 2 * h, h)
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


def AddMca(
    builder: DiagramBuilder,
    mca: McaConfig | str,
    robot: SerialChain,
    time_step: float = CONTROL_PERIOD_S,
    update_event: str = "unrestricted",
) -> LeafSystem:
    """Adds the motion cueing algorithm of `mca` (a typed config, or a name of
    `mca_drake.cueing.MCA_NAMES` for its default config) to `builder` as system "mca".

    Every MCA has input ports `state` (12) and `reference` (6), the output ports
    `joint_acceleration` (6) and `statistics` (`mca_drake.conventions.MCA_STATISTICS`), and
    DPC also the input `inertial_output` (6).

    Args:
        time_step: the control period, s; an NmpcConfig must state the same.
        update_event: the phase of each control instant the MCA's step runs in
            (`mca_drake.systems.mca_update`): "unrestricted" (before the plant's discrete
            update at the same instant) or "discrete" (after the instant's unrestricted
            updates: the live loop's telemetry poll).

    Raises:
        ValueError: an unknown name, a config that does not validate, or an NmpcConfig
            whose time_step is not the control period.
    """
    config = as_mca_config(mca)
    if isinstance(config, NmpcConfig):
        if abs(config.time_step - time_step) > 1e-12:
            raise ValueError(
                f"NmpcConfig.time_step {config.time_step} s differs from the control period "
                f"{time_step} s of the reference"
            )
        return builder.AddNamedSystem(
            "mca", NmpcController(config, robot, update_event=update_event)
        )
    if isinstance(config, DpcConfig):
        config.validate()
        return builder.AddNamedSystem(
            "mca",
            DpcPolicy(
                str(config.policy_path(robot.name)),
                robot,
                time_step,
                update_event,
                recognized=config.recognized_policy_paths(robot.name),
                first_policy=config.first_policy(),
                range_clip=config.clips_reference(),
                predictor=config.predictor,
            ),
        )
    if isinstance(config, WashoutConfig):
        return builder.AddNamedSystem(
            "mca",
            ClassicalWashout(
                config=config, robot=robot, time_step=time_step, update_event=update_event
            ),
        )
    raise TypeError(f"not an MCA config: {type(config).__name__}")


def AddReferenceGuard(
    builder, reference_port, plausibility, time_step: float, update_offset_s: float = 0.0
):
    """The output port an MCA reads its reference from: `reference_port` through a
    ReferenceGuard named "reference_guard" (`mca_drake.cueing.plausibility`; its step
    committed `update_offset_s` after each control instant), or `reference_port` itself
    where `plausibility` is disabled; and the guard (None where disabled). `plausibility`
    None: the default PlausibilityConfig()."""
    config = plausibility if plausibility is not None else PlausibilityConfig()
    if not config.enabled:
        return reference_port, None
    guard = builder.AddNamedSystem(
        "reference_guard", ReferenceGuard(config, time_step, update_offset_s)
    )
    builder.Connect(reference_port, guard.GetInputPort("reference"))
    return guard.GetOutputPort("guarded_reference"), guard


def _add_source_and_mca(builder, reference, mca, robot, plausibility=None, scaling=None):
    """ReferenceSource and the MCA, wired together through the reference guard and the
    scenario's scaling (`AddReferenceScaling`); returns (source, mca, initial_state, guard):
    the robot starts at rest at the MCA's home pose (q = 0 unless the MCA has one); guard
    None where `plausibility` disables it. An MCA with a preview reads the recorded future,
    or, where its config names a predictor, the forecast of a ReferencePredictor
    (`AddReferencePredictor`) from the reference it has read."""
    controller = AddMca(builder, mca, robot, reference.time_step)
    preview = controller.preview_samples if hasattr(controller, "preview_samples") else 0
    source = builder.AddNamedSystem(
        "reference_source", ReferenceSource(reference, preview_samples=max(preview, 1))
    )
    guarded, guard = AddReferenceGuard(
        builder, source.GetOutputPort("reference"), plausibility, reference.time_step
    )
    forecast = bool(getattr(controller, "predictor", ""))
    # a known future: the MCA reads it (the NMPC at its grid's nodes)
    preview_port = source.GetOutputPort("reference_preview") if preview and not forecast else None
    guarded, preview_port = AddReferenceScaling(builder, guarded, scaling, preview_port)
    builder.Connect(guarded, controller.GetInputPort("reference"))
    if forecast:  # a forecast from what the MCA has read so far, in the MCA's own phase
        preview_port = AddReferencePredictor(
            builder,
            controller,
            guarded,
            reference.time_step,
            signals_port=source.GetOutputPort("signals"),
        )
    if preview:
        builder.Connect(preview_port, controller.GetInputPort("reference_preview"))
    home = getattr(controller, "home_position", robot.home)
    return source, controller, np.concatenate([home, np.zeros_like(home)]), guard


def AddComfortBound(
    builder,
    robot: SerialChain,
    comfort: ComfortConfig | None,
    command_port,
    state_port,
    time_step: float,
    plant_update_offset_s: float = 0.0,
    station: StationConfig | None = None,
):
    """The output port the robot reads its command from: `command_port` through a
    CabinComfortBound named "comfort_bound" (`mca_drake.comfort`), or `command_port` itself
    where `comfort` is None or disabled; and the bound (None where absent). The bound keeps
    the command when the robot takes it: the analytical plant's update
    (`plant_update_offset_s` after each control instant) or, with a `station`, its command
    limiter's (half a plant step after it, with the station's substep clamp)."""
    if comfort is None or not comfort.enabled:
        return command_port, None
    if station is None:
        taken_at, coefficient = plant_update_offset_s, 0.5
    else:
        step = station.plant_time_step
        taken_at = 0.5 * step
        coefficient = substep_position_coefficient(round(time_step / step))
    bound = builder.AddNamedSystem(
        "comfort_bound", CabinComfortBound(robot, comfort, time_step, taken_at, coefficient)
    )
    builder.Connect(command_port, bound.GetInputPort("command"))
    builder.Connect(state_port, bound.GetInputPort("state"))
    return bound.GetOutputPort("bounded_command"), bound


def _command_taken(controller, bound):
    """The port whose log is the command the robot took: the MCA's, or the comfort bound's
    applied command where there is one."""
    if bound is None:
        return controller.GetOutputPort("joint_acceleration")
    return bound.GetOutputPort("applied_command")


def _connect_mca(
    builder, controller, state, inertial_output, joint_acceleration, command=None
) -> None:
    """Feeds the MCA the robot's `state` (and `inertial_output` where it reads one) and
    drives the robot's `joint_acceleration` input with its command (`command`: that
    command after a comfort bound, `AddComfortBound`)."""
    builder.Connect(state, controller.GetInputPort("state"))
    if controller.HasInputPort("inertial_output"):
        builder.Connect(inertial_output, controller.GetInputPort("inertial_output"))
    builder.Connect(command or controller.GetOutputPort("joint_acceleration"), joint_acceleration)


def _add_logs(builder: DiagramBuilder, ports: dict, controller, time_step: float) -> dict:
    """Named VectorLogSinks of `ports` (name -> output port), plus the MCA's
    `statistics_log`, all sampled every `time_step`."""
    ports = ports | {"statistics_log": controller.GetOutputPort("statistics")}
    logs = {}
    for name, port in ports.items():
        logs[name] = LogVectorOutput(port, builder, time_step)
        logs[name].set_name(name)
    return logs


def MakeAnalyticalClosedLoop(
    reference: Reference,
    mca: McaConfig | str,
    robot: SerialChain,
    plausibility: PlausibilityConfig | None = None,
    comfort: ComfortConfig | None = None,
    scaling: ReferenceScaling | None = None,
) -> tuple[Diagram, dict]:
    """ReferenceSource -> ReferenceGuard -> (ReferenceScaler) -> MCA -> (CabinComfortBound)
    -> MotionCueingPlant,
    the MCA fed the plant state, with logs.

    The control period is the reference's time step. Logs (VectorLogSinks at the control
    period): `reference_log`, `state_log` (x_n at t_n), `command_log` and `statistics_log`.
    Publishing happens before the control update at the same instant, so the command logged
    at t_(n+1) is u_n, the one applied over [t_n, t_(n+1)).

    Args:
        reference: the target outputs.
        mca: an MCA config or name (`mca_drake.cueing`).
        robot: the platform the plant moves.
        plausibility: the reference guard's settings (default PlausibilityConfig();
            `enabled: false` leaves it out).
        comfort: the cabin comfort bound (`mca_drake.comfort`; None or disabled: none).
        scaling: the scaling the MCA cues at (`ReferenceScaler`; `reference` is at the
            default scaling; None or the default: no scaler).

    Returns:
        (diagram, handles) with the systems `source`, `guard` (None without one), `mca`,
        `comfort_bound` (None without one), `plant` and the logs (`command_log`: what the
        plant took). The `reference_log` is the reference itself, unguarded: runs
        are scored against what the vehicle did.
    """
    time_step = reference.time_step
    builder = DiagramBuilder()
    source, controller, initial_state, guard = _add_source_and_mca(
        builder, reference, mca, robot, plausibility, scaling
    )
    plant = builder.AddNamedSystem(
        "plant", MotionCueingPlant(robot=robot, time_step=time_step, initial_state=initial_state)
    )
    command, bound = AddComfortBound(
        builder,
        robot,
        comfort,
        controller.GetOutputPort("joint_acceleration"),
        plant.GetOutputPort("state"),
        time_step,
    )
    _connect_mca(
        builder,
        controller,
        plant.GetOutputPort("state"),
        plant.GetOutputPort("inertial_output"),
        plant.GetInputPort("joint_acceleration"),
        command,
    )
    handles = dict(source=source, guard=guard, mca=controller, comfort_bound=bound, plant=plant)
    ports = {
        "reference_log": source.GetOutputPort("reference"),
        "state_log": plant.GetOutputPort("state"),
        "command_log": _command_taken(controller, bound),
    }
    if guard is not None:
        ports["reaction_log"] = guard.GetOutputPort("reaction")
    handles |= _add_logs(builder, ports, controller, time_step)
    diagram = builder.Build()
    diagram.set_name("analytical_closed_loop")
    return diagram, handles


def MakeMultibodyClosedLoop(
    reference: Reference,
    mca: McaConfig | str,
    robot: SerialChain,
    station: StationConfig | None = None,
    meshcat=None,
    visualization: VisualizationConfig | None = None,
    plausibility: PlausibilityConfig | None = None,
    comfort: ComfortConfig | None = None,
    scaling: ReferenceScaling | None = None,
) -> tuple[Diagram, dict]:
    """ReferenceSource -> ReferenceGuard -> (ReferenceScaler) -> MCA -> (CabinComfortBound)
    -> SerialChain
    station (MultibodyPlant, inverse dynamics, head IMU), the MCA fed the station's
    measured state (and measured y where it reads one).

    Logs (at the control period, the reference's time step): `reference_log`,
    `command_log` (the MCA's joint accelerations), `desired_state_log` ([q_d, qd_d] the
    controller tracks), `measured_state_log` ([q, qd] of the MultibodyPlant),
    `measured_output_log` (y from the head IMU, without the measurement delay: what the
    occupant felt) and `statistics_log`.

    Args:
        reference: the target outputs (a `Reference`).
        mca: an MCA config or name (`mca_drake.cueing`).
        station: a `StationConfig` (default: 1 ms plant, 40 rad/s tracking, no limits,
            no noise, no delay).
        meshcat: a pydrake Meshcat to draw the robot, the cabin and live target/measured
            strip charts in; None for none.
        visualization: Drake's VisualizationConfig of the Meshcat drawing (publish period,
            illustration/proximity/inertia layers); default: illustration only at 30 Hz.
        plausibility: the reference guard's settings (default PlausibilityConfig();
            `enabled: false` leaves it out).
        comfort: the cabin comfort bound (`mca_drake.comfort`; None or disabled: none), on
            the station's measured state.
        scaling: the scaling the MCA cues at (`ReferenceScaler`; `reference` is at the
            default scaling; None or the default: no scaler).

    Returns:
        (diagram, handles): handles has `source`, `guard` (None without one), `mca`,
        `comfort_bound` (None without one), `station` (StationHandles) and the logs; call
        `handles["station"].SetInitialState(root_context)` before simulating (the robot
        starts at rest at the MCA's home pose).
    """
    time_step = reference.time_step
    builder = DiagramBuilder()
    source, controller, initial_state, guard = _add_source_and_mca(
        builder, reference, mca, robot, plausibility, scaling
    )
    station_handles = AddStation(
        builder,
        robot,
        station,
        initial_state,
        with_geometry=meshcat is not None,
        control_period=time_step,
    )
    command, bound = AddComfortBound(
        builder,
        robot,
        comfort,
        controller.GetOutputPort("joint_acceleration"),
        station_handles.measured_state,
        time_step,
        station=station if station is not None else StationConfig(),
    )
    _connect_mca(
        builder,
        controller,
        station_handles.measured_state,
        station_handles.measured_output,
        station_handles.joint_acceleration,
        command,
    )
    handles = dict(
        source=source, guard=guard, mca=controller, comfort_bound=bound, station=station_handles
    )
    ports = {
        "reference_log": source.GetOutputPort("reference"),
        "command_log": _command_taken(controller, bound),
        "desired_state_log": station_handles.desired_state,
        "measured_state_log": station_handles.true_state,
        "measured_output_log": station_handles.true_output,
    }
    if guard is not None:
        ports["reaction_log"] = guard.GetOutputPort("reaction")
    handles |= _add_logs(builder, ports, controller, time_step)
    if meshcat is not None:
        handles["traces"] = AddMeshcatDrawing(
            builder,
            meshcat,
            visualization,
            station_handles,
            source.GetOutputPort("reference"),
            time_step,
            robot,
        )
    diagram = builder.Build()
    diagram.set_name("multibody_closed_loop")
    return diagram, handles


def default_visualization() -> VisualizationConfig:
    """The Meshcat drawing of a closed loop: the robot and cabin (illustration) at 30 Hz,
    without the collision layer."""
    return VisualizationConfig(publish_period=1 / 30, publish_proximity=False)


def AddMeshcatDrawing(
    builder, meshcat, visualization, station_handles, reference_port, time_step, robot=None
):
    """Meshcat drawing of the station and the live target/measured strip charts (the target
    from `reference_port`), and a legged platform's legs (`robot`, a `LegPlatform`; the
    virtual chain's URDF draws only its base and moving platform); returns the
    MeshcatOutputTraces system.

    The drawing follows Drake's VisualizationConfig: the illustration and proximity layers
    with their colours, publish period and alpha sliders, as ApplyVisualizationConfig
    would draw them, but straight into `meshcat` with no LCM (nothing on the network).
    Contact and inertia layers are not drawn: a motion simulator touches nothing.
    """
    config = visualization if visualization is not None else default_visualization()
    layers = []
    if config.publish_illustration:
        layers.append((Role.kIllustration, config.default_illustration_color, True))
    if config.publish_proximity:
        color = config.default_proximity_color
        faded = Rgba(color.r(), color.g(), color.b(), config.initial_proximity_alpha)
        layers.append((Role.kProximity, faded, False))
    for role, color, visible in layers:
        params = MeshcatVisualizerParams(
            publish_period=config.publish_period,
            role=role,
            default_color=color,
            prefix="illustration" if role == Role.kIllustration else "proximity",
            delete_on_initialization_event=config.delete_on_initialization_event,
            enable_alpha_slider=config.enable_alpha_sliders,
            visible_by_default=visible,
        )
        MeshcatVisualizer.AddToBuilder(builder, station_handles.scene_graph, meshcat, params)
    # A view of the whole robot with the strip-chart board behind it, to its left.
    meshcat.SetCameraPose(np.array([3.5, -4.5, 3.2]), np.array([-0.5, 1.5, 1.6]))
    traces = builder.AddNamedSystem(
        "output_traces", MeshcatOutputTraces(meshcat, sample_period=time_step)
    )
    builder.Connect(reference_port, traces.GetInputPort("reference"))
    builder.Connect(station_handles.true_output, traces.GetInputPort("measured_output"))
    if isinstance(robot, LegPlatform):
        legs = builder.AddNamedSystem(
            "legs", MeshcatLegs(meshcat, robot, publish_period=config.publish_period)
        )
        builder.Connect(station_handles.true_state, legs.GetInputPort("state"))
    return traces
