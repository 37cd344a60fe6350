"""CabinComfortBound: the cabin comfort bound (`mca_drake.comfort`) as a Drake system between
whatever commands the robot (an MCA, the live supervisor) and the robot."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    LeafSystem,
    ValueProducer,
)

from mca_drake.comfort import FORCE_ROWS, ComfortConfig, comfort_fraction
from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.platforms.clamp import platform_clamp
from mca_drake.platforms.kinematics import plant_output
from mca_drake.platforms.serial import SerialChain


class CabinComfortBound(LeafSystem):
    """The command the robot gets: the incoming `command` moved from the last applied one
    only as far as the cabin's specific force may change in one period, then clamped into
    the joint limits' viability interval (the clamp has the last word).

    .. pydrake_system::

        name: CabinComfortBound
        input_ports:
        - state
        - command
        output_ports:
        - bounded_command
        - applied_command
        - bounded_periods

    `bounded_command` (n) is direct feedthrough of the robot's `state` [q, qd] (2n) and the
    `command` (n); it costs two evaluations of the plant output, so it is meant for runs
    that ask for the bound (with `config` disabled the command passes as it is, at no cost).
    A periodic update at `update_offset_s` after each control instant, when the robot
    takes its command, keeps the command applied and the force it gave (f(x, u)); the first
    period passes unbounded. `applied_command` (n) is the command the robot took at the
    last update (a log of it lines up with the robot's state as the MCA's own command log
    does); `bounded_periods` (1) counts the commands the bound scaled.

    Args:
        robot: the platform (its kinematics and limits).
        config: the bound.
        time_step: the control period, s.
        update_offset_s: when in each period the robot takes its command, s after t_k.
        position_coefficient: the viability clamp's (`safety.ViabilityClamp`; the station's
            substeps need theirs).
    """

    def __init__(
        self,
        robot: SerialChain,
        config: ComfortConfig,
        time_step: float = CONTROL_PERIOD_S,
        update_offset_s: float = 0.0,
        position_coefficient: float = 0.5,
    ):
        super().__init__()
        config.validate()
        self._config, self._robot = config, robot
        n = self._joints = robot.num_joints
        self._clamp = platform_clamp(robot, time_step, position_coefficient)
        self._state_port = self.DeclareVectorInputPort("state", 2 * n)
        self._command_port = self.DeclareVectorInputPort("command", n)
        # [u applied (n), its force (3), started, bounded periods]
        self._index = self.DeclareDiscreteState(np.zeros(n + 5))
        if not 0 <= update_offset_s < time_step:
            raise ValueError(f"update_offset_s must be in [0, time_step); got {update_offset_s}")
        self.DeclarePeriodicDiscreteUpdateEvent(time_step, update_offset_s, self._update)
        # The bounded command, whether the bound scaled it, and the force it gives: computed
        # once per context for both the output and the update (a cache entry).
        self._step = self.DeclareCacheEntry(
            description="the bounded command",
            value_producer=ValueProducer(
                allocate=lambda: AbstractValue.Make(((), False, ())), calc=self._calc_step
            ),
            prerequisites_of_calc={
                self.xd_ticket(),
                self._state_port.ticket(),
                self._command_port.ticket(),
            },
        )
        self.DeclareVectorOutputPort(
            "bounded_command", n, self._calc_command, {self._step.ticket()}
        )
        self.DeclareVectorOutputPort("applied_command", n, self._calc_applied, {self.xd_ticket()})
        self.DeclareVectorOutputPort("bounded_periods", 1, self._calc_count, {self.xd_ticket()})

    @property
    def config(self) -> ComfortConfig:
        """The bound."""
        return self._config

    def bounded_periods(self, context: Context) -> int:
        """How many commands the bound has scaled so far."""
        return int(context.get_discrete_state(self._index).value()[-1])

    def _force(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        n = self._joints
        return plant_output(x[:n], x[n:], u, self._robot)[FORCE_ROWS]

    def _calc_step(self, context: Context, value: AbstractValue) -> None:
        """(the command after the bound and the clamp, whether the bound scaled it, the
        force f(x, u) it gives; empty where the command is not finite)."""
        u = np.array(self._command_port.Eval(context))
        if not self._config.enabled or not np.all(np.isfinite(u)):
            value.set_value((u, False, ()))
            return
        s = context.get_discrete_state(self._index).value()
        n = self._joints
        x = np.array(self._state_port.Eval(context))
        force, scaled = self._force(x, u), False
        if s[n + 3]:
            u_prev, f_prev = s[:n], s[n : n + 3]
            f_hold = self._force(x, u_prev)
            alpha = comfort_fraction(force - f_hold, f_hold - f_prev, self._config.max_force_change)
            if alpha < 1.0:
                # the force is affine in the command: the scaled command's, exactly
                u, force, scaled = (
                    u_prev + alpha * (u - u_prev),
                    f_hold + alpha * (force - f_hold),
                    True,
                )
        u, clamped = self._clamp(x, u)
        if clamped:
            force = self._force(x, u)
        value.set_value((u, scaled, force))

    def _calc_command(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._step.Eval(context)[0])

    def _calc_applied(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._index).value()[: self._joints])

    def _calc_count(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector([context.get_discrete_state(self._index).value()[-1]])

    def _update(self, context: Context, discrete: DiscreteValues) -> None:
        u, scaled, force = self._step.Eval(context)
        if len(force):  # (nothing to keep from a command that is not finite)
            count = context.get_discrete_state(self._index).value()[-1] + scaled
            discrete.set_value(self._index, np.r_[u, force, 1.0, count])


__all__ = ["CabinComfortBound"]
