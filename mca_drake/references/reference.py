"""Motion-cueing references: a recording scaled and gravity-compensated into y_ref.

    y_ref = [s_w omega_x, s_w omega_y, s_w omega_z, s_f f_x, s_f f_y, s_f (f_z - 9.81)]

so that level unaccelerated flight asks for y_ref = 0, what the simulator feels at rest in its
neutral pose. The defaults s_w = s_f = 0.5 are the customary starting point for motion
cueing of aircraft on a robot whose accelerations are far below the vehicle's; optional
per-channel limits clip (or softly saturate) what is asked of the robot.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from mca_drake.conventions import CHANNELS, GRAVITY
from mca_drake.references.recording import DEFAULT_RATE_HZ, Recording

DEFAULT_ANGULAR_SCALE = 0.5
DEFAULT_FORCE_SCALE = 0.5


@dataclasses.dataclass
class ReferenceScaling:
    """How a recording becomes a reference."""

    # Scale s_w on angular velocity (dimensionless).
    angular_scale: float = DEFAULT_ANGULAR_SCALE
    # Scale s_f on specific force (dimensionless).
    force_scale: float = DEFAULT_FORCE_SCALE
    # Per-channel bound on |y_ref| after scaling (rad/s, m/s^2), six values; empty: none.
    limits: tuple[float, ...] = ()
    # "clip" (hard) or "tanh" (smooth: limit * tanh(y / limit)).
    limit_mode: str = "clip"

    def validate(self) -> None:
        if not (self.angular_scale >= 0 and self.force_scale >= 0):
            raise ValueError("scale factors must be non-negative")
        if self.limits and (len(self.limits) != 6 or min(self.limits) <= 0):
            raise ValueError(f"limits must be six positive values; got {self.limits}")
        if self.limit_mode not in ("clip", "tanh"):
            raise ValueError(f"unknown limit_mode '{self.limit_mode}'; valid: clip, tanh")


@dataclasses.dataclass
class Reference:
    """A motion-cueing reference sampled uniformly.

    Attributes:
        y: target outputs, shape (T, 6), channels `mca_drake.metrics.CHANNELS`.
        time_step: sample period, s.
        name: where it came from (a file name, a vehicle and seed).
        vehicle: the vehicle flown or driven, as `FlightSpec.vehicle` or `DriveSpec.car`
            name it; "" where it is not known (a recording file, live telemetry). The DPC
            picks its policy by it (`mca_drake.cueing.dpc.vehicle_policy_name`).
    """

    y: np.ndarray
    time_step: float = 1.0 / DEFAULT_RATE_HZ
    name: str = ""
    vehicle: str = ""

    def __post_init__(self) -> None:
        self.y = np.asarray(self.y, dtype=float)
        if self.y.ndim != 2 or self.y.shape[1] != len(CHANNELS) or self.y.shape[0] < 1:
            raise ValueError(f"reference y must have shape (T, 6); got {self.y.shape}")
        if not np.all(np.isfinite(self.y)):
            raise ValueError("reference y has non-finite values")
        if not self.time_step > 0:
            raise ValueError(f"time_step must be positive; got {self.time_step}")

    @property
    def times(self) -> np.ndarray:
        """Sample times k * time_step, s, shape (T,)."""
        return self.time_step * np.arange(self.y.shape[0])

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample [s]."""
        return self.time_step * (self.y.shape[0] - 1)

    def truncated(self, duration_s: float) -> Reference:
        """The first `duration_s` seconds (all of it if shorter)."""
        n = min(round(duration_s / self.time_step) + 1, self.y.shape[0])
        return Reference(self.y[:n], self.time_step, self.name, self.vehicle)


def scaled_reference(omega: np.ndarray, f: np.ndarray, scaling: ReferenceScaling) -> np.ndarray:
    """y_ref of head-frame samples (module docstring): omega (..., 3) rad/s and f (..., 3)
    m/s^2 to y_ref (..., 6), scaled, gravity-compensated and limited as `scaling` says. One
    formula for recordings and live telemetry."""
    omega, f = np.asarray(omega, dtype=float), np.asarray(f, dtype=float)
    y = np.concatenate(
        [
            scaling.angular_scale * omega,
            scaling.force_scale * f[..., :2],
            scaling.force_scale * (f[..., 2:] - GRAVITY),
        ],
        axis=-1,
    )
    if scaling.limits:
        limits = np.asarray(scaling.limits)
        y = (
            np.clip(y, -limits, limits)
            if scaling.limit_mode == "clip"
            else limits * np.tanh(y / limits)
        )
    return y


def scaled_reference_sample(omega, f, scaling: ReferenceScaling) -> list[float]:
    """`scaled_reference` of one sample in Python floats: omega (3, rad/s) and f (3, m/s^2)
    to y_ref (6 floats), the same formula. For the live loop, which scales every datagram
    between its arrival and the command: a dozen numpy calls on a cold core cost it about
    50 us, these float operations a few."""
    sw, sf = scaling.angular_scale, scaling.force_scale
    y = [sw * omega[0], sw * omega[1], sw * omega[2], sf * f[0], sf * f[1], sf * (f[2] - GRAVITY)]
    if not scaling.limits:
        return y
    if scaling.limit_mode == "clip":
        return [min(max(v, -limit), limit) for v, limit in zip(y, scaling.limits, strict=True)]
    return [limit * math.tanh(v / limit) for v, limit in zip(y, scaling.limits, strict=True)]


def reference_from_recording(
    recording: Recording,
    scaling: ReferenceScaling | None = None,
    name: str = "",
    vehicle: str = "",
) -> Reference:
    """Scales and gravity-compensates a recording into a reference (see module docstring),
    named `name` (default: from the recording's metadata) and flown or driven by `vehicle`.

    The recording must be uniformly sampled (`Recording.resampled`; `load_recording` does it).
    """
    scaling = scaling or ReferenceScaling()
    scaling.validate()
    steps = np.diff(recording.t)
    # Absolute time stamps (Unix epoch, 1.7e9 s) resolve only 2.4e-7 s: allow for that.
    resolution = 4 * float(np.spacing(np.max(np.abs(recording.t))))
    if not np.allclose(steps, steps[0], rtol=1e-6, atol=max(1e-9, resolution)):
        raise ValueError("recording is not uniformly sampled; call recording.resampled() first")
    y = scaled_reference(recording.omega, recording.f, scaling)
    label = name or ", ".join(f"{k}={v}" for k, v in recording.metadata.items() if k != "format")
    # The mean step, to the nanosecond: single steps of epoch time stamps carry their
    # 2.4e-7 s resolution, and no control period needs finer than 1 ns.
    time_step = round(float((recording.t[-1] - recording.t[0]) / (recording.t.size - 1)), 9)
    return Reference(y, time_step, label, vehicle)
