"""When an MCA's control step runs within its control instant: one home for the choice.

Drake handles the events of one instant in one simulator step, in a fixed order: every
unrestricted update (each on the state before the step), then every discrete update (on the
state the unrestricted ones left), then the publishes. Every MCA (`DpcPolicy`,
`NmpcController`, `ClassicalWashout`) computes its command at t_k in one of two phases:

- "unrestricted" (the default): before any discrete update of t_k, so that the offline
  analytical plant (`MotionCueingPlant`, a discrete update at t_k) integrates the command
  computed at t_k, from x_k, at once.
- "discrete": after every unrestricted update of t_k, so that the step sees what they set.
  The live loop polls its telemetry at t_k in an unrestricted update (`TelemetryReceiver`),
  and a discrete MCA computes its command from that very sample in the same simulator step:
  nothing (no second step, no monitor call) sits between the poll and the MCA. A discrete
  update of another system at t_k still reads the previous command, so the live loop steps
  its plant after the command (`MotionCueingPlant(update_offset_s=...)`); the station's
  command limiter latches half a plant step later anyway.
"""

from __future__ import annotations

from collections.abc import Callable

from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

MCA_UPDATE_EVENTS = ("unrestricted", "discrete")


def DeclareMcaUpdate(
    system: LeafSystem,
    period_s: float,
    update: Callable[[Context, DiscreteValues], None],
    event: str = "unrestricted",
) -> None:
    """Declares `update(context, discrete_state)` as `system`'s control step every `period_s`
    (s) from t = 0, in the phase `event` of MCA_UPDATE_EVENTS (module docstring). `update`
    writes the new values into `discrete_state`, which holds the current ones on entry.

    Raises:
        ValueError: an unknown `event`.
    """
    if event == "unrestricted":

        def unrestricted(context: Context, state) -> None:
            update(context, state.get_mutable_discrete_state())

        system.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, unrestricted)
    elif event == "discrete":
        system.DeclarePeriodicDiscreteUpdateEvent(period_s, 0.0, update)
    else:
        raise ValueError(
            f"unknown MCA update event '{event}'; valid: {', '.join(MCA_UPDATE_EVENTS)}"
        )


__all__ = ["MCA_UPDATE_EVENTS", "DeclareMcaUpdate"]
