"""Synthetic vehicle motion: band-limited random angular velocity and specific force inside a
vehicle class's flight envelope, as a `Recording` like the ones JSBSim flights produce.

Each of the six recording channels (omega_x, omega_y, omega_z, f_x, f_y, f_z; head-frame
axes x forward, y left, z up, SI units) is drawn independently:

1. Gaussian white noise (numpy's `default_rng(seed)`), with a lead-in and a run-out
   (`settling_time_s`) that are cut off after filtering, so the kept samples carry no filter
   start-up transient;
2. a zero-phase Butterworth band-pass (`scipy.signal.sosfiltfilt`, `FILTER_ORDER` per band
   edge, run forward and back) from `band_low_hz` to `band_high_hz`;
3. scaled to unit RMS, then by a gain chosen so that, after step 4, the channel's RMS
   deviation from level flight is the configured share of the envelope (`rms_share`);
4. a smooth saturation, `limit * tanh(x / limit)` with the upper limit for x >= 0 and the
   lower one for x < 0, added to the level-flight value. The result stays inside the
   envelope whatever the seed and the share (|tanh| <= 1), and it is smooth: the saturation
   adds no step, only the weak harmonics of a gentle compression.

Level, unaccelerated flight is omega = 0 and f = (0, 0, +9.81) (`recording`'s convention);
the vertical specific force varies around that 1 g between the class's limit load factors,
f_z in [n_min g, n_max g]. Where the two load-factor limits lie at different distances from
1 g, the saturation compresses the nearer side more and the mean of f_z moves a little
towards the farther one (positive g for fighters, as in real flight).

The channels are independent random signals: no flight dynamics ties a roll rate to the
lateral force or a pitch rate to the load factor. They spread over the envelope's box in
every combination of channels, which a training set needs and flights seldom fly; flights
(`mca_drake.references.jsbsim`) give the correlated motion of a flown aircraft.

`synthetic_recording(config)` returns the recording; `synthetic_reference(config, scaling)`
the motion-cueing reference, through `reference_from_recording`, with the same scaling as
flights.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.optimize import brentq
from scipy.signal import butter, sosfiltfilt

from mca_drake.conventions import CONTROL_PERIOD_S, GRAVITY
from mca_drake.input_checks import MAX_DURATION_S, check_config_numbers, check_range, quoted
from mca_drake.references.recording import COLUMNS, MIN_DURATION_S, MIN_RATE_HZ, Recording
from mca_drake.references.reference import Reference, ReferenceScaling, reference_from_recording

_DEG = math.pi / 180

# The recording channels (its columns but t) in the order the generator draws them, and their
# level-flight values (rad/s for omega, m/s^2 for f): level, unaccelerated flight reads
# f = (0, 0, +g).
SYNTHETIC_CHANNELS = COLUMNS[1:]
LEVEL_FLIGHT = (0.0, 0.0, 0.0, 0.0, 0.0, GRAVITY)


@dataclasses.dataclass(frozen=True)
class FlightEnvelope:
    """The motion a vehicle class can make, as bounds on each recording channel (head frame).

    Attributes:
        load_factors: limit load factors (n_min, n_max), dimensionless: the specific force
            along the head's z axis stays in [n_min g, n_max g] (level flight: 1 g).
        max_rates: largest |angular velocity| about x (roll), y (pitch) and z (yaw), rad/s.
        max_horizontal_force: largest |specific force| along x (surge) and y (sway), m/s^2.
    """

    load_factors: tuple[float, float]
    max_rates: tuple[float, float, float]
    max_horizontal_force: tuple[float, float]

    def channel_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lowest, highest) value of each channel of `SYNTHETIC_CHANNELS`, rad/s and m/s^2,
        shape (6,) each."""
        n_min, n_max = self.load_factors
        magnitudes = np.array([*self.max_rates, *self.max_horizontal_force])
        return np.append(-magnitudes, n_min * GRAVITY), np.append(magnitudes, n_max * GRAVITY)

    def deviation_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(below, above): how far each channel may go below and above its level-flight
        value, rad/s and m/s^2, shape (6,) each, all positive."""
        lowest, highest = self.channel_bounds()
        level = np.array(LEVEL_FLIGHT)
        return level - lowest, highest - level


def _envelope(
    load_factors: tuple[float, float],
    rates_deg_s: tuple[float, float, float],
    horizontal_g: tuple[float, float],
) -> FlightEnvelope:
    """An envelope from limit load factors, rates in deg/s and horizontal forces in g."""
    return FlightEnvelope(
        load_factors=load_factors,
        max_rates=tuple(r * _DEG for r in rates_deg_s),
        max_horizontal_force=tuple(a * GRAVITY for a in horizontal_g),
    )


# The envelopes of the vehicle classes. Sources and reasoning, channel by channel:
#
# - Load factors: the structural limit load factors of the certification basis.
#   light: 14 CFR 23.337 (before amendment 23-64) and CS 23.337 (before amendment 5), normal
#     category: n_max = 2.1 + 24000 / (W + 10000) (W in lb), which need not exceed 3.8, and
#     n_min = -0.4 n_max = -1.52.
#   aerobatic: the same rules, aerobatic category: +6.0, and -0.5 n_max = -3.0 (the T-6, T-37
#     and T-38 are cleared for somewhat more, +6.7 to +7.3 g; the category's values are the
#     conservative common bound).
#   transport: 14 CFR / CS 25.337: n_max = 2.5 for airplanes of the fleet's weights, n_min =
#     -1.0 up to the design cruise speed.
#   fighter: the +9 / -3 g of current fighters' flight manuals (F-16, F-15); older types of
#     the class (A-4, F-4) are cleared for a little less, +7 to +8.5 g.
# - Roll rate: MIL-F-8785C (3.3.4, Level 1, Category A) asks Class I aircraft to bank 60 deg in
#   1.3 s (46 deg/s on average) and Class III 30 deg in 1.5 s (20 deg/s); light and transport
#   take about these, rounded up. Aerobatic trainers and fighters roll well beyond their
#   class minimum (90 deg in 1.3 s for Class IV); 120 and 180 deg/s are round values below
#   their full-deflection roll rates.
# - Pitch rate: the rate of a pull-up to the limit load factor at manoeuvring speed V,
#   q = (n_max - 1) g / V, rounded: light 2.8 g at 50 m/s (31 deg/s) -> 30; aerobatic 5 g at
#   70 m/s (40 deg/s) -> 40; transport 1.5 g at 140 m/s (6 deg/s) -> 6; fighter 8 g at a
#   corner speed of 160 m/s (28 deg/s) -> 30.
# - Yaw rate: the turn rate g tan(bank) / V at the class's steepest bank and manoeuvring
#   speed, rounded up: light 60 deg at 50 m/s (19 deg/s) -> 20; aerobatic 70 deg at 70 m/s
#   (22 deg/s) -> 20; transport 45 deg at 130 m/s (4.3 deg/s) -> 5; fighter 75 deg at 160 m/s
#   (13 deg/s) -> 15.
# - Surge specific force f_x: thrust minus drag, and braking, over weight, round estimates:
#   light +-0.3 g (static thrust to weight about 0.2, wheel braking about 0.3 g); transport
#   +-0.4 g (thrust to weight 0.25 to 0.35, maximum braking 0.4 to 0.5 g); aerobatic +-0.5 g;
#   fighter +-1.0 g (thrust to weight about 1 with afterburner, speed brakes at high speed).
# - Sway specific force f_y: coordinated flight keeps it near 0; the bounds are round
#   estimates of full-rudder sideslips and engine-out or crosswind manoeuvres: light 0.2 g,
#   transport 0.15 g, aerobatic 0.4 g, fighter 0.6 g.
ENVELOPES = {
    "light": _envelope((-1.52, 3.8), (60.0, 30.0, 20.0), (0.3, 0.2)),
    "aerobatic": _envelope((-3.0, 6.0), (120.0, 40.0, 20.0), (0.5, 0.4)),
    "transport": _envelope((-1.0, 2.5), (20.0, 6.0, 5.0), (0.4, 0.15)),
    "fighter": _envelope((-3.0, 9.0), (180.0, 30.0, 15.0), (1.0, 0.6)),
}

# The envelope of every vehicle of the JSBSim fleet (`mca_drake.references.jsbsim.fleet`),
# by its certification basis or role: the Twin Otter is a normal-category (CS/FAR 23) utility
# aircraft; business jets and airliners are CS/FAR 25 transports; the jet trainers and the
# turboprop aerobatic trainer fly the aerobatic envelope; attack and fighter jets the fighter's.
VEHICLE_ENVELOPES = {
    "light": "light",
    "DHC6": "light",
    "jet": "transport",
    "A320": "transport",
    "787-8": "transport",
    "MD11": "transport",
    "B747": "transport",
    "t6texan2": "aerobatic",
    "T37": "aerobatic",
    "T38": "aerobatic",
    "f16": "fighter",
    "f15": "fighter",
    "A4": "fighter",
    "F4N": "fighter",
}

# Butterworth order of each band edge (the band-pass has twice this order; run forward and
# back, its magnitude falls as the 16th power of frequency outside the band).
FILTER_ORDER = 4
# Noise drawn before and after the kept samples, in periods of the slower of the lower
# cut-off frequency and the bandwidth (a narrow band rings for about 1 / bandwidth). What the
# first kept sample misses of its variance is the band-pass's impulse-response energy beyond
# the lead-in: 6e-10 of it for the default band, under 1e-3 even for a band as narrow as its
# lower cut-off (0.05 to 0.1 Hz), so the kept samples are statistically alike throughout.
FILTER_SETTLING_PERIODS = 4.0
# Lowest lower cut-off and narrowest band, Hz: periods of 100 s are slower than the motion a
# simulator cues as motion, and they keep the noise drawn around the kept samples under
# FILTER_SETTLING_PERIODS x 100 s on each side.
MIN_BAND_HZ = 0.01
# Largest RMS share: the RMS deviation may approach but never reach the nearer limit (tanh
# stays below 1); beyond 0.9 the signal spends most of its time pressed against the limits,
# a square wave rather than band-limited motion.
MAX_RMS_SHARE = 0.9
# Default RMS of each channel's deviation from level flight, as a share of its nearer limit:
# a quarter keeps the saturation gentle (the gain before it is only 7 % above the target, so
# the band-pass's spectrum survives) while 4 % of the samples lie beyond half that limit.
DEFAULT_RMS_SHARE = 0.25


@dataclasses.dataclass
class SyntheticConfig:
    """A synthetic recording: which envelope, how long, which band, how strong, which seed."""

    # Flight envelope, a key of ENVELOPES (VEHICLE_ENVELOPES names a fleet vehicle's).
    envelope: str = "light"
    # Length of the recording, s.
    duration_s: float = 60.0
    # Seed of the noise (numpy `default_rng`); the same seed gives the same recording.
    seed: int = 0
    # Lower cut-off frequency of the band-pass, Hz.
    band_low_hz: float = 0.05
    # Upper cut-off frequency of the band-pass, Hz (below the Nyquist frequency 0.5 / time_step).
    band_high_hz: float = 2.0
    # RMS of each channel's deviation from level flight, in the order SYNTHETIC_CHANNELS, as a
    # share of the channel's nearer envelope limit (dimensionless, in (0, MAX_RMS_SHARE]).
    rms_share: tuple[float, ...] = (DEFAULT_RMS_SHARE,) * len(SYNTHETIC_CHANNELS)
    # Sample period, s.
    time_step: float = CONTROL_PERIOD_S

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        owner = type(self).__name__
        check_config_numbers(self)
        if not isinstance(self.envelope, str) or self.envelope not in ENVELOPES:
            raise ValueError(
                f"{owner}.envelope: unknown envelope {quoted(self.envelope)}; valid: "
                f"{', '.join(ENVELOPES)} (a fleet vehicle's is VEHICLE_ENVELOPES[vehicle])"
            )
        if not 0 <= self.seed < 2**32:
            raise ValueError(f"{owner}.seed must be in [0, 2^32); got {self.seed}")
        check_range(owner, "time_step", self.time_step, 0.0, 1.0 / MIN_RATE_HZ, low_open=True)
        check_range(owner, "duration_s", self.duration_s, MIN_DURATION_S, MAX_DURATION_S)
        nyquist = 0.5 / self.time_step
        if not (
            self.band_low_hz >= MIN_BAND_HZ and self.band_high_hz - self.band_low_hz >= MIN_BAND_HZ
        ):
            raise ValueError(
                f"{owner}: the band needs {MIN_BAND_HZ:g} Hz <= band_low_hz < band_high_hz, at "
                f"least {MIN_BAND_HZ:g} Hz apart; got band_low_hz = {self.band_low_hz} Hz, "
                f"band_high_hz = {self.band_high_hz} Hz"
            )
        if not self.band_high_hz < nyquist:
            raise ValueError(
                f"{owner}.band_high_hz = {self.band_high_hz} Hz must be below the Nyquist "
                f"frequency {nyquist:g} Hz of time_step = {self.time_step} s"
            )
        if len(self.rms_share) != len(SYNTHETIC_CHANNELS) or not all(
            0 < share <= MAX_RMS_SHARE for share in self.rms_share
        ):
            raise ValueError(
                f"{owner}.rms_share must be {len(SYNTHETIC_CHANNELS)} values (one per channel "
                f"{', '.join(SYNTHETIC_CHANNELS)}) in (0, {MAX_RMS_SHARE}]; got "
                f"{quoted(self.rms_share)}"
            )


def saturate(x: np.ndarray, below: np.ndarray, above: np.ndarray) -> np.ndarray:
    """Smooth saturation of deviations x (..., C) into [-below, above] (C,): `above *
    tanh(x / above)` where x >= 0, `below * tanh(x / below)` where x < 0. Slope 1 and no
    curvature at 0 on both sides, so it is smooth there; monotone, odd where below = above."""
    return np.where(x >= 0, above * np.tanh(x / above), below * np.tanh(x / below))


# Grid of the standard normal density on which the saturated RMS is integrated: +-9 standard
# deviations hold all but 2e-19 of the probability; with 4001 points the RMS agrees with
# adaptive quadrature to 1e-13 at every share up to MAX_RMS_SHARE.
_NORMAL_GRID = np.linspace(-9.0, 9.0, 4001)
_NORMAL_WEIGHTS = np.exp(-0.5 * _NORMAL_GRID**2) * (_NORMAL_GRID[1] - _NORMAL_GRID[0])
_NORMAL_WEIGHTS /= _NORMAL_WEIGHTS.sum()


def saturated_rms(gain: float, below: float, above: float) -> float:
    """RMS of `saturate(gain * z, below, above)` for z standard normal (the expectation, by
    quadrature), in the units of the limits."""
    y = saturate(gain * _NORMAL_GRID, np.float64(below), np.float64(above))
    return float(np.sqrt(np.sum(_NORMAL_WEIGHTS * y**2)))


def gain_for_rms(target: float, below: float, above: float) -> float:
    """The gain g for which `saturate(g z, below, above)`, z standard normal, has RMS
    `target` (units of the limits). It exists while target < sqrt((below^2 + above^2) / 2),
    which a target of at most MAX_RMS_SHARE x min(below, above) always is."""
    # Saturation only shrinks, so the target itself is a lower bracket; double to an upper.
    low, high = target, 2.0 * target
    while saturated_rms(high, below, above) < target:
        low, high = high, 2.0 * high
    return float(brentq(lambda g: saturated_rms(g, below, above) - target, low, high, xtol=1e-12))


def settling_time_s(band_low_hz: float, band_high_hz: float) -> float:
    """Length of the noise drawn before and after the kept samples, s
    (`FILTER_SETTLING_PERIODS`)."""
    return FILTER_SETTLING_PERIODS / min(band_low_hz, band_high_hz - band_low_hz)


def synthetic_recording(config: SyntheticConfig | None = None) -> Recording:
    """A synthetic recording inside `config.envelope` (module docstring).

    Returns:
        A `Recording` on the uniform grid t = k * time_step, k = 0 .. round(duration_s /
        time_step) (T samples): t (T,) s, omega (T, 3) rad/s and f (T, 3) m/s^2 in head-frame
        axes, level flight at f = (0, 0, 9.81); its metadata names the source, envelope,
        seed, band and RMS shares.

    Raises:
        ValueError: an invalid config (`SyntheticConfig.validate`).
    """
    config = config or SyntheticConfig()
    config.validate()
    h = config.time_step
    steps = round(config.duration_s / h) + 1
    settling = math.ceil(settling_time_s(config.band_low_hz, config.band_high_hz) / h)
    rng = np.random.default_rng(config.seed)
    noise = rng.standard_normal((steps + 2 * settling, len(SYNTHETIC_CHANNELS)))
    sos = butter(
        FILTER_ORDER,
        [config.band_low_hz, config.band_high_hz],
        btype="bandpass",
        fs=1.0 / h,
        output="sos",
    )
    shaped = sosfiltfilt(sos, noise, axis=0)[settling : settling + steps]
    shaped /= np.sqrt(np.mean(shaped**2, axis=0))

    envelope = ENVELOPES[config.envelope]
    below, above = envelope.deviation_limits()
    targets = np.array(config.rms_share) * np.minimum(below, above)
    gains = np.array([gain_for_rms(*args) for args in zip(targets, below, above, strict=True)])
    lowest, highest = envelope.channel_bounds()
    # Level value plus a deviation inside (-below, above) is inside [lowest, highest] up to
    # the last bit of the sum's rounding, which the clip removes.
    values = np.clip(
        np.array(LEVEL_FLIGHT) + saturate(gains * shaped, below, above), lowest, highest
    )

    metadata = {
        "source": "synthetic",
        "envelope": config.envelope,
        "seed": str(config.seed),
        "band_hz": f"{config.band_low_hz:g}-{config.band_high_hz:g}",
        "rms_share": ",".join(f"{share:g}" for share in config.rms_share),
    }
    t = h * np.arange(steps)
    return Recording(t, values[:, :3], values[:, 3:], metadata)


def synthetic_reference(
    config: SyntheticConfig | None = None, scaling: ReferenceScaling | None = None
) -> Reference:
    """The motion-cueing reference of `synthetic_recording(config)`, scaled as flights are
    (`reference_from_recording`; `scaling` None: the default s_w = s_f = 0.5).

    Returns:
        A `Reference` with y of shape (T, 6) (`mca_drake.conventions.CHANNELS`; T as in
        `synthetic_recording`) and time_step = config.time_step, s.
    """
    config = config or SyntheticConfig()
    recording = synthetic_recording(config)
    name = f"synthetic {config.envelope} seed {config.seed}"
    return reference_from_recording(recording, scaling, name=name)
