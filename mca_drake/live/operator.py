"""OperatorConsole: the operator's controls of a live run as a Drake system (`live.controls`
for the settings, the commands and the ramps; `live.control_inputs` for their sources)."""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State

from mca_drake.conventions import NUM_CHANNELS
from mca_drake.live.controls import (
    CONTROL_SETTINGS,
    ESTOP,
    MODES,
    RUN,
    ControlsConfig,
    apply_command,
    fade_target,
    initial_settings,
    ramp,
    scale_reference,
)

_S = len(CONTROL_SETTINGS)
# The state: the settings now, the settings asked for, the fade, the mode.
_CURRENT, _TARGET, _FADE, _MODE = slice(0, _S), slice(_S, 2 * _S), 2 * _S, 2 * _S + 1
# At most this many commands are kept in the log (the rest are counted).
MAX_LOGGED_COMMANDS = 1000


class OperatorConsole(LeafSystem):
    """The reference as the operator wants it cued, and the mode for the supervisor.

    .. pydrake_system::

        name: OperatorConsole
        input_ports:
        - reference
        output_ports:
        - scaled_reference
        - mode
        - settings

    `scaled_reference` (6) is `live.controls.scale_reference` of the `reference` under the
    settings now (direct feedthrough: it is on the path from a sample to its command, a few
    multiplications). `mode` (1) is the index in `live.controls.MODES` (the supervisor
    washes out or stops on it); `settings` (9) the settings now (CONTROL_SETTINGS) and the
    fade. A periodic update at `update_offset_s` after each control instant (the live loop:
    after the command has gone out) reads the sources' commands, applies them in the order
    they came, answers each, and moves every setting and the fade one ramp step toward its
    target; every command is logged with its time (`log`).

    Args:
        config: the controls' settings (ramp, gain range, the run's first settings).
        sources: where commands come from (`live.control_inputs`); polled, never closed here.
        time_step: the control period, s.
        update_offset_s: when in each period the commands are read, s after t_k.
    """

    def __init__(
        self,
        config: ControlsConfig | None,
        sources: list,
        time_step: float,
        update_offset_s: float = 0.0,
    ):
        super().__init__()
        self._config = config or ControlsConfig()
        self._config.validate()
        self._sources = list(sources)
        self._step = time_step / self._config.ramp_s  # the largest change per period
        settings = initial_settings(self._config)
        initial = np.array(settings + settings + [1.0, float(RUN)])
        self._index = self.DeclareDiscreteState(initial)
        self._input = self.DeclareVectorInputPort("reference", NUM_CHANNELS)
        if not 0 <= update_offset_s < time_step:
            raise ValueError(f"update_offset_s must be in [0, time_step); got {update_offset_s}")
        self.DeclarePeriodicUnrestrictedUpdateEvent(time_step, update_offset_s, self._update)
        self.DeclareVectorOutputPort(
            "scaled_reference",
            NUM_CHANNELS,
            self._calc_reference,
            {self.xd_ticket(), self._input.ticket()},
        )
        self.DeclareVectorOutputPort("mode", 1, self._calc_mode, {self.xd_ticket()})
        self.DeclareVectorOutputPort("settings", _S + 1, self._calc_settings, {self.xd_ticket()})
        # (time s, source, command, answer, accepted) of every command read
        self.log: list[tuple[float, str, str, str, bool]] = []
        self.commands = self.refused = 0
        self.estop: dict | None = None

    @property
    def sources(self) -> list[str]:
        """The names of the command sources."""
        return [source.name for source in self._sources]

    def _update(self, context: Context, state: State) -> None:
        s = context.get_discrete_state(self._index).value().tolist()
        targets, mode = s[_TARGET], int(s[_MODE])
        asked = (targets, mode)
        for source in self._sources:
            for text, answer in source.poll():
                targets, new_mode, said, accepted = apply_command(
                    targets, mode, text, self._config.max_gain
                )
                self._record(context.get_time(), source.name, text, said, accepted)
                if new_mode == ESTOP and mode != ESTOP:
                    self.estop = {"t_s": round(context.get_time(), 6), "source": source.name}
                mode = new_mode
                if answer is not None:
                    answer(said)
        if (targets, mode) != asked:  # every source shows the settings as they now are
            for source in self._sources:
                source.show(targets, mode)
        current = [ramp(c, t, self._step) for c, t in zip(s[_CURRENT], targets, strict=True)]
        fade = ramp(s[_FADE], fade_target(mode), self._step)
        state.get_mutable_discrete_state().set_value(
            self._index, np.array(current + targets + [fade, float(mode)])
        )

    def _record(self, t: float, source: str, text: str, said: str, accepted: bool) -> None:
        self.commands += 1
        self.refused += not accepted
        if len(self.log) < MAX_LOGGED_COMMANDS:
            self.log.append((t, source, text[:80], said, accepted))

    def _calc_reference(self, context: Context, output: BasicVector) -> None:
        s = context.get_discrete_state(self._index).value().tolist()
        output.SetFromVector(
            scale_reference(self._input.Eval(context).tolist(), s[_CURRENT], s[_FADE])
        )

    def _calc_mode(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector([context.get_discrete_state(self._index).value()[_MODE]])

    def _calc_settings(self, context: Context, output: BasicVector) -> None:
        s = context.get_discrete_state(self._index).value()
        output.SetFromVector(np.r_[s[_CURRENT], s[_FADE]])

    def summary(self, context: Context, time_to_rest_s: float = math.nan) -> dict:
        """The summary's `controls` block: the sources, every command with its time and
        answer, the settings and mode at the end, and the emergency stop (when one came:
        its time, source and `time_to_rest_s`, the supervisor's)."""
        s = context.get_discrete_state(self._index).value().tolist()
        estop = None
        if self.estop is not None:
            rest = time_to_rest_s if math.isfinite(time_to_rest_s) else None
            estop = self.estop | {"time_to_rest_s": rest}
        return {
            "sources": self.sources,
            "commands": self.commands,
            "refused": self.refused,
            "log": [
                {"t_s": round(t, 6), "source": src, "command": text, "answer": said}
                for t, src, text, said, _ in self.log
            ],
            "final": dict(zip(CONTROL_SETTINGS, s[_CURRENT], strict=True))
            | {"fade": s[_FADE], "mode": MODES[int(s[_MODE])]},
            "estop": estop,
        }


__all__ = ["OperatorConsole"]
