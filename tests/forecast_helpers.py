"""What the forecast tests share: a smooth flight whose every sample can be told apart, and
a forecaster that knows its future (the oracle a predictive MCA must equal the preview MCA
with)."""

from __future__ import annotations

import numpy as np

from mca_drake.references.reference import Reference
from mca_drake.systems.predictor import ReferencePredictor

H = 0.01


def smooth_flight(seconds=8.0):
    """A smooth reference whose w_x channel is unique at every sample (`perfect_predictor`
    finds its place by it)."""
    t = np.arange(round(seconds / H) + 1) * H
    y = np.stack(
        [
            0.02 + 1e-4 * t,
            0.04 * np.sin(0.7 * t),
            0.05 * np.sin(0.3 * t),
            0.8 * np.sin(0.5 * t),
            0.5 * np.sin(0.9 * t + 1.0),
            0.3 * np.sin(1.3 * t),
        ],
        axis=1,
    )
    return Reference(y, H, "smooth")


def perfect_predictor(reference: Reference):
    """A stand-in for `systems.predictor.MakeReferencePredictor` whose forecast is the
    recorded future of `reference` (found by the current sample's w_x), the last sample
    held beyond its end."""

    def make(kind, preview, time_step, update_event):
        def forecast(history):
            k = int(np.flatnonzero(reference.y[:, 0] == history[-1, 0])[0])
            rows = np.minimum(np.arange(k + 1, k + preview), reference.y.shape[0] - 1)
            return reference.y[rows]

        return ReferencePredictor(forecast, 1, preview, time_step, update_event)

    return make
