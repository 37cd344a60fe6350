"""ReferenceGuard: the input plausibility guard in front of every MCA, as a Drake system."""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    LeafSystem,
    ValueProducer,
)

from mca_drake.conventions import CONTROL_PERIOD_S, NUM_CHANNELS
from mca_drake.cueing.plausibility import (
    REACTIONS,
    PlausibilityConfig,
    guard_step,
    initial_state,
    reaction,
    summary_block,
)


class ReferenceGuard(LeafSystem):
    """The reference as an MCA may read it (`mca_drake.cueing.plausibility`): spikes held,
    every channel's change per period bounded, a frozen stream faded out to zero and back.

    .. pydrake_system::

        name: ReferenceGuard
        input_ports:
        - reference
        output_ports:
        - guarded_reference
        - reaction

    `guarded_reference` at t_k is the guard's step on the reference sample at t_k from the
    guard's state after t_(k-1) (direct feedthrough: the MCA's update at t_k reads the
    sample of t_k, as it would read the reference itself); a periodic update at every t_k
    commits that step to the state (at `update_offset_s` after t_k: the live loop commits
    after the command has gone out, off the path from a sample to its command; the input
    holds until the next poll). `reaction` (1) is the index in
    `cueing.plausibility.REACTIONS` of what the step on the current sample does. The counts
    go into the run's summary (`summary_block`).

    Args:
        config: the guard's settings (default `PlausibilityConfig()`); validated here.
        time_step: the control period, s (the reference's sample period).
        update_offset_s: when in each period the step is committed, s after t_k.
    """

    def __init__(
        self,
        config: PlausibilityConfig | None = None,
        time_step: float = CONTROL_PERIOD_S,
        update_offset_s: float = 0.0,
    ):
        super().__init__()
        self._config = config or PlausibilityConfig()
        self._config.validate()
        self._time_step = float(time_step)
        self._input = self.DeclareVectorInputPort("reference", NUM_CHANNELS)
        self._state_index = self.DeclareDiscreteState(initial_state())
        # The step on the current sample from the committed state, computed once per period
        # for both the output and the update (a cache entry of the context: (the state after
        # the step, the output)).
        self._step = self.DeclareCacheEntry(
            description="the guard's step on the current sample",
            value_producer=ValueProducer(
                allocate=lambda: AbstractValue.Make(((), ())), calc=self._calc_step
            ),
            prerequisites_of_calc={self.xd_ticket(), self._input.ticket()},
        )
        if not 0 <= update_offset_s < self._time_step:
            raise ValueError(f"update_offset_s must be in [0, time_step); got {update_offset_s}")
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, update_offset_s, self._update)
        self.DeclareVectorOutputPort(
            "guarded_reference",
            NUM_CHANNELS,
            self._calc_output,
            prerequisites_of_calc={self._step.ticket()},
        )
        self.DeclareVectorOutputPort(
            "reaction", 1, self._calc_reaction, prerequisites_of_calc={self._step.ticket()}
        )

    def _calc_reaction(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector([REACTIONS.index(reaction(self._step.Eval(context)[0]))])

    def _calc_step(self, context: Context, value: AbstractValue) -> None:
        state = context.get_discrete_state(self._state_index).value().tolist()
        out = guard_step(state, self._input.Eval(context).tolist(), self._time_step, self._config)
        value.set_value((state, out))

    def _calc_output(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._step.Eval(context)[1])

    def _update(self, context: Context, discrete: DiscreteValues) -> None:
        discrete.set_value(self._state_index, self._step.Eval(context)[0])

    def summary(self, context: Context) -> dict:
        """The `plausibility` block of the run's summary so far (`summary_block`)."""
        state = context.get_discrete_state(self._state_index).value().tolist()
        return summary_block(state, self._time_step)


__all__ = ["ReferenceGuard"]
