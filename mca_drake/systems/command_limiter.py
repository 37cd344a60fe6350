"""CommandLimiter: the station's last line of defence, which holds the commanded joint
trajectory inside the joint limits whatever the MCA sends."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from mca_drake.platforms.clamp import platform_clamp
from mca_drake.platforms.serial import SerialChain
from mca_drake.safety import substep_position_coefficient


class CommandLimiter(LeafSystem):
    """Clamps each MCA command into the viability interval of the commanded trajectory.

    .. pydrake_system::

        name: CommandLimiter
        input_ports:
        - command
        - desired_state
        output_ports:
        - limited_command
        - interventions

    The station integrates its desired trajectory [q_d, qd_d] (`desired_state`, 12) from
    the command at the plant rate. Every control period, half a plant step after the MCA
    has computed its command (6, rad/s^2) at t_n, a discrete update reads that command and
    the desired state from which the next control period's plant steps start, clamps the
    command into the exact viability interval of that state for those steps
    (`mca_drake.safety.ViabilityClamp` with the position coefficient of N semi-implicit
    substeps) and holds the result on `limited_command`. The half-step offset keeps the
    update off the plant's own instants, so the MCA's command enters the desired trajectory
    and the controller's feedforward together at the next plant step (a one-step transport
    delay, as on hardware), and the clamp knows exactly the steps it will act for. The
    commanded trajectory therefore never leaves the joint limits, whatever the MCA sends
    (late, non-finite, or computed from a delayed or noisy measurement). `interventions`
    (1) counts the commands it changed by more than 1e-9 rad/s^2.

    Args:
        robot: the platform (its joint limits).
        control_period: the MCA's period, s.
        plant_time_step: the station's plant (and desired-trajectory) period, s; the
            control period must be a whole number of these.
    """

    def __init__(self, robot: SerialChain, control_period: float, plant_time_step: float):
        super().__init__()
        substeps = round(control_period / plant_time_step)
        if substeps < 1 or abs(substeps * plant_time_step - control_period) > 1e-9:
            raise ValueError(
                f"the control period {control_period} s must be a whole number of plant "
                f"steps ({plant_time_step} s)"
            )
        self._clamp = platform_clamp(
            robot, control_period, position_coefficient=substep_position_coefficient(substeps)
        )
        n = robot.num_joints
        self._command_port = self.DeclareVectorInputPort("command", n)
        self._desired_port = self.DeclareVectorInputPort("desired_state", 2 * n)
        self._command_index = self.DeclareDiscreteState(n)
        self._interventions_index = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(control_period, 0.5 * plant_time_step, self._update)
        self.DeclareStateOutputPort("limited_command", self._command_index)
        self.DeclareStateOutputPort("interventions", self._interventions_index)

    def interventions(self, context: Context) -> int:
        """How many commands this limiter has changed so far in `context`."""
        return int(context.get_discrete_state(self._interventions_index).value()[0])

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        command = self._command_port.Eval(context)
        safe, intervened = self._clamp(self._desired_port.Eval(context), command)
        count = context.get_discrete_state(self._interventions_index).value()[0]
        discrete_state.set_value(self._command_index, safe)
        discrete_state.set_value(self._interventions_index, np.array([count + intervened]))
