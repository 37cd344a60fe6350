"""Real-time operation: telemetry protocols, receiver and supervisor, robot protocols.

Decoders turn one UDP datagram into a head-frame `TelemetrySample` (angular velocity, rad/s,
and specific force, m/s^2, in the recording conventions), or raise `BadPacket`:

    telemetry  TelemetrySample, BadPacket, the Decoder base, LeverArm (CG or pilot point to head)
    fgnetfdm   FlightGear's native FDM packet, version 24, as JSBSim sends it
    xplane     X-Plane 11/12 UDP DATA rows (load factors, body rates)
    csv_udp    the documented CSV-over-UDP line format, encoder and decoder
    beamng     BeamNG.drive's MotionSim packet (acceleration, attitude, rates)
    outsim     Live for Speed's OutSim: the classic OutSimPack and OutSim 2 (world axes)
    f1         EA Sports F1 23/24: the Motion and Motion Ex packets of the player's car
    receiver   TelemetryReceiver, the Drake system that polls a UDP socket every control
               period (imported from its module: it loads pydrake, the decoders do not)
    supervisor Supervisor: health state machine (ok, degraded, fault) and the blended,
               limit-respecting wash-out to home (also imported from its module)
    rsi        KUKA RobotSensorInterface: messages, the driver process, its link and an
               emulator (a subpackage, `mca_drake.live.rsi`)
"""

from __future__ import annotations

from mca_drake.live.beamng import BeamNGConfig, BeamNGDecoder
from mca_drake.live.csv_udp import CsvDecoder, encode_csv_sample
from mca_drake.live.f1 import F1Config, F1Decoder
from mca_drake.live.fgnetfdm import FgNetFdmDecoder, jsbsim_output_directive, unpack_fgnetfdm
from mca_drake.live.outsim import OutSimConfig, OutSimDecoder
from mca_drake.live.telemetry import (
    BadPacket,
    Decoder,
    HeadPointTransfer,
    LeverArm,
    TelemetrySample,
    specific_force_at,
)
from mca_drake.live.xplane import XPLANE_LAYOUTS, XPlaneDecoder, XPlaneLayout, xplane_layout

__all__ = [
    "XPLANE_LAYOUTS",
    "BadPacket",
    "BeamNGConfig",
    "BeamNGDecoder",
    "CsvDecoder",
    "Decoder",
    "F1Config",
    "F1Decoder",
    "FgNetFdmDecoder",
    "HeadPointTransfer",
    "LeverArm",
    "OutSimConfig",
    "OutSimDecoder",
    "TelemetrySample",
    "XPlaneDecoder",
    "XPlaneLayout",
    "encode_csv_sample",
    "jsbsim_output_directive",
    "specific_force_at",
    "unpack_fgnetfdm",
    "xplane_layout",
]
