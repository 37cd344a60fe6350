"""ReferencePredictor: a forecast of the reference over an MCA's horizon, from its history.

The system keeps the last samples of the reference it reads (discrete state, updated at
the control period in the same phase as the MCA's step, `systems.mca_update`) and outputs
the forecast of the next N samples from that history and the current sample. A predictive
MCA reads the forecast where a preview MCA reads the recorded future: at its step at t_k it
sees the history up to t_(k-1) and the sample of t_k, never anything later.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.cueing.learned_predictor import load_forecast_model
from mca_drake.cueing.predictor import constant_forecast
from mca_drake.references.vehicle_signals import SIGNALS
from mca_drake.systems.mca_update import DeclareMcaUpdate

NUM_CHANNELS = 6


class ReferencePredictor(LeafSystem):
    """Forecasts its input over `steps` samples from the last `history` samples.

    .. pydrake_system::

        name: ReferencePredictor
        input_ports:
        - reference
        output_ports:
        - reference_preview

    `reference` (6): the sample of the current control period. `reference_preview` (6 N):
    the current sample and the forecast of the N - 1 after it, sample after sample (reshape
    to (N, 6)), laid out as `ReferenceSource`'s preview of the recorded future; before the
    first update the history is the current sample held (as at rest). A forecast that
    reads controls and vehicle state (`signals` given) has a `signals` input
    (len(SIGNALS), as `ReferenceSource` and the live receiver give them, NaN where absent;
    unconnected: all absent) whose history it keeps as it keeps the reference's.

    Args:
        forecast: maps histories (H, 6), oldest first and the current sample last, to the
            forecast of the next N - 1 samples (N - 1, 6) (`cueing.predictor`:
            `LinearPredictor.forecast`, `constant_forecast`).
        history: H, the samples the forecast reads (the current one included), at least 1.
        steps: N, the preview's length in samples (the current one included), at least 1.
        time_step: the control period, s.
        update_event: the phase of each control instant its history moves in: the MCA's
            (`systems.mca_update`).
        signals: the places in the `signals` input (`vehicle_signals.SIGNALS` order) of the
            signals the forecast reads; then `forecast` maps (history, signal history
            (H_s, S), NaN where absent) to the forecast. Empty: no `signals` input.
        signal_history: H_s, the samples of signal history it reads (with `signals`).
    """

    def __init__(
        self,
        forecast: Callable[..., np.ndarray],
        history: int,
        steps: int,
        time_step: float = CONTROL_PERIOD_S,
        update_event: str = "unrestricted",
        signals: tuple[int, ...] = (),
        signal_history: int = 1,
    ):
        super().__init__()
        if history < 1 or steps < 1:
            raise ValueError(f"history and steps must be at least 1; got {history}, {steps}")
        if signals and signal_history < 1:
            raise ValueError(f"signal_history must be at least 1; got {signal_history}")
        self._forecast = forecast
        self._history = int(history)
        self._steps = int(steps)
        self._input = self.DeclareVectorInputPort("reference", NUM_CHANNELS)
        # the samples before the current one, oldest first, and whether any has been seen
        self._past = self.DeclareDiscreteState(NUM_CHANNELS * (self._history - 1) + 1)
        self._signal_places = np.asarray(signals, dtype=int)
        self._signal_history = int(signal_history) if signals else 0
        self._signals = None
        if signals:
            self._signals = self.DeclareVectorInputPort("signals", len(SIGNALS))
            past = np.full(len(signals) * (self._signal_history - 1), np.nan)
            self._signals_past = self.DeclareDiscreteState(past)
        self.DeclareVectorOutputPort(
            "reference_preview",
            NUM_CHANNELS * self._steps,
            self._calc_preview,
            prerequisites_of_calc={self.xd_ticket(), self.all_input_ports_ticket()},
        )
        DeclareMcaUpdate(self, time_step, self._update, update_event)

    @property
    def steps(self) -> int:
        """N, the forecast's length."""
        return self._steps

    def history(self, context: Context) -> np.ndarray:
        """The history the forecast reads in `context`: (H, 6), the current sample last."""
        current = self._input.Eval(context)
        state = context.get_discrete_state(self._past).value()
        if state[-1] == 0.0:  # nothing seen yet: as if the current sample had always been
            return np.tile(current, (self._history, 1))
        past = state[:-1].reshape(self._history - 1, NUM_CHANNELS)
        return np.vstack([past, current])

    def signal_history(self, context: Context) -> np.ndarray:
        """The signal history the forecast reads in `context`: (H_s, S), the current sample
        last, NaN where absent; before the first update the current sample held."""
        port = self._signals
        if port.HasValue(context):
            current = port.Eval(context)[self._signal_places]
        else:
            current = np.full(self._signal_places.size, np.nan)
        if context.get_discrete_state(self._past).value()[-1] == 0.0:
            return np.tile(current, (self._signal_history, 1))
        past = context.get_discrete_state(self._signals_past).value()
        return np.vstack([past.reshape(-1, self._signal_places.size), current])

    def _calc_preview(self, context: Context, output: BasicVector) -> None:
        history = self.history(context)
        if self._steps == 1:
            output.SetFromVector(history[-1])
            return
        if self._signals is None:
            forecast = self._forecast(history)
        else:
            forecast = self._forecast(history, self.signal_history(context))
        forecast = np.asarray(forecast, dtype=float)
        output.SetFromVector(np.vstack([history[-1:], forecast]).reshape(-1))

    def _update(self, context: Context, discrete: DiscreteValues) -> None:
        if self._signals is not None and self._signal_history > 1:
            signals = self.signal_history(context)
            discrete.get_mutable_vector(self._signals_past).SetFromVector(signals[1:].reshape(-1))
        if self._history == 1:
            return
        history = self.history(context)
        state = discrete.get_mutable_vector(self._past)
        state.SetFromVector(np.r_[history[1:].reshape(-1), 1.0])


def MakeReferencePredictor(
    kind: str,
    steps: int,
    time_step: float = CONTROL_PERIOD_S,
    update_event: str = "unrestricted",
) -> ReferencePredictor:
    """The ReferencePredictor of an NMPC's `predictor` setting (`NmpcConfig.predictor`):
    "constant", "linear" or "learned" (the packaged models) or an .npz file of either
    (`cueing.learned_predictor.load_forecast_model`), its preview `steps` samples long (the
    current one and `steps - 1` forecast).

    Raises:
        ValueError: an unknown kind, a model of another control period or shorter than
            `steps`. FileNotFoundError: a missing model file.
    """
    ahead = steps - 1
    if kind == "constant":
        return ReferencePredictor(
            lambda history: constant_forecast(history, ahead), 1, steps, time_step, update_event
        )
    model = load_forecast_model(kind)
    if abs(model.time_step - time_step) > 1e-12:
        raise ValueError(
            f"the predictor was fitted at {model.time_step} s, the control period is {time_step} s"
        )
    if model.steps < ahead:
        raise ValueError(f"the predictor forecasts {model.steps} steps; the MCA needs {ahead}")
    reads = getattr(model, "signals", ())
    if reads:  # a learned forecast that reads controls and vehicle state where given
        return ReferencePredictor(
            lambda history, signals: model.forecast(history, ahead, signals),
            model.history,
            steps,
            time_step,
            update_event,
            signals=tuple(list(SIGNALS).index(name) for name in reads),
            signal_history=model.signal_history,
        )
    return ReferencePredictor(
        lambda history: model.forecast(history, ahead),
        model.history,
        steps,
        time_step,
        update_event,
    )


def AddReferencePredictor(
    builder,
    controller,
    reference_port,
    time_step: float = CONTROL_PERIOD_S,
    update_event: str = "unrestricted",
    signals_port=None,
):
    """The forecast a predictive MCA reads: for a `controller` (an MCA system) whose
    `predictor` names one (an NMPC's `NmpcConfig.predictor`, a DPC's `DpcConfig.predictor`),
    a ReferencePredictor named "predictor" reading `reference_port` (and, for a forecast that
    reads them, the controls and vehicle state of `signals_port`, a `signals` output of
    `ReferenceSource` or the live receiver), updated in the MCA's phase `update_event`, as
    long as the controller's `preview_samples`; returns its `reference_preview` port, or
    None (and adds nothing) for an MCA without a predictor."""
    kind = getattr(controller, "predictor", "")
    if not kind:
        return None
    predictor = builder.AddNamedSystem(
        "predictor",
        MakeReferencePredictor(kind, controller.preview_samples, time_step, update_event),
    )
    builder.Connect(reference_port, predictor.GetInputPort("reference"))
    if signals_port is not None and predictor.HasInputPort("signals"):
        builder.Connect(signals_port, predictor.GetInputPort("signals"))
    return predictor.GetOutputPort("reference_preview")
