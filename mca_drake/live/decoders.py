"""The telemetry decoders by protocol name: what `mca-drake live --protocol` chooses."""

from __future__ import annotations

from mca_drake.live.beamng import BeamNGConfig, BeamNGDecoder
from mca_drake.live.csv_udp import CsvDecoder
from mca_drake.live.f1 import F1Config, F1Decoder
from mca_drake.live.fgnetfdm import FgNetFdmDecoder
from mca_drake.live.outsim import OutSimConfig, OutSimDecoder
from mca_drake.live.telemetry import Decoder
from mca_drake.live.xplane import XPlaneDecoder

PROTOCOLS = ("fgnetfdm", "xplane", "csv", "beamng", "outsim", "f1")


def make_decoder(
    protocol: str,
    *,
    xplane_version: int | None = None,
    fgnetfdm_time_resolution_s=None,
    beamng: BeamNGConfig | None = None,
    outsim: OutSimConfig | None = None,
    f1: F1Config | None = None,
) -> Decoder:
    """The decoder of `protocol` (PROTOCOLS). X-Plane needs its version (11 or 12: they
    differ in the body-rate row); FGNetFDM reads the sender's time only when JSBSim's
    directive sets a resolution (else arrival times). The racing simulators take their
    configs (None: the defaults: BeamNG's signs, LFS's classic OutSimPack, F1's 2024 format)."""
    if protocol == "fgnetfdm":
        return FgNetFdmDecoder(time_resolution_s=fgnetfdm_time_resolution_s)
    if protocol == "xplane":
        if xplane_version is None:
            raise ValueError("protocol xplane needs its version (11 or 12): --xplane-version")
        return XPlaneDecoder(version=xplane_version)
    if protocol == "csv":
        return CsvDecoder()
    if protocol == "beamng":
        return BeamNGDecoder(config=beamng)
    if protocol == "outsim":
        return OutSimDecoder(config=outsim)
    if protocol == "f1":
        return F1Decoder(config=f1)
    raise ValueError(f"unknown protocol '{protocol}'; valid: {', '.join(PROTOCOLS)}")
