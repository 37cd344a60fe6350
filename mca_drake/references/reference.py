"""Motion-cueing references: a recording scaled and gravity-compensated into y_ref.

    y_ref = [s_w omega_x, s_w omega_y, s_w omega_z, s_f f_x, s_f f_y, s_f (f_z - 9.81)]

so that level unaccelerated flight asks for y_ref = 0, what the simulator feels at rest in its
neutral pose. The defaults s_w = s_f = 0.5 are the customary starting point for motion
cueing of aircraft on a robot whose accelerations are far below the vehicle's; optional
per-channel limits clip (or softly saturate) what is asked of the robot.

A run that cues with another scaling (a scenario's `scaling`, `--force-scale`) is still scored
against the reference at the default scaling (`rescaled_reference` takes one to the other), so
that its PI stays comparable with every other run's: a reference scaled down reads as the
weaker cue it is.
(No `from __future__ import annotations` here: scenarios load `ReferenceScaling` from YAML.)
"""

import dataclasses
import math

import numpy as np

from mca_drake.conventions import CHANNELS, GRAVITY
from mca_drake.references.recording import DEFAULT_RATE_HZ, Recording
from mca_drake.references.vehicle_signals import SIGNALS

DEFAULT_ANGULAR_SCALE = 0.5
DEFAULT_FORCE_SCALE = 0.5


@dataclasses.dataclass
class ReferenceScaling:
    """How a recording becomes a reference: y_ref = scale * (vehicle motion), then limits."""

    # Scale s_w on angular velocity (dimensionless).
    angular_scale: float = DEFAULT_ANGULAR_SCALE
    # Scale s_f on specific force (dimensionless).
    force_scale: float = DEFAULT_FORCE_SCALE
    # Per-channel bound on |y_ref| after scaling (rad/s, m/s^2), six values in the order
    # w_x, w_y, w_z, f_x, f_y, a_z; empty: none.
    limits: list[float] = dataclasses.field(default_factory=list)
    # "clip" (hard) or "tanh" (smooth: limit * tanh(y / limit)).
    limit_mode: str = "clip"

    def validate(self) -> None:
        """Raises ValueError for settings that cannot scale a reference."""
        scales = (self.angular_scale, self.force_scale)
        if not all(math.isfinite(s) and s >= 0 for s in scales):
            raise ValueError(
                f"scaling: angular_scale and force_scale must be finite and >= 0; got {scales}"
            )
        limits = list(self.limits)
        if limits and (len(limits) != 6 or not all(math.isfinite(v) and v > 0 for v in limits)):
            raise ValueError(f"scaling: limits must be six positive values; got {limits}")
        if self.limit_mode not in ("clip", "tanh"):
            raise ValueError(f"scaling: unknown limit_mode '{self.limit_mode}'; valid: clip, tanh")

    @property
    def is_default(self) -> bool:
        """Whether this is the default scaling, which every run is scored against."""
        return (
            self.angular_scale == DEFAULT_ANGULAR_SCALE
            and self.force_scale == DEFAULT_FORCE_SCALE
            and not self.limits
        )

    def factors(self) -> tuple[float, ...]:
        """Per-channel factors (6) from the default scaling to this one, before the
        limits: s_w / 0.5 on the angular rates, s_f / 0.5 on the forces."""
        w = self.angular_scale / DEFAULT_ANGULAR_SCALE
        f = self.force_scale / DEFAULT_FORCE_SCALE
        return (w, w, w, f, f, f)

    def record(self) -> dict:
        """The scaling as a run's summary reports it (`scaling` block)."""
        return {
            "angular_scale": float(self.angular_scale),
            "force_scale": float(self.force_scale),
            "limits": [float(v) for v in self.limits],
            "limit_mode": self.limit_mode,
        }


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
        signals: the controls and vehicle state on the same samples, SI, each shape (T,)
            (`mca_drake.references.vehicle_signals.SIGNALS` names; a recording's, unscaled);
            empty where the source carries none. A predictor reads them
            (`mca_drake.cueing.learned_predictor`).
    """

    y: np.ndarray
    time_step: float = 1.0 / DEFAULT_RATE_HZ
    name: str = ""
    vehicle: str = ""
    signals: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        self.y = np.asarray(self.y, dtype=float)
        if self.y.ndim != 2 or self.y.shape[1] != len(CHANNELS) or self.y.shape[0] < 1:
            raise ValueError(f"reference y must have shape (T, 6); got {self.y.shape}")
        if not np.all(np.isfinite(self.y)):
            raise ValueError("reference y has non-finite values")
        if not self.time_step > 0:
            raise ValueError(f"time_step must be positive; got {self.time_step}")
        self.signals = {name: np.asarray(v, dtype=float) for name, v in self.signals.items()}
        for name, values in self.signals.items():
            if name not in SIGNALS:
                raise ValueError(f"unknown reference signal '{name}'; known: {', '.join(SIGNALS)}")
            if values.shape != (self.y.shape[0],):
                raise ValueError(
                    f"reference signal {name} must have {self.y.shape[0]} samples; got "
                    f"{values.shape}"
                )

    @property
    def times(self) -> np.ndarray:
        """Sample times k * time_step, s, shape (T,)."""
        return self.time_step * np.arange(self.y.shape[0])

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample [s]."""
        return self.time_step * (self.y.shape[0] - 1)

    def truncated(self, duration_s: float) -> "Reference":
        """The first `duration_s` seconds (all of it if shorter)."""
        n = min(round(duration_s / self.time_step) + 1, self.y.shape[0])
        signals = {name: v[:n] for name, v in self.signals.items()}
        return Reference(self.y[:n], self.time_step, self.name, self.vehicle, signals)


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
    return _limited(y, scaling)


def _limited(y: np.ndarray, scaling: ReferenceScaling) -> np.ndarray:
    """y (..., 6) within the scaling's limits (clipped or softly saturated)."""
    if not scaling.limits:
        return y
    limits = np.asarray(scaling.limits, dtype=float)
    if scaling.limit_mode == "clip":
        return np.clip(y, -limits, limits)
    return limits * np.tanh(y / limits)


def rescaled_reference(y: np.ndarray, scaling: ReferenceScaling) -> np.ndarray:
    """The reference at `scaling` of a reference at the default scaling: y (..., 6) times
    `ReferenceScaling.factors` per channel, then the limits. Exact: the default scaling is
    linear in the vehicle's motion and has no limits."""
    y = np.asarray(y, dtype=float) * np.asarray(scaling.factors())
    return _limited(y, scaling)


def scaled_reference_sample(omega, f, scaling: ReferenceScaling) -> list[float]:
    """`scaled_reference` of one sample in Python floats: omega (3, rad/s) and f (3, m/s^2)
    to y_ref (6 floats), the same formula. For the live loop, which scales every datagram
    between its arrival and the command: a dozen numpy calls on a cold core cost it about
    50 us, these float operations a few."""
    sw, sf = scaling.angular_scale, scaling.force_scale
    y = [sw * omega[0], sw * omega[1], sw * omega[2], sf * f[0], sf * f[1], sf * (f[2] - GRAVITY)]
    return _limited_sample(y, scaling)


def rescaled_reference_sample(y, factors, scaling: ReferenceScaling) -> list[float]:
    """`rescaled_reference` of one sample in Python floats (the live loop's path): y (6
    floats at the default scaling), `factors` = `scaling.factors()` (computed once)."""
    return _limited_sample([v * k for v, k in zip(y, factors, strict=True)], scaling)


def _limited_sample(y: list[float], scaling: ReferenceScaling) -> list[float]:
    """`_limited` of one sample in Python floats."""
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
    return Reference(y, time_step, label, vehicle, dict(recording.signals))
