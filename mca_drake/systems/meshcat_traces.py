"""MeshcatOutputTraces: live strip charts of target and measured y, drawn in Meshcat."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat, Rgba
from pydrake.systems.framework import Context, LeafSystem, State

from mca_drake.conventions import CONTROL_PERIOD_S

# Half-height of a strip corresponds to these magnitudes (rad/s for w, m/s^2 for f, a).
DEFAULT_SCALES = (0.5, 0.5, 0.5, 3.0, 3.0, 3.0)
_TARGET_RGBA = Rgba(0.55, 0.55, 0.55, 1.0)
_MEASURED_RGBA = Rgba(0.0, 0.45, 0.85, 1.0)
_FRAME_RGBA = Rgba(0.2, 0.2, 0.2, 0.6)


class MeshcatOutputTraces(LeafSystem):
    """Six strip charts (one per channel of y) on a board beside the robot in Meshcat:
    the target in grey, the measured output in blue, over the last `window_s` seconds.

    .. pydrake_system::

        name: MeshcatOutputTraces
        input_ports:
        - reference
        - measured_output

    The samples live in the context (abstract state, a ring buffer updated every
    `sample_period`); drawing happens in a periodic publish every `publish_period`.

    Args:
        meshcat: the Meshcat instance.
        sample_period: buffer update period, s (default 0.01, the control period).
        publish_period: drawing period, s (default 0.1).
        window_s: time shown, s (default 10).
        origin: position in W of the board's lower-left corner, m (default beside the
            robot, 3 m to its left, behind it).
        width: board width, m.
        strip_height: height of one strip, m.
        scales: magnitude at a strip's half-height per channel (DEFAULT_SCALES).
        prefix: Meshcat path of the drawings.
    """

    def __init__(
        self,
        meshcat: Meshcat,
        sample_period: float = CONTROL_PERIOD_S,
        publish_period: float = 0.1,
        window_s: float = 10.0,
        origin=(-5.5, 2.5, 0.2),
        width: float = 4.0,
        strip_height: float = 0.55,
        scales=DEFAULT_SCALES,
        prefix: str = "traces",
    ):
        super().__init__()
        if not (0 < sample_period <= publish_period and window_s > sample_period):
            raise ValueError("need 0 < sample_period <= publish_period and window_s > it")
        self._meshcat = meshcat
        self._n = round(window_s / sample_period)
        self._origin = np.asarray(origin, dtype=float)
        self._width = float(width)
        self._strip = float(strip_height)
        self._scales = np.asarray(scales, dtype=float)
        self._prefix = prefix
        self._reference_port = self.DeclareVectorInputPort("reference", 6)
        self._measured_port = self.DeclareVectorInputPort("measured_output", 6)
        empty = np.full((self._n, 12), np.nan)
        self._buffer_index = self.DeclareAbstractState(AbstractValue.Make(empty))
        self.DeclarePeriodicUnrestrictedUpdateEvent(sample_period, 0.0, self._sample)
        self.DeclarePeriodicPublishEvent(publish_period, 0.0, self._draw)
        self._draw_frames()

    def _draw_frames(self) -> None:
        for k in range(6):
            base = self._origin + np.array([0.0, 0.0, (5 - k) * self._strip])
            w, z = self._width, 0.9 * self._strip
            offsets = np.array([[0, 0, 0], [w, 0, 0], [w, 0, z], [0, 0, z], [0, 0, 0]])
            corners = (base + offsets).T
            self._meshcat.SetLine(f"{self._prefix}/frame_{k}", corners, 1.0, _FRAME_RGBA)

    def _sample(self, context: Context, state: State) -> None:
        buffer = context.get_abstract_state(self._buffer_index).get_value()
        row = np.concatenate(
            [self._reference_port.Eval(context), self._measured_port.Eval(context)]
        )
        updated = np.roll(buffer, -1, axis=0)
        updated[-1] = row
        state.get_mutable_abstract_state(self._buffer_index).set_value(updated)

    def _draw(self, context: Context) -> None:
        buffer = context.get_abstract_state(self._buffer_index).get_value()
        valid = ~np.isnan(buffer[:, 0])
        if valid.sum() < 2:
            return
        data = buffer[valid]
        x = np.linspace(0.0, self._width, self._n)[valid]
        for k in range(6):
            middle = (5 - k) * self._strip + 0.45 * self._strip
            for offset, name, rgba in (
                (0, "target", _TARGET_RGBA),
                (6, "measured", _MEASURED_RGBA),
            ):
                value = np.clip(data[:, k + offset] / self._scales[k], -1.0, 1.0)
                points = (
                    np.stack([x, np.zeros_like(x), middle + 0.42 * self._strip * value])
                    + self._origin[:, None]
                )
                self._meshcat.SetLine(f"{self._prefix}/{name}_{k}", points, 2.0, rgba)
