"""Supervisor: the health of a live loop, and a safe wash-out to home when it fails.

Between the MCA and the robot. Every control period it judges the loop:

- fault: no telemetry yet, telemetry not fresh (no sample for `stale_after_s`), a reference
  that is not finite or beyond `max_reference`, an MCA command that is not finite, or
  `overruns_to_fault` MCA steps in a row over `step_budget_s`;
- degraded: one MCA step over budget, or telemetry older than half `stale_after_s`;
- ok otherwise. A fault clears only after `recovery_s` without any fault condition; the
  wait for the first sample ("no telemetry yet") clears with that sample.

The command it passes on blends the MCA's command u_mca and a wash-out command u_home with a
weight w that moves toward 0 in a fault and toward 1 otherwise, over `blend_s`, so that
neither leaving nor rejoining the MCA jumps in acceleration:

    u = clamp(w u_mca + (1 - w) u_home),   u_home = sat(-omega^2 q - 2 omega qd)

(critically damped return to the home pose, q = 0 or the MCA's own, at most
`home_acceleration_fraction` of each joint's acceleration limit). A non-finite MCA command
sets w = 0 at once.

The operator (`live.operator.OperatorConsole`, its `mode` on the optional `operator` input)
can ask for the same wash-out (mode washout: w moves toward 0 while the health state stays
what it is) or an emergency stop (mode estop): from the next command on, every joint brakes
to rest at `estop_acceleration_fraction` of its acceleration limit,

    u = sat(-qd / h),

and stays there for the rest of the run; the time it came to rest (every |qd| below
`REST_SPEED`) is kept (`estop_times`).

Whatever the blend, the command passes the exact viability clamp of `mca_drake.safety`, so
the robot stays inside its limits. Every transition is counted and
logged (`Supervisor.transitions`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State

from mca_drake.conventions import CONTROL_PERIOD_S, NUM_CHANNELS
from mca_drake.input_checks import check_config_numbers
from mca_drake.live.controls import ESTOP, RUN, WASHOUT
from mca_drake.live.receiver import TELEMETRY_FIELDS
from mca_drake.platforms.clamp import platform_clamp
from mca_drake.platforms.serial import SerialChain

HEALTH_STATES = ("ok", "degraded", "fault")
# The `health` output port, in this order.
HEALTH_FIELDS = ("state", "transitions", "ok_s", "degraded_s", "fault_s", "weight")
_STATE, _TRANSITIONS, _OK_S, _DEGRADED_S, _FAULT_S, _WEIGHT, _CLEAR_S, _OVERRUNS = range(8)
_ESTOP_AT, _REST_AT = 8, 9  # loop time of the emergency stop and of rest after it (nan: none)
_STREAMING = 10  # 1 once the first telemetry sample has come
# The robot is at rest when every joint is slower than this (rad/s or m/s).
REST_SPEED = 1e-3
_AGE, _FRESH = TELEMETRY_FIELDS.index("age_s"), TELEMETRY_FIELDS.index("fresh")


@dataclasses.dataclass
class SupervisorConfig:
    """When the loop is unhealthy, and how the robot goes home."""

    # No new telemetry sample for this long (s): fault.
    stale_after_s: float = 0.1
    # An MCA step longer than this (s) is an overrun (degraded); this many in a row: fault.
    step_budget_s: float = 0.008
    overruns_to_fault: int = 3
    # A fault clears after this long (s) without a fault condition.
    recovery_s: float = 0.5
    # Time (s) over which the command moves between the MCA and the wash-out.
    blend_s: float = 0.3
    # Natural frequency (Hz) of the critically damped return home, and the fraction of each
    # joint's acceleration limit it may use.
    home_frequency_hz: float = 0.3
    home_acceleration_fraction: float = 0.5
    # The fraction of each joint's acceleration limit an emergency stop brakes with.
    estop_acceleration_fraction: float = 1.0
    # Largest sane |y_ref| per channel (rad/s, m/s^2): beyond is a fault (a unit error).
    max_reference: tuple[float, ...] = (5.0, 5.0, 5.0, 50.0, 50.0, 50.0)
    # Control period, s.
    time_step: float = CONTROL_PERIOD_S

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        positive = (
            "stale_after_s",
            "step_budget_s",
            "recovery_s",
            "blend_s",
            "time_step",
            "home_frequency_hz",
        )
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"SupervisorConfig.{name} must be positive")
        if self.overruns_to_fault < 1:
            raise ValueError("SupervisorConfig.overruns_to_fault must be at least 1")
        for name in ("home_acceleration_fraction", "estop_acceleration_fraction"):
            if not 0 < getattr(self, name) <= 1:
                raise ValueError(f"SupervisorConfig.{name} must be in (0, 1]")
        if len(self.max_reference) != NUM_CHANNELS or min(self.max_reference) <= 0:
            raise ValueError("SupervisorConfig.max_reference must be six positive values")


class Supervisor(LeafSystem):
    """Health state machine and safe command (see the module docstring).

    .. pydrake_system::

        name: Supervisor
        input_ports:
        - state
        - mca_command
        - reference
        - telemetry
        - mca_statistics
        - operator
        output_ports:
        - joint_acceleration
        - health

    Inputs: the robot's `state` [q, qd] (2n for n joints), the MCA's `mca_command` (n,
    rad/s^2 or m/s^2), the `reference` the MCA cues (6), the receiver's `telemetry`
    (TELEMETRY_FIELDS), the MCA's `mca_statistics` (MCA_STATISTICS: its step time
    first) and, optionally, the operator's `mode` (`operator`, 1: index in
    `live.controls.MODES`; unconnected: run). `joint_acceleration` (n) is the
    supervised command (direct feedthrough of the command and the state); `health`
    (HEALTH_FIELDS) holds the state (0 ok, 1 degraded, 2 fault), the transitions, the time
    spent in each state (s) and the blend weight.

    Args:
        config: thresholds and the wash-out.
        robot: the limits the command is clamped to.
        home_position: the pose the wash-out returns to, shape (n,); default q = 0 (the MCA's
            own home where it has one: the classical washout's is not zero).
        judge_offset_s: the judgement runs at t_k + this, s (in [0, time_step)). The live
            loop runs it after the command has gone out and the robot has stepped, so that
            it is not between a sample and its command; it then judges the MCA step just
            taken, and its new blend weight acts from the next command on.
    """

    def __init__(
        self,
        config: SupervisorConfig | None,
        robot: SerialChain,
        home_position: np.ndarray | None = None,
        judge_offset_s: float = 0.0,
    ):
        super().__init__()
        self._config = config or SupervisorConfig()
        self._config.validate()
        self._robot = robot
        h = self._config.time_step
        self._clamp = platform_clamp(self._robot, h)
        omega = 2 * math.pi * self._config.home_frequency_hz
        self._kp, self._kd = omega * omega, 2 * omega
        self._home_limit = self._config.home_acceleration_fraction * self._robot.qdd_max
        self._brake_limit = self._config.estop_acceleration_fraction * self._robot.qdd_max
        n = self._joints = robot.num_joints
        self._home = np.zeros(n) if home_position is None else np.array(home_position)
        if self._home.shape != (n,) or not np.all(np.isfinite(self._home)):
            raise ValueError(
                f"home_position must be {n} finite joint positions for {robot.name}; "
                f"got {home_position}"
            )
        self._transitions: list[tuple[float, str, str, str]] = []
        self._state_port = self.DeclareVectorInputPort("state", 2 * n)
        self._command_port = self.DeclareVectorInputPort("mca_command", n)
        self._reference_port = self.DeclareVectorInputPort("reference", NUM_CHANNELS)
        self._telemetry_port = self.DeclareVectorInputPort("telemetry", len(TELEMETRY_FIELDS))
        self._statistics_port = self.DeclareVectorInputPort("mca_statistics", 4)
        self._operator_port = self.DeclareVectorInputPort("operator", 1)
        initial = np.zeros(11)
        initial[_WEIGHT] = 1.0
        initial[[_ESTOP_AT, _REST_AT]] = math.nan
        self._index = self.DeclareDiscreteState(initial)
        if not 0 <= judge_offset_s < h:
            raise ValueError(f"judge_offset_s must be in [0, time_step); got {judge_offset_s}")
        self.DeclarePeriodicUnrestrictedUpdateEvent(h, judge_offset_s, self._judge)
        self.DeclareVectorOutputPort(
            "joint_acceleration",
            n,
            self._calc_command,
            {
                self.xd_ticket(),
                self._state_port.ticket(),
                self._command_port.ticket(),
                self._operator_port.ticket(),
            },
        )
        self.DeclareVectorOutputPort(
            "health", len(HEALTH_FIELDS), self._calc_health, {self.xd_ticket()}
        )

    @property
    def transitions(self) -> list[tuple[float, str, str, str]]:
        """Every transition so far: (time s, from state, to state, why)."""
        return list(self._transitions)

    def health(self, context: Context) -> dict[str, float]:
        """The `health` output in `context`, by name."""
        values = context.get_discrete_state(self._index).value()[: len(HEALTH_FIELDS)]
        return dict(zip(HEALTH_FIELDS, (float(v) for v in values), strict=True))

    def estop_times(self, context: Context) -> tuple[float, float]:
        """(loop time the supervisor first judged under the emergency stop, loop time the
        robot was at rest after it), s; nan where none."""
        s = context.get_discrete_state(self._index).value()
        return float(s[_ESTOP_AT]), float(s[_REST_AT])

    def _operator_mode(self, context: Context) -> int:
        """The operator's mode (MODES index); run when no console is connected."""
        if not self._operator_port.HasValue(context):
            return RUN
        return int(self._operator_port.Eval(context)[0])

    def brake_command(self, x: np.ndarray) -> np.ndarray:
        """The emergency stop's deceleration at state x (2n): every joint's velocity to zero
        in one period where its limit allows, per s^2 (n)."""
        u = -x[self._joints :] / self._config.time_step
        return np.clip(u, -self._brake_limit, self._brake_limit)

    def home_command(self, x: np.ndarray) -> np.ndarray:
        """The wash-out's acceleration toward the home pose at state x (2n), per s^2 (n)."""
        q, qd = x[: self._joints] - self._home, x[self._joints :]
        u = -self._kp * q - self._kd * qd
        return np.clip(u, -self._home_limit, self._home_limit)

    def _fault_reason(self, context: Context, overruns: int) -> str:
        telemetry = self._telemetry_port.Eval(context)
        if not np.isfinite(telemetry[_AGE]):
            return "no telemetry yet"  # the robot waits at home for the first sample
        if telemetry[_FRESH] < 0.5 or not telemetry[_AGE] <= self._config.stale_after_s:
            return "telemetry stale"
        reference = self._reference_port.Eval(context)
        if not np.all(np.isfinite(reference)):
            return "reference not finite"
        if np.any(np.abs(reference) > np.asarray(self._config.max_reference)):
            return "reference beyond max_reference"
        if not np.all(np.isfinite(self._command_port.Eval(context))):
            return "MCA command not finite"
        if overruns >= self._config.overruns_to_fault:
            return f"{overruns} MCA steps over budget"
        return ""

    def _judge(self, context: Context, state: State) -> None:
        cfg, h = self._config, self._config.time_step
        s = np.array(context.get_discrete_state(self._index).value())
        step_time = float(self._statistics_port.Eval(context)[0])
        overrun = step_time > cfg.step_budget_s
        s[_OVERRUNS] = s[_OVERRUNS] + 1 if overrun else 0
        why = self._fault_reason(context, int(s[_OVERRUNS]))
        current = int(s[_STATE])
        first_sample = not why and not s[_STREAMING]
        s[_STREAMING] = s[_STREAMING] or why != "no telemetry yet"
        if why:
            new, s[_CLEAR_S] = 2, 0.0
        elif first_sample:  # the stream's start, not a recovery: the blend brings the MCA in
            new, why = 0, "first sample"
        elif current == 2 and s[_CLEAR_S] + h < cfg.recovery_s - 1e-9:
            new, s[_CLEAR_S] = 2, s[_CLEAR_S] + h  # fault holds until it has been clear long
        else:
            age = float(self._telemetry_port.Eval(context)[_AGE])
            new = 1 if overrun or age > 0.5 * cfg.stale_after_s else 0
            why = "MCA step over budget" if overrun else ("telemetry late" if new else "clear")
        if new != current:
            s[_TRANSITIONS] += 1
            self._transitions.append(
                (context.get_time(), HEALTH_STATES[current], HEALTH_STATES[new], why)
            )
        s[_STATE] = new
        s[[_OK_S, _DEGRADED_S, _FAULT_S][new]] += h
        target = 0.0 if new == 2 else 1.0
        mode = self._operator_mode(context)
        if mode == ESTOP and math.isnan(s[_ESTOP_AT]):
            s[_ESTOP_AT] = context.get_time()
        if mode == WASHOUT or mode == ESTOP:
            target = 0.0  # (the stop brakes whatever the weight; it holds the wash-out after)
        s[_WEIGHT] = float(
            np.clip(target, s[_WEIGHT] - h / cfg.blend_s, s[_WEIGHT] + h / cfg.blend_s)
        )
        if not math.isnan(s[_ESTOP_AT]) and math.isnan(s[_REST_AT]):
            qd = self._state_port.Eval(context)[self._joints :]
            if np.max(np.abs(qd)) < REST_SPEED:
                s[_REST_AT] = context.get_time()
        state.get_mutable_discrete_state().set_value(self._index, s)

    def _calc_health(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._index).value()[: len(HEALTH_FIELDS)])

    def _calc_command(self, context: Context, output: BasicVector) -> None:
        x = self._state_port.Eval(context)
        if self._operator_mode(context) == ESTOP:
            output.SetFromVector(self._clamp(x, self.brake_command(x))[0])
            return
        u_mca = self._command_port.Eval(context).tolist()
        w = float(context.get_discrete_state(self._index).value()[_WEIGHT])
        if not all(map(math.isfinite, u_mca)):
            w = 0.0  # nothing to blend with
        # (the wash-out's command only where it has weight, and Python floats, not numpy
        # calls, for the MCA's: this runs between a live sample and its command)
        if w != 1.0:
            u_home = (1.0 - w) * self.home_command(x)
            u = u_home + w * np.asarray(u_mca) if w else u_home
        else:
            u = u_mca
        u, _ = self._clamp(x, u)
        output.SetFromVector(u)
