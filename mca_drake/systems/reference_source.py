"""ReferenceSource: plays a motion-cueing reference into a diagram at its sample rate."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from mca_drake.references.reference import Reference
from mca_drake.references.vehicle_signals import SIGNALS, signal_matrix


class ReferenceSource(LeafSystem):
    """Plays a sampled reference y_ref (zero-order hold) with a preview of what comes next.

    .. pydrake_system::

        name: ReferenceSource
        output_ports:
        - reference
        - reference_preview
        - signals

    At time t the sample index is k = floor(t / time_step) (with a tolerance for rounding
    at sample instants). `reference` (6) is y_ref[k]; `reference_preview` (6 N) holds the N
    samples y_ref[k], y_ref[k + 1], ..., y_ref[k + N - 1] stacked sample after sample
    (reshape to (N, 6)); samples past the end hold the last value, as does `reference`.
    `signals` (len(SIGNALS)): the reference's controls and vehicle state at sample k, one
    per `vehicle_signals.SIGNALS` name in its order, NaN for one it does not carry (as the
    live receiver's port).

    Args:
        reference: the reference to play.
        preview_samples: N, the number of samples in `reference_preview` (at least 1).
    """

    def __init__(self, reference: Reference, preview_samples: int = 1):
        super().__init__()
        # (T, len(SIGNALS)), NaN columns for the signals the reference does not carry
        self._signals = signal_matrix(reference.signals, tuple(SIGNALS), reference.y.shape[0])
        if preview_samples < 1:
            raise ValueError(f"preview_samples must be at least 1; got {preview_samples}")
        self._y = np.array(reference.y)
        self._time_step = reference.time_step
        self._preview_samples = int(preview_samples)
        self._reference = reference
        self._reference_port = self.DeclareVectorOutputPort(
            "reference", 6, self._calc_reference, prerequisites_of_calc={self.time_ticket()}
        )
        self._preview_port = self.DeclareVectorOutputPort(
            "reference_preview",
            6 * self._preview_samples,
            self._calc_preview,
            prerequisites_of_calc={self.time_ticket()},
        )
        self.DeclareVectorOutputPort(
            "signals", len(SIGNALS), self._calc_signals, prerequisites_of_calc={self.time_ticket()}
        )

    @property
    def reference(self) -> Reference:
        """The recording this source plays."""
        return self._reference

    @property
    def preview_samples(self) -> int:
        """N, the samples in each `reference_preview` output (the NMPC/DPC horizon)."""
        return self._preview_samples

    def sample_index(self, time: float) -> int:
        """k = floor(time / time_step), clamped to the recording; negative times give 0."""
        k = int(np.floor(time / self._time_step + 1e-6))
        return min(max(k, 0), self._y.shape[0] - 1)

    def _calc_reference(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._y[self.sample_index(context.get_time())])

    def _calc_preview(self, context: Context, output: BasicVector) -> None:
        k = self.sample_index(context.get_time())
        rows = np.minimum(np.arange(k, k + self._preview_samples), self._y.shape[0] - 1)
        output.SetFromVector(self._y[rows].reshape(-1))

    def _calc_signals(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._signals[self.sample_index(context.get_time())])
