"""Motion-cueing quality metrics: RMSE, Pearson CC, performance index, statistics, limits.

Signals have shape (T, 6) (time, channel) with the channels of y:
[w_x, w_y, w_z, f_x, f_y, a_z]. The performance index of equation (10) is
PI = sum_k (RMSE_k - CC_k), minimum -6 (perfect rendering), lower is better.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.stats

from mca_drake.conventions import CHANNELS
from mca_drake.input_checks import as_float_array, same_shapes

# A channel whose peak-to-peak spread is below this (relative to max(1, its largest value),
# in its SI units: rad/s, m/s^2) counts as still for the correlation, and a still target is
# rendered exactly when the achieved signal stays within it. 1e-6 is five orders of magnitude
# below the vestibular thresholds (about 0.01 rad/s and 0.05 m/s^2) and above a numerical
# solver's round-off: without it a converged NMPC that keeps a still channel within 1e-8 of
# zero would score CC 0 instead of 1 there (+1 on the PI per channel) for noise no occupant
# could feel.
STILL_TOLERANCE = 1e-6


def _signals(target, achieved) -> tuple[np.ndarray, np.ndarray]:
    target = as_float_array("target", target)
    achieved = as_float_array("achieved", achieved)
    same_shapes(target=target, achieved=achieved)
    if target.ndim != 2 or target.shape[0] < 2:
        raise ValueError(f"signals must have shape (T, channels) with T >= 2; got {target.shape}")
    return target, achieved


def rmse(target, achieved) -> np.ndarray:
    """Root-mean-square error per channel: shape (C,) for signals of shape (T, C)."""
    target, achieved = _signals(target, achieved)
    return np.sqrt(np.mean((achieved - target) ** 2, axis=0))


def _is_constant(x: np.ndarray) -> np.ndarray:
    scale = np.maximum(np.max(np.abs(x), axis=0), 1.0)
    return np.ptp(x, axis=0) <= STILL_TOLERANCE * scale


def pearson_cc(target, achieved) -> np.ndarray:
    """Pearson correlation coefficient per channel, shape (C,), in [-1, 1].

    Defined for constant channels too (where Pearson's formula divides by zero):
    1 when both signals are constant and equal (a perfectly rendered still channel),
    0 when at least one is constant otherwise (no co-variation to measure); constant and
    equal within STILL_TOLERANCE.
    """
    target, achieved = _signals(target, achieved)
    t = target - target.mean(axis=0)
    a = achieved - achieved.mean(axis=0)
    constant = _is_constant(target) | _is_constant(achieved)
    denominator = np.sqrt(np.sum(t * t, axis=0) * np.sum(a * a, axis=0))
    cc = np.divide(
        np.sum(t * a, axis=0), denominator, out=np.zeros(target.shape[1]), where=~constant
    )
    close = np.isclose(target, achieved, rtol=STILL_TOLERANCE, atol=STILL_TOLERANCE)
    equal = constant & np.all(close, axis=0)
    cc[equal] = 1.0
    return np.clip(cc, -1.0, 1.0)


@dataclasses.dataclass(frozen=True)
class TrackingScore:
    """Per-channel RMSE and CC and the performance index PI = sum(RMSE - CC)."""

    rmse: np.ndarray
    cc: np.ndarray

    @property
    def pi(self) -> float:
        """Performance index: sum over channels of RMSE - CC (lower is better)."""
        return float(np.sum(self.rmse - self.cc))


def tracking_score(target, achieved) -> TrackingScore:
    """RMSE, CC and PI of `achieved` against `target`, both shape (T, 6)."""
    target, achieved = _signals(target, achieved)
    if target.shape[1] != len(CHANNELS):
        raise ValueError(
            f"signals must have {len(CHANNELS)} channels {CHANNELS}; got {target.shape}"
        )
    return TrackingScore(rmse=rmse(target, achieved), cc=pearson_cc(target, achieved))


def performance_index(target, achieved) -> float:
    """PI of equation (10): sum over the six channels of RMSE - CC. Minimum -6."""
    return tracking_score(target, achieved).pi


# Rotation-rate thresholds of the semicircular canals about the head's x, y and z axes, rad/s:
# 3.0, 3.6 and 2.6 deg/s (Reid & Nahon 1985, the values motion-cueing studies use). A false
# rotation below them goes unnoticed; tilt coordination is rate-limited to about these.
ROTATION_THRESHOLD_RAD_S = tuple(float(v) for v in np.radians([3.0, 3.6, 2.6]))
# Specific-force thresholds of the otoliths along the head's x, y and z axes, m/s^2: 0.17,
# 0.17 and 0.28 (Reid & Nahon 1985, from the same review). A specific-force error below them
# goes unnoticed.
SPECIFIC_FORCE_THRESHOLD_M_S2 = (0.17, 0.17, 0.28)


@dataclasses.dataclass(frozen=True)
class FalseRotation:
    """Rotation the occupant feels that the vehicle did not make (see `false_rotation`)."""

    rms_deg_s: float  # RMS over time of the false rotation rate's norm, deg/s
    share_felt: float  # share of samples whose false rotation exceeds the thresholds, 0-1


def false_rotation(target, achieved) -> FalseRotation:
    """The false rotation cues of `achieved` against `target` (both (T, 6), channels as in
    the module docstring; only w_x, w_y, w_z are read).

    Per axis, the false part of the achieved rate w against the target w_r is |w| where
    the two differ in sign (a rotation the wrong way) and max(|w| - |w_r|, 0) where they
    agree (more rotation than the vehicle's); a missing rotation is not false. A sample is
    felt when the false rates, each divided by its axis's `ROTATION_THRESHOLD_RAD_S`, have a
    norm above 1. The PI prices rotation errors in rad/s beside specific-force errors in
    m/s^2, so an MCA can buy a better PI with large false rotations (a tuned NMPC swung the
    cabin at 50 deg/s RMS to sustain heave): this measure shows it.
    """
    target, achieved = _signals(target, achieved)
    if target.shape[1] != len(CHANNELS):
        raise ValueError(
            f"signals must have {len(CHANNELS)} channels {CHANNELS}; got {target.shape}"
        )
    w, w_r = achieved[:, :3], target[:, :3]
    same_way = np.sign(w) == np.sign(w_r)
    false = np.where(same_way, np.maximum(np.abs(w) - np.abs(w_r), 0.0), np.abs(w))
    felt = np.linalg.norm(false / np.asarray(ROTATION_THRESHOLD_RAD_S), axis=1) > 1.0
    return FalseRotation(
        rms_deg_s=float(np.degrees(np.sqrt(np.mean(np.sum(false**2, axis=1))))),
        share_felt=float(np.mean(felt)),
    )


@dataclasses.dataclass(frozen=True)
class Jolts:
    """How hard the cabin's motion changed from one control period to the next."""

    # largest |(f_x, f_y, a_z)_(k+1) - (f_x, f_y, a_z)_k| over the run, m/s^2 per period
    peak_force_change_m_s2: float
    # the same over the period: the head's peak jerk, m/s^3
    peak_jerk_m_s3: float
    # largest |w_(k+1) - w_k| over the period: the head's peak angular acceleration, rad/s^2
    peak_angular_acceleration_rad_s2: float


def jolts(achieved, time_step: float) -> Jolts:
    """The `Jolts` of the platform's outputs `achieved` (T, 6, channels as in the module
    docstring) sampled every `time_step` s: the largest change, as a vector norm, of the
    specific force (f_x, f_y, a_z) and of the angular velocity between two samples. A
    hazard in the reference (a spike, a reset) shows here as a jolt the clean run does not
    have (`mca_drake.cueing.plausibility`)."""
    achieved = as_float_array("achieved", achieved, last_dim=len(CHANNELS))
    if not time_step > 0:
        raise ValueError(f"time_step must be positive; got {time_step}")
    if achieved.shape[0] < 2:
        return Jolts(0.0, 0.0, 0.0)
    change = np.diff(achieved, axis=0)
    force = float(np.linalg.norm(change[:, 3:], axis=1).max())
    rate = float(np.linalg.norm(change[:, :3], axis=1).max())
    return Jolts(force, force / time_step, rate / time_step)


@dataclasses.dataclass(frozen=True)
class RankSumResult:
    """Wilcoxon rank-sum test: z statistic, two-sided p-value, medians of both samples."""

    z: float
    p: float
    median_a: float
    median_b: float

    def significant(self, alpha: float = 0.05) -> bool:
        """Whether the two distributions differ at level `alpha`."""
        return self.p < alpha


def wilcoxon_rank_sum(pi_a, pi_b) -> RankSumResult:
    """Two-sided Wilcoxon rank-sum test between two sets of PIs (the paper's test).

    Args:
        pi_a: 1-D array of performance indices, at least 2.
        pi_b: 1-D array of performance indices, at least 2.
    """
    a = as_float_array("pi_a", pi_a)
    b = as_float_array("pi_b", pi_b)
    if a.ndim != 1 or b.ndim != 1 or a.size < 2 or b.size < 2:
        raise ValueError(f"need two 1-D samples of at least 2; got shapes {a.shape}, {b.shape}")
    z, p = scipy.stats.ranksums(a, b)
    return RankSumResult(float(z), float(p), float(np.median(a)), float(np.median(b)))


@dataclasses.dataclass(frozen=True)
class SignedRankResult:
    """Wilcoxon signed-rank test on paired PIs (the same flights under two MCAs).

    Attributes:
        n: number of pairs.
        p: two-sided p-value (exact for small samples without ties, else normal).
        median_difference: median of pi_a - pi_b over the pairs (negative: a better).
        a_better: pairs in which pi_a < pi_b.
    """

    n: int
    p: float
    median_difference: float
    a_better: int


def wilcoxon_signed_rank(pi_a, pi_b) -> SignedRankResult:
    """Two-sided Wilcoxon signed-rank test of paired PIs: pi_a[i] and pi_b[i] come from the
    same flight. Pairing removes the flight-to-flight spread that the rank-sum test carries,
    so it sees smaller differences with the same number of flights.

    Args:
        pi_a: 1-D array of performance indices, at least 2.
        pi_b: 1-D array of the same length, paired with pi_a.
    """
    a = as_float_array("pi_a", pi_a)
    b = as_float_array("pi_b", pi_b)
    if a.ndim != 1 or a.shape != b.shape or a.size < 2:
        raise ValueError(f"need two paired 1-D samples of at least 2; got {a.shape}, {b.shape}")
    d = a - b
    if np.all(d == 0):  # scipy refuses all-zero differences; they are no evidence at all
        return SignedRankResult(int(a.size), 1.0, 0.0, 0)
    p = scipy.stats.wilcoxon(a, b, alternative="two-sided").pvalue
    return SignedRankResult(int(a.size), float(p), float(np.median(d)), int(np.sum(d < 0)))
