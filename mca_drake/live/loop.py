"""The live closed loop: telemetry -> receiver -> MCA -> supervisor -> robot, in real time.

`MakeLiveClosedLoop` wires the diagram on the analytical plant or the platform's station;
`run_live` runs it at a real-time rate (1 by default) for a bounded time, paced against the
wall clock (and phase-locked to the sender), and returns the result summary with its
`live` block (`live_summary`: packets, bad, dropped and stale counts, the latency from a
sample's arrival to the first command computed from it, the time in each health state;
the PI scored against the reference that was received). The decoders are chosen by
protocol in `decoders`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import math
import socket
import sys
import time
from collections.abc import Callable

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import (
    Context,
    Diagram,
    DiagramBuilder,
    EventStatus,
    InputPort,
    LeafSystem,
    OutputPort,
)

from mca_drake.atomic_io import atomic_write_text
from mca_drake.comfort import ComfortConfig, comfort_block
from mca_drake.cueing import McaConfig, as_mca_config
from mca_drake.cueing.dpc import DpcConfig, for_vehicle, policy_record
from mca_drake.cueing.plausibility import PlausibilityConfig
from mca_drake.live.control_inputs import control_inputs
from mca_drake.live.controls import ControlsConfig
from mca_drake.live.decoders import PROTOCOLS, make_decoder
from mca_drake.live.live_summary import (
    STALL_PERIODS,
    PacedRun,
    live_block,
    live_signals,
    live_trajectory,
    rsi_block,
    scored_summary,
)
from mca_drake.live.operator import OperatorConsole
from mca_drake.live.pacing import RealTimePacer
from mca_drake.live.phase_lock import PhaseLockConfig, phase_correction
from mca_drake.live.pose_stream import PoseStreamSender
from mca_drake.live.receiver import TELEMETRY_FIELDS, ReceiverConfig, TelemetryReceiver
from mca_drake.live.recorder import BEFORE_POLL_S, LiveRecorder
from mca_drake.live.rig_output import RigConnection, RigOutputConfig, RigOutputSender
from mca_drake.live.rsi.driver import RsiDriverConfig
from mca_drake.live.rsi.link import (
    RobotClockServo,
    RsiCommandSender,
    segment_socket_pair,
    start_rsi_driver,
    wait_for_robot,
)
from mca_drake.live.supervisor import Supervisor, SupervisorConfig
from mca_drake.live.telemetry import Decoder
from mca_drake.platforms.serial import SerialChain
from mca_drake.references.reference import ReferenceScaling
from mca_drake.simulation.builders import (
    AddComfortBound,
    AddMca,
    AddMeshcatDrawing,
    AddReferenceGuard,
    default_visualization,
)
from mca_drake.simulation.closed_loop import (
    PLANTS,
)
from mca_drake.systems import MotionCueingPlant
from mca_drake.systems.meshcat_traces import MeshcatOutputTraces
from mca_drake.systems.predictor import AddReferencePredictor
from mca_drake.systems.reference_scaling import AddReferenceScaling
from mca_drake.systems.station import AddStation, StationConfig

_ARRIVAL = TELEMETRY_FIELDS.index("arrival_s")
_POLL = TELEMETRY_FIELDS.index("poll_s")
# The probe publishes this long (s) after each control instant: Drake handles a publish at
# time t at the end of the step that reaches t, before that instant's updates, so a probe at
# the instant itself would read the command computed one period earlier, from the previous
# sample.
PROBE_DELAY_S = 1e-5
# The analytical plant steps this long (s) after each control instant: after the probe and
# the recorder (`live.recorder.AFTER_COMMAND_S`), so that its step and the clamp it would
# re-evaluate are not between a sample and its command, and it integrates the very command
# that was recorded.
PLANT_DELAY_S = 2e-5
# The supervisor judges the loop this long (s) after each control instant: after the plant's
# step (its new blend weight would change the command the plant integrates).
JUDGE_DELAY_S = 2.5e-5


class LatencyProbe(LeafSystem):
    """Measures, just after every control instant's updates (`PROBE_DELAY_S`), the wall time
    from the arrival of the newest telemetry sample to the command computed from it (once
    per sample), and how long that sample waited in the socket for its poll.

    Input `telemetry` (TELEMETRY_FIELDS) and `command` (n, the platform's joints: the
    command the robot gets now).
    `latencies_s` holds the latencies, `waits_s` the waits (poll - arrival) and
    `instants_s` the wall time of every control instant; `arrivals_s` and
    `sample_instants` the arrival and control instant index of every new sample.
    """

    def __init__(self, time_step: float, joints: int):
        super().__init__()
        self._telemetry = self.DeclareVectorInputPort("telemetry", len(TELEMETRY_FIELDS))
        self._command = self.DeclareVectorInputPort("command", joints)
        self.DeclarePeriodicPublishEvent(time_step, PROBE_DELAY_S, self._probe)
        self._time_step = time_step
        self.latencies_s: list[float] = []
        self.waits_s: list[float] = []
        # per new sample: its arrival (time.perf_counter()) and its control instant's index
        self.arrivals_s: list[float] = []
        self.sample_instants: list[int] = []
        # wall time of every control instant (after its updates): the loop's jitter
        self.instants_s: list[float] = []
        self._last_arrival = float("nan")

    def _probe(self, context: Context) -> EventStatus:
        self._command.Eval(context)  # the command the robot gets now
        now = time.perf_counter()
        self.instants_s.append(now)
        telemetry = self._telemetry.Eval(context)
        arrival = float(telemetry[_ARRIVAL])
        if np.isfinite(arrival) and arrival != self._last_arrival:
            self.latencies_s.append(now - arrival)
            self.waits_s.append(float(telemetry[_POLL]) - arrival)
            self.arrivals_s.append(arrival)
            self.sample_instants.append(round(context.get_time() / self._time_step))
            self._last_arrival = arrival
        return EventStatus.Succeeded()


@dataclasses.dataclass
class _LiveRobotPorts:
    """The robot of a live loop in its diagram: the ports the loop wires to it."""

    handles: dict  # {"plant": MotionCueingPlant} or {"station": StationHandles}
    state: OutputPort  # x = [q, qd] the MCA reads (measured, on the station)
    inertial_output: OutputPort  # y the MCA may read
    joint_acceleration: InputPort  # the command
    before_poll: dict  # the station's true state and output, recorded before each poll


def _AddLiveRobot(
    builder: DiagramBuilder,
    plant: str,
    robot: SerialChain,
    h: float,
    initial_state: np.ndarray,
    station: StationConfig | None,
    with_geometry: bool,
) -> _LiveRobotPorts:
    """Adds the analytical plant or the KR500 station, starting at `initial_state`."""
    if plant == "analytical":
        # the plant steps after the command has gone out (PLANT_DELAY_S), with that command
        system = builder.AddNamedSystem(
            "plant",
            MotionCueingPlant(
                robot=robot, time_step=h, initial_state=initial_state, update_offset_s=PLANT_DELAY_S
            ),
        )
        return _LiveRobotPorts(
            {"plant": system},
            system.GetOutputPort("state"),
            system.GetOutputPort("inertial_output"),
            system.GetInputPort("joint_acceleration"),
            {},
        )
    station = station or StationConfig()
    if BEFORE_POLL_S >= station.plant_time_step:
        # the recorder reads the station just before the poll, as it is at t_k
        raise ValueError(
            f"the station's plant_time_step ({station.plant_time_step} s) must be longer "
            f"than the live recorder's {BEFORE_POLL_S} s before the poll"
        )
    handles = AddStation(
        builder, robot, station, initial_state, with_geometry=with_geometry, control_period=h
    )
    return _LiveRobotPorts(
        {"station": handles},
        handles.measured_state,
        handles.measured_output,
        handles.joint_acceleration,
        {"measured_output": handles.true_output, "true_state": handles.true_state},
    )


def _AddLiveRecorder(
    builder: DiagramBuilder, before_poll: dict, after_command: dict, h: float
) -> LiveRecorder:
    """Adds the LiveRecorder of the named ports and connects them."""
    recorder = builder.AddNamedSystem(
        "recorder",
        LiveRecorder(
            {name: port.size() for name, port in before_poll.items()},
            {name: port.size() for name, port in after_command.items()},
            h,
        ),
    )
    for name, port in (before_poll | after_command).items():
        builder.Connect(port, recorder.GetInputPort(name))
    return recorder


def _ConnectMcaToSupervisor(
    builder: DiagramBuilder,
    source: TelemetryReceiver,
    controller,
    guard: Supervisor,
    robot_ports: _LiveRobotPorts,
    time_step: float,
    plausibility: PlausibilityConfig | None = None,
    console: OperatorConsole | None = None,
    scaling: ReferenceScaling | None = None,
):
    """Wires the receiver's reference (through the reference guard, `AddReferenceGuard`,
    the scenario's scaling, `AddReferenceScaling`, and the operator's `console`, if any)
    and the robot's state into the MCA, and the MCA's
    command, statistics, the telemetry and the operator's mode into the supervisor that
    judges them (the supervisor reads the reference as received: its NaN and stale checks
    are its own); returns the reference guard (None: disabled)."""
    reference = source.GetOutputPort("reference")
    # the guard's step is committed with the supervisor's judgement, after the command
    guarded, reference_guard = AddReferenceGuard(
        builder, reference, plausibility, time_step, JUDGE_DELAY_S
    )
    # the operator's intensity and gains act on the reference at the scenario's scaling
    guarded, _ = AddReferenceScaling(builder, guarded, scaling)
    if console is not None:
        builder.Connect(guarded, console.GetInputPort("reference"))
        guarded = console.GetOutputPort("scaled_reference")
        builder.Connect(console.GetOutputPort("mode"), guard.GetInputPort("operator"))
    builder.Connect(guarded, controller.GetInputPort("reference"))
    # a predictive MCA's forecast, from what it has read, moved in its own (discrete) phase
    forecast = AddReferencePredictor(
        builder,
        controller,
        guarded,
        time_step,
        "discrete",
        signals_port=source.GetOutputPort("signals"),
    )
    if forecast is not None:
        builder.Connect(forecast, controller.GetInputPort("reference_preview"))
    builder.Connect(robot_ports.state, controller.GetInputPort("state"))
    if controller.HasInputPort("inertial_output"):
        builder.Connect(robot_ports.inertial_output, controller.GetInputPort("inertial_output"))
    builder.Connect(robot_ports.state, guard.GetInputPort("state"))
    builder.Connect(
        controller.GetOutputPort("joint_acceleration"), guard.GetInputPort("mca_command")
    )
    builder.Connect(reference, guard.GetInputPort("reference"))
    builder.Connect(source.GetOutputPort("telemetry"), guard.GetInputPort("telemetry"))
    builder.Connect(controller.GetOutputPort("statistics"), guard.GetInputPort("mca_statistics"))
    return reference_guard


def MakeLiveClosedLoop(
    decoder: Decoder,
    mca: McaConfig | str,
    *,
    plant: str = "analytical",
    receiver: ReceiverConfig | None = None,
    supervisor: SupervisorConfig | None = None,
    scaling: ReferenceScaling | None = None,
    robot: SerialChain,
    station: StationConfig | None = None,
    meshcat=None,
    rsi_commands: socket.socket | None = None,
    plausibility: PlausibilityConfig | None = None,
    controls: ControlsConfig | None = None,
    control_sources: list | None = None,
    comfort: ComfortConfig | None = None,
    rig: tuple | None = None,
    pose_stream: str = "",
) -> tuple[Diagram, dict]:
    """TelemetryReceiver -> ReferenceGuard -> OperatorConsole -> MCA -> Supervisor -> robot,
    with logs and a LatencyProbe; the robot is the analytical plant or the platform's
    station (multibody, drawn in `meshcat` if given; on the analytical plant `meshcat`
    shows the traces of the reference and the cue). The control period is
    `receiver.time_step`.

    Returns:
        (diagram, handles): the systems `receiver`, `mca`, `supervisor`, `probe`,
        `recorder` (`live.recorder.LiveRecorder`) and `plant` (analytical) or `station`
        (StationHandles: call its SetInitialState). The recorder holds, before each poll,
        `state` (the state the MCA reads), `statistics`, `health` and, on the station,
        `true_state` and `measured_output` (the head IMU without its delay: what the occupant
        felt); after each command, `reference` and `command` (what the robot got).
        With `rsi_commands` (the loop's end of `live.rsi.link.segment_socket_pair`; the
        analytical plant only: its trajectory is the one a real robot follows), an
        `RsiCommandSender` `rsi` sends every period's command segment there; `home` is the
        MCA's home pose (rad), where the robot must start. `console` is the
        OperatorConsole of `controls` (the run's first settings) reading `control_sources`
        (`live.control_inputs`); with neither, the MCA reads the guarded reference as it is.
        `comfort_bound` is the CabinComfortBound of `comfort` between the supervisor and the
        robot (None where `comfort` is absent or disabled). With `rig` (an open
        `live.rig_output.RigConnection` and its RigOutputConfig), a RigOutputSender `rig`
        sends the actuator positions every period; with `pose_stream` (udp://HOST:PORT), a
        PoseStreamSender `pose_stream` sends the head's pose relative to home.
    """
    if plant not in PLANTS:
        raise ValueError(f"unknown plant '{plant}'; valid: {', '.join(PLANTS)}")
    if rsi_commands is not None and plant != "analytical":
        raise ValueError(
            "a robot over RSI follows the analytical plant's trajectory: use plant 'analytical'"
        )
    receiver_config = receiver or ReceiverConfig()
    h = receiver_config.time_step
    builder = DiagramBuilder()
    source = builder.AddNamedSystem("receiver", TelemetryReceiver(decoder, receiver_config))
    # the MCA's step after the poll, in the poll's simulator step (`systems.mca_update`)
    controller = AddMca(builder, mca, robot, h, update_event="discrete")
    n = robot.num_joints
    home = getattr(controller, "home_position", np.zeros(n))
    guard = builder.AddNamedSystem(
        "supervisor",
        Supervisor(
            supervisor or SupervisorConfig(time_step=h), robot, home, judge_offset_s=JUDGE_DELAY_S
        ),
    )
    handles = dict(receiver=source, mca=controller, supervisor=guard, home=home)
    robot_ports = _AddLiveRobot(
        builder, plant, robot, h, np.r_[home, np.zeros(n)], station, meshcat is not None
    )
    handles |= robot_ports.handles
    state, inertial_output = robot_ports.state, robot_ports.inertial_output
    before_poll = dict(robot_ports.before_poll)
    probe = builder.AddNamedSystem("probe", LatencyProbe(h, n))
    handles["probe"] = probe
    reference = source.GetOutputPort("reference")
    console = None
    if controls is not None or control_sources:
        console = builder.AddNamedSystem(
            "operator",
            OperatorConsole(controls, control_sources or [], h, update_offset_s=JUDGE_DELAY_S),
        )
    handles["operator"] = console
    handles["reference_guard"] = _ConnectMcaToSupervisor(
        builder, source, controller, guard, robot_ports, h, plausibility, console, scaling
    )
    command, handles["comfort_bound"] = AddComfortBound(
        builder,
        robot,
        comfort,
        guard.GetOutputPort("joint_acceleration"),
        state,
        h,
        PLANT_DELAY_S,  # the analytical plant steps after the command has gone out
        None if plant == "analytical" else (station or StationConfig()),
    )
    builder.Connect(command, robot_ports.joint_acceleration)
    builder.Connect(source.GetOutputPort("telemetry"), probe.GetInputPort("telemetry"))
    builder.Connect(command, probe.GetInputPort("command"))
    if rig is not None:
        rig_sender = builder.AddNamedSystem("rig", RigOutputSender(rig[0], rig[1], h, robot))
        builder.Connect(state, rig_sender.GetInputPort("state"))
        builder.Connect(command, rig_sender.GetInputPort("command"))
        handles["rig"] = rig_sender
    if pose_stream:
        poses = builder.AddNamedSystem("pose_stream", PoseStreamSender(pose_stream, robot, home, h))
        builder.Connect(state, poses.GetInputPort("state"))
        builder.Connect(command, poses.GetInputPort("command"))
        handles["pose_stream"] = poses
    if rsi_commands is not None:
        sender = builder.AddNamedSystem("rsi", RsiCommandSender(rsi_commands, h, robot.num_joints))
        builder.Connect(state, sender.GetInputPort("state"))
        builder.Connect(command, sender.GetInputPort("command"))
        handles["rsi"] = sender
    # recorded off the path from a sample to its command (`live.recorder`)
    before_poll |= {
        "state": state,
        # the output the MCA reads: computed here, before the poll, it is cached for the MCA
        "inertial_output": inertial_output,
        "statistics": controller.GetOutputPort("statistics"),
        "health": guard.GetOutputPort("health"),
    }
    # the reference and the controls and vehicle state of the sample it came from
    after_command = {
        "reference": reference,
        "command": command,
        "signals": source.GetOutputPort("signals"),
    }
    if handles["reference_guard"] is not None:  # what the guard did in the period
        after_command["reaction"] = handles["reference_guard"].GetOutputPort("reaction")
    if console is not None:  # the operator's settings and mode in the period
        after_command["settings"] = console.GetOutputPort("settings")
        after_command["mode"] = console.GetOutputPort("mode")
    handles["recorder"] = _AddLiveRecorder(builder, before_poll, after_command, h)
    if meshcat is not None and plant == "multibody":
        handles["traces"] = AddMeshcatDrawing(
            builder, meshcat, default_visualization(), handles["station"], reference, h, robot
        )
    elif meshcat is not None:  # no geometry to draw: the traces of the reference and cue
        traces = MeshcatOutputTraces(meshcat, sample_period=h)
        handles["traces"] = builder.AddNamedSystem("output_traces", traces)
        builder.Connect(reference, traces.GetInputPort("reference"))
        builder.Connect(inertial_output, traces.GetInputPort("measured_output"))
    diagram = builder.Build()
    diagram.set_name(f"live_{plant}_closed_loop")
    return diagram, handles


def run_live(
    decoder: Decoder,
    mca: McaConfig | str,
    duration_s: float,
    *,
    receiver: ReceiverConfig | None = None,
    supervisor: SupervisorConfig | None = None,
    scaling: ReferenceScaling | None = None,
    realtime_rate: float = 1.0,
    on_listening: Callable[[tuple[str, int]], None] | None = None,
    robot: SerialChain,
    plant: str = "analytical",
    station: StationConfig | None = None,
    meshcat=None,
    phase_lock: PhaseLockConfig | None = None,
    rsi: RsiDriverConfig | None = None,
    plausibility: PlausibilityConfig | None = None,
    trajectory: str | None = None,
    controls: ControlsConfig | None = None,
    keyboard_fd: int | None = None,
    comfort: ComfortConfig | None = None,
    rig: RigOutputConfig | None = None,
    pose_stream: str = "",
) -> dict:
    """Runs the live loop for `duration_s` (s of simulated time, at `realtime_rate`) and
    returns its summary with the `live` block.

    Args:
        on_listening: called with the bound (host, port) once the socket is open, before the
            loop starts (the CLI prints `listening on udp://HOST:PORT`; tests start senders).
        realtime_rate: Drake's target real-time rate (1: live; 0: as fast as possible).
        robot: the platform cued (its limits are the supervisor's and the clamp's).
        plant: "analytical" or "multibody" (the platform's station; `station` its settings,
            `meshcat` a pydrake Meshcat to draw it in; on the analytical plant it shows the
            traces of the reference and the cue). `meshcat` also carries the operator page
            (`controls`), on either plant.
        phase_lock: how the loop follows a periodic sender's phase (`live.phase_lock`;
            default on), so that samples wait little for their poll; at real-time rates only.
        rsi: drive a KUKA robot over RSI (`live.rsi.driver`; analytical plant, real time):
            the driver starts in its own process before the loop (with port 0 it takes a
            free port, written back into `rsi.port` before `on_listening`) and brakes the
            robot to rest after it; its counters are the summary's `rsi` block. The driver refuses
            (and the run ends with RuntimeError) if the robot is not at the MCA's home pose.
        plausibility: the reference guard in front of the MCA (`cueing.plausibility`;
            default on); its counts are the summary's `plausibility` block.
        scaling: the scaling the MCA cues at (`references.reference.ReferenceScaling`,
            applied behind the guard and before the operator's gains; default: the default
            scaling); the run is scored against the telemetry at the default scaling, and the
            summary's `scaling` block records it.
        trajectory: a CSV path for the run's time series (`simulation.trajectory`, with the
            supervisor's health per period), written atomically after the run.
        controls: the operator's controls (`live.controls`; default: the run's settings at
            1, no UDP port): intensity, gains, pause, wash-out and emergency stop from the
            UDP control port, the keyboard of `keyboard_fd` (a terminal; the CLI passes its
            stdin) and the operator page in `meshcat`; its log is the summary's `controls`
            block.
        comfort: the cabin comfort bound between the supervisor and the robot
            (`mca_drake.comfort`; default none: it costs two evaluations of the plant
            output on the path from a sample to its command); its counts are the summary's
            `comfort` block.
        rig: the rig's own output (`live.rig_output`: the actuator positions each period
            over UDP or a serial port; default none); its counts are the summary's `rig`
            block.
        pose_stream: udp://HOST:PORT for the head's pose relative to home each period
            (`live.pose_stream`, for VR motion compensation; "": none).
    """
    if not 0 < duration_s <= 24 * 3600:
        raise ValueError(f"duration_s must be in (0, 86400] s; got {duration_s}")
    # a DPC that names no vehicle cues the protocol's kind (a racing simulator's: a car)
    config = for_vehicle(as_mca_config(mca), decoder.vehicle)
    lock = phase_lock or PhaseLockConfig()
    lock.validate()
    rc = receiver or ReceiverConfig()
    h = rc.time_step
    loop_end = driver_end = None
    if rsi is not None:
        if realtime_rate != 1.0:
            raise ValueError("a robot over RSI runs in real time: realtime_rate must be 1")
        rsi.period_s = h
        rsi.validate()
        loop_end, driver_end = segment_socket_pair()
    controls = controls or ControlsConfig()
    controls.validate()
    if rig is not None and rig.url:
        rig.validate(robot.num_joints)
    with control_inputs(controls, meshcat, keyboard_fd) as sources, _rig(rig) as connection:
        diagram, handles = MakeLiveClosedLoop(
            decoder,
            config,
            plant=plant,
            receiver=receiver,
            supervisor=supervisor,
            scaling=scaling,
            robot=robot,
            station=station,
            meshcat=meshcat,
            rsi_commands=loop_end,
            plausibility=plausibility,
            controls=controls if controls.enabled else None,
            control_sources=sources,
            comfort=comfort,
            rig=None if connection is None else (connection, rig),
            pose_stream=pose_stream,
        )
        run = _run_paced(
            diagram,
            handles,
            duration_s=duration_s,
            realtime_rate=realtime_rate,
            lock=lock,
            h=h,
            plant=plant,
            on_listening=on_listening,
            rsi=rsi,
            robot=robot,
            sockets=(loop_end, driver_end),
        )
    summary = scored_summary(handles, config, plant, decoder, robot, h, run.wall_s)
    summary["live"] = live_block(handles, run, decoder, realtime_rate, h)
    summary["scaling"] = (scaling or ReferenceScaling()).record()
    reference_guard = handles["reference_guard"]
    if reference_guard is not None:
        summary["plausibility"] = reference_guard.summary(
            reference_guard.GetMyContextFromRoot(run.context)
        )
    if isinstance(config, DpcConfig):
        mca = handles["mca"]
        changes = mca.policy_changes(mca.GetMyContextFromRoot(run.context))
        reference = handles["recorder"].rows("reference")
        summary |= policy_record(config, robot.name, changes, reference, h)
    console = handles["operator"]
    if console is not None:
        guard = handles["supervisor"]
        _, rest_at = guard.estop_times(guard.GetMyContextFromRoot(run.context))
        to_rest = rest_at - console.estop["t_s"] if console.estop is not None else math.nan
        context = console.GetMyContextFromRoot(run.context)
        summary["controls"] = console.summary(context, to_rest)
    if handles.get("rig") is not None:
        probe = handles["probe"]
        summary["rig"] = handles["rig"].summary(probe.arrivals_s, probe.sample_instants)
    if handles.get("pose_stream") is not None:
        handles["pose_stream"].close()
        summary["pose_stream"] = handles["pose_stream"].summary()
    bound = handles["comfort_bound"]
    if bound is not None:
        outputs = live_signals(handles, plant, robot, h)[1]
        scaled = bound.bounded_periods(bound.GetMyContextFromRoot(run.context))
        summary["comfort"] = comfort_block(outputs, bound.config, scaled)
    if run.rsi_status is not None:
        summary["rsi"] = rsi_block(handles, run)
    if trajectory:
        atomic_write_text(trajectory, live_trajectory(handles, plant, robot, h))
    return summary


@contextlib.contextmanager
def _rig(config: RigOutputConfig | None):
    """The rig output's open connection for the `with` block (None: no output)."""
    if config is None or not config.url:
        yield None
        return
    connection = RigConnection(config)
    try:
        yield connection
    finally:
        connection.close()


def _run_paced(
    diagram: Diagram,
    handles: dict,
    *,
    duration_s: float,
    realtime_rate: float,
    lock: PhaseLockConfig,
    h: float,
    plant: str,
    on_listening,
    rsi: RsiDriverConfig | None,
    robot: SerialChain,
    sockets: tuple,
) -> PacedRun:
    """Starts the robot's driver (with `rsi`), runs the diagram paced to the wall clock and
    closes the socket and the driver whatever happens."""
    source = handles["receiver"]
    loop_end, driver_end = sockets
    link = pacer = servo = None
    notices: list[str] = []
    try:
        if rsi is not None:
            link = start_rsi_driver(rsi, robot, handles["home"], driver_end)
            rsi.port = link.address[1]  # the port it got (port 0: any free one)
        simulator = Simulator(diagram)
        # the loop paces itself (`live.pacing`): the poll on time, the MCA right after it
        if realtime_rate > 0:
            pacer = RealTimePacer(
                h,
                realtime_rate,
                max_slew_per_period_s=lock.max_slew_s * h / lock.window_s,
                wake_socket=source if lock.enabled else None,
                wake_window_s=lock.wake_window_s if lock.enabled else 0.0,
            )
            simulator.set_monitor(pacer)
        if plant == "multibody":
            handles["station"].SetInitialState(simulator.get_mutable_context())
        simulator.Initialize()
        if on_listening is not None:
            on_listening(source.address)
        if link is not None:
            wait_for_robot(loop_end, link, rsi.connect_timeout_s)
            servo = RobotClockServo(loop_end, pacer)
        # Everything built so far (torch, Drake, the diagram) leaves the garbage collector's
        # view: a full collection of it took about 0.1 s, a stall in the loop whenever one
        # came due; the loop's own garbage is still collected.
        gc.collect()
        gc.freeze()
        start, cpu_start = time.perf_counter(), time.process_time()
        if pacer is not None:
            pacer.start()
        shifts = _advance_phase_locked(
            simulator, handles, duration_s, pacer, lock, h, link, servo, notices
        )
        wall_s = time.perf_counter() - start
        cpu_s = time.process_time() - cpu_start
        if link is not None:
            sender = handles["rsi"]
            sender.finish(sender.GetMyContextFromRoot(simulator.get_context()))
    finally:
        gc.unfreeze()
        source.close()
        rsi_status = link.stop() if link is not None else None
        for end in sockets:
            if end is not None:
                end.close()
    return PacedRun(
        simulator.get_context(), wall_s, cpu_s, shifts, pacer, link, servo, rsi_status, notices
    )


def _check_driver(link) -> None:
    """Raises RuntimeError if the RSI driver process has ended (it refused the robot, or
    died): the loop must not go on cueing a robot nobody drives."""
    if link is not None and link.process.poll() is not None:
        raise RuntimeError(f"the RSI driver ended during the run: {link.stop_and_say_why()}")


def _advance_phase_locked(
    simulator, handles, duration_s, pacer, lock, period_s, link=None, servo=None, notices=None
):
    """Advances to `duration_s` in windows of `lock.window_s`; after a window measured at a
    steady phase, the phase lock's correction (`phase_correction` of the samples' waits for
    the time their poll was due) becomes the pacer's new target phase, which it slews to
    within the next window (measured only after that). Between windows the RSI driver of
    `link` (if any) is checked alive (`_check_driver`) and the loop's clock follows the
    robot's (`servo`). No pacer (as fast as possible) or no lock, and no driver: one
    AdvanceTo past the first look and one to the end. After the loop's first
    FIRST_LOOK_S, `first_look` tells the user (stderr, and `notices`) when every datagram
    so far was refused. Returns the shifts."""
    probe, source = handles["probe"], handles["receiver"]
    notices = [] if notices is None else notices
    looked = False

    def look() -> None:
        nonlocal looked
        if not looked and simulator.get_context().get_time() >= FIRST_LOOK_S - 1e-9:
            looked = True
            notice = first_look(source, simulator.get_context())
            if notice:
                notices.append(notice)
                print(f"mca-drake live: {notice}", file=sys.stderr, flush=True)

    locked = pacer is not None and lock.enabled
    if not locked and link is None:
        simulator.AdvanceTo(min(duration_s, FIRST_LOOK_S))
        look()
        simulator.AdvanceTo(duration_s)
        return []
    shifts, measured_from, shift = [], 0, 0.0
    while simulator.get_context().get_time() < duration_s - 1e-9:
        _check_driver(link)
        if servo is not None:
            servo.update()
        look()
        t = simulator.get_context().get_time()
        if not locked:
            simulator.AdvanceTo(min(duration_s, _window_end(t, lock.window_s, period_s)))
            continue
        # a window right after a shift only measures (its waits show the new phase)
        shift = (
            0.0
            if shift
            else phase_correction(_waits_for_due(probe, pacer, measured_from), period_s, lock)
        )
        measured_from = len(probe.arrivals_s)
        if shift:
            shifts.append(shift)
            pacer.target_phase_s += shift
        simulator.AdvanceTo(min(duration_s, _window_end(t, lock.window_s, period_s)))
    return shifts


# After this much loop time (s), a run whose every datagram was refused is told why.
FIRST_LOOK_S = 1.0


def first_look(source: TelemetryReceiver, context) -> str:
    """What to tell a user whose datagrams, all of them so far, the receiver `source`
    refused (a protocol or format the decoder does not read, a sender not allowed, a clock
    that jumps), with the last reason; "" when none came or one was taken."""
    counters = source.counters(source.GetMyContextFromRoot(context))
    if counters["packets"] == 0 or math.isfinite(counters["arrival_s"]):
        return ""
    return (
        f"all {int(counters['packets'])} datagrams so far were refused "
        f"({int(counters['bad'])} not read as {source.protocol} packets, "
        f"{int(counters['foreign'])} from other senders, {int(counters['time_jumps'])} off "
        f"the sender's clock); the last: {source.last_refusal}. Check --protocol and the "
        "sender's output settings (docs: Live telemetry)"
    )


def _window_end(t: float, window_s: float, period_s: float) -> float:
    """Where a phase-lock window from `t` ends: about `window_s` later, in the middle of a
    control period. Between windows Python runs the lock's arithmetic and re-enters
    AdvanceTo (0.3-1 ms); ending at a control instant would put that between the pacer's
    wait for the sample and its poll, in one sample's latency of every fifty (the whole
    p99)."""
    return (math.floor((t + window_s) / period_s) + 0.5) * period_s


def _waits_for_due(probe: LatencyProbe, pacer: RealTimePacer, first: int) -> np.ndarray:
    """(time the poll was due - arrival) of the probe's samples from index `first`, s: the
    phase the lock follows, which a poll brought forward by the sample itself would hide."""
    due = dict(pacer.dues)
    return np.array(
        [
            due[k] - arrival
            for k, arrival in zip(
                probe.sample_instants[first:], probe.arrivals_s[first:], strict=True
            )
            if k in due
        ]
    )


__all__ = [
    "PROTOCOLS",
    "STALL_PERIODS",
    "LatencyProbe",
    "MakeLiveClosedLoop",
    "make_decoder",
    "run_live",
]
