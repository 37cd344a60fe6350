"""VestibularModel: what the occupant perceives of y-like signals, as a Drake system."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from mca_drake.conventions import CHANNELS, CONTROL_PERIOD_S
from mca_drake.perception.filters import vestibular_filter
from mca_drake.perception.models import PerceptionConfig


class VestibularModel(LeafSystem):
    """The vestibular model of `mca_drake.perception` (canals on the rates, otoliths on the
    specific forces), discrete at the control period.

    .. pydrake_system::

        name: VestibularModel
        input_ports:
        - signals
        output_ports:
        - perceived
        - felt

    `signals` (6) is y or a reference (channels `mca_drake.conventions.CHANNELS`), sampled
    every `time_step` with a periodic discrete update x <- A x + B u (the exact zero-order-
    hold discretisation of `perception.filters`). `perceived` (6) is C x + D u, in the units
    of y: at t_n, before that instant's update, the n-th output of
    `perception.filters.perceive` for the samples u_0..u_n. `felt` (6) is `perceived` where
    its magnitude exceeds the channel's threshold and 0 where it does not (below the
    thresholds nothing is felt). The state starts at zero: the occupant at rest.

    Args:
        config: the vestibular model and thresholds (default PerceptionConfig()).
        time_step: the sample period, s.
    """

    def __init__(self, config: PerceptionConfig | None = None, time_step: float = CONTROL_PERIOD_S):
        super().__init__()
        self._config = config or PerceptionConfig()
        self._filter = vestibular_filter(self._config, time_step)
        self._thresholds = self._config.thresholds
        self._signals_port = self.DeclareVectorInputPort("signals", len(CHANNELS))
        self._state_index = self.DeclareDiscreteState(self._filter.num_states)
        self.DeclarePeriodicDiscreteUpdateEvent(time_step, 0.0, self._update)
        self._perceived_port = self.DeclareVectorOutputPort(
            "perceived", len(CHANNELS), self._calc_perceived
        )
        self._felt_port = self.DeclareVectorOutputPort("felt", len(CHANNELS), self._calc_felt)

    @property
    def config(self) -> PerceptionConfig:
        """The vestibular model and thresholds this system uses."""
        return self._config

    def _perceived(self, context: Context) -> np.ndarray:
        x = context.get_discrete_state(self._state_index).value()
        u = self._signals_port.Eval(context)
        return self._filter.C @ x + self._filter.D @ u

    def _calc_perceived(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._perceived(context))

    def _calc_felt(self, context: Context, output: BasicVector) -> None:
        perceived = self._perceived(context)
        output.SetFromVector(np.where(np.abs(perceived) > self._thresholds, perceived, 0.0))

    def _update(self, context: Context, discrete: DiscreteValues) -> None:
        x = context.get_discrete_state(self._state_index).value()
        u = self._signals_port.Eval(context)
        discrete.set_value(self._state_index, self._filter.A @ x + self._filter.B @ u)
