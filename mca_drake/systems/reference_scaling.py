"""ReferenceScaler: the reference at a scenario's own scaling, between the guard and the MCA.

Every reference enters a diagram at the default scaling (`references.reference`), which is
what runs are scored against; a scenario's `scaling` (`ReferenceScaling`: other scale
factors, per-channel limits) changes what the MCA is asked to cue, and this system is the
one place it does so, offline and live alike.
"""

from pydrake.systems.framework import BasicVector, Context, LeafSystem

from mca_drake.references.reference import (
    ReferenceScaling,
    rescaled_reference,
    rescaled_reference_sample,
)


class ReferenceScaler(LeafSystem):
    """y_ref at `scaling` from y_ref at the default scaling (`rescaled_reference`), with
    direct feedthrough; and the same for a preview, sample by sample.

    .. pydrake_system::

        name: ReferenceScaler
        input_ports:
        - reference
        - reference_preview (optional)
        output_ports:
        - scaled_reference
        - scaled_reference_preview (optional)

    `reference` and `scaled_reference` are 6 channels (rad/s, m/s^2); the preview ports, where
    `preview_samples` > 0, hold that many samples stacked one after another (6 N).

    Args:
        scaling: the scaling the MCA cues at (validated here).
        preview_samples: N of the preview ports; 0: none.
    """

    def __init__(self, scaling: ReferenceScaling, preview_samples: int = 0):
        super().__init__()
        scaling.validate()
        self._scaling = scaling
        # the factors once: the live path scales every sample with six multiplications
        self._factors = scaling.factors()
        self._input = self.DeclareVectorInputPort("reference", 6)
        self.DeclareVectorOutputPort("scaled_reference", 6, self._calc_reference)
        if preview_samples > 0:
            self._preview = self.DeclareVectorInputPort("reference_preview", 6 * preview_samples)
            self.DeclareVectorOutputPort(
                "scaled_reference_preview", 6 * preview_samples, self._calc_preview
            )

    @property
    def scaling(self) -> ReferenceScaling:
        """The scaling this system applies."""
        return self._scaling

    def _calc_reference(self, context: Context, output: BasicVector) -> None:
        y = self._input.Eval(context).tolist()
        output.SetFromVector(rescaled_reference_sample(y, self._factors, self._scaling))

    def _calc_preview(self, context: Context, output: BasicVector) -> None:
        preview = self._preview.Eval(context).reshape(-1, 6)
        output.SetFromVector(rescaled_reference(preview, self._scaling).reshape(-1))


def AddReferenceScaling(
    builder, reference_port, scaling: ReferenceScaling | None, preview_port=None
):
    """(reference, preview) ports at `scaling`: `reference_port` and `preview_port` through a
    ReferenceScaler named "reference_scaler", or the ports themselves where `scaling` is
    None or the default (no system on the path). `preview_port` None: no preview."""
    if scaling is None or scaling.is_default:
        return reference_port, preview_port
    samples = 0 if preview_port is None else preview_port.size() // 6
    scaler = builder.AddNamedSystem("reference_scaler", ReferenceScaler(scaling, samples))
    builder.Connect(reference_port, scaler.GetInputPort("reference"))
    if preview_port is None:
        return scaler.GetOutputPort("scaled_reference"), None
    builder.Connect(preview_port, scaler.GetInputPort("reference_preview"))
    return scaler.GetOutputPort("scaled_reference"), scaler.GetOutputPort(
        "scaled_reference_preview"
    )
