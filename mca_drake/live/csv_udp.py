"""CSV over UDP: one head-frame sample per datagram, as one line of ASCII text.

Format (this project's own; any program can send it):

    t,omega_x,omega_y,omega_z,f_x,f_y,f_z

- the columns of a recording (`mca_drake.references.recording.COLUMNS`), in that order, with
  its conventions: t the sender's time in s, omega the angular velocity in rad/s, f the
  specific force in m/s^2, head axes x forward, y left, z up (level flight: f_z = +9.81);
- decimal numbers with '.' (optionally signed, with an exponent: `-1.5e-3`); spaces or tabs
  around a number are allowed; no header, no quotes, no nan or inf;
- an optional line end ("\\n" or "\\r\\n"); at most `MAX_DATAGRAM_BYTES` bytes.

`encode_csv_sample` writes it (shortest round-trip decimal form, so decoding gives back the
same float64 values); `CsvDecoder` reads it.
"""

from __future__ import annotations

import math
import re

from mca_drake.live.telemetry import BadPacket, Decoder, LeverArm, TelemetrySample
from mca_drake.references.recording import COLUMNS

# Longest datagram accepted, bytes: seven doubles in their longest form take under 200.
MAX_DATAGRAM_BYTES = 512
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")


def encode_csv_sample(t_s: float, omega, f) -> bytes:
    """One datagram of the CSV-over-UDP format: "t,omega_x,...,f_z\\n" in ASCII.

    Args:
        t_s: the sample's time, s.
        omega: angular velocity, rad/s, shape (3,), head axes.
        f: specific force, m/s^2, shape (3,), head axes.

    Raises:
        ValueError: a wrong shape or a non-finite value.
    """
    sample = TelemetrySample(t_s, omega, f)  # checks shapes and finiteness
    values = [sample.t_s, *sample.omega, *sample.f]
    return (",".join(repr(float(v)) for v in values) + "\n").encode("ascii")


class CsvDecoder(Decoder):
    """Decodes CSV-over-UDP datagrams (module docstring) into head-frame samples; the
    sample time is the sender's `t`.

    Args:
        lever_arm: where the head is relative to the sender's point (None: the sender's
            samples are at the head, as the format specifies).
    """

    protocol = "csv"
    # seven numbers and an optional sequence as text: far below this
    max_datagram_bytes = 1024

    def __init__(self, *, lever_arm: LeverArm | None = None) -> None:
        super().__init__(lever_arm=lever_arm)

    def _decode_at_source(self, packet: bytes, received_s: float) -> TelemetrySample:
        if len(packet) > MAX_DATAGRAM_BYTES:
            raise BadPacket(
                f"csv datagram of {len(packet)} bytes; one sample takes at most "
                f"{MAX_DATAGRAM_BYTES}"
            )
        try:
            text = packet.decode("ascii")
        except UnicodeDecodeError as error:
            raise BadPacket(f"csv datagram is not ASCII text ({error})") from error
        if text.endswith("\r\n"):
            text = text[:-2]
        elif text.endswith("\n"):
            text = text[:-1]
        cells = text.split(",")
        if len(cells) != len(COLUMNS):
            raise BadPacket(
                f"csv datagram has {len(cells)} fields; expected {len(COLUMNS)}: "
                f"{','.join(COLUMNS)} (got {text[:80]!r})"
            )
        values = []
        for column, cell in zip(COLUMNS, cells, strict=True):
            cell = cell.strip(" \t")
            if not _NUMBER.fullmatch(cell):
                raise BadPacket(f"csv datagram field {column} is not a decimal number: {cell!r}")
            value = float(cell)
            if not math.isfinite(value):  # "1e999" is a number that overflows
                raise BadPacket(f"csv datagram field {column} overflows: {cell!r}")
            values.append(value)
        return TelemetrySample(values[0], values[1:4], values[4:7])
