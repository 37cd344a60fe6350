"""Synthetic references: band-limited random motion inside a vehicle class's flight envelope.

The oracles are independent of the generator: the certification load factors written out
here, the level-flight specific force of the conventions (0, 0, +9.81), Welch's power
spectrum, the RMS computed from the samples, and the reference formula of the conventions.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import welch

from mca_drake.references.jsbsim.fleet import RESERVED_MODELS, VEHICLE_CLASSES
from mca_drake.references.recording import check_units
from mca_drake.references.reference import ReferenceScaling
from mca_drake.references.synthetic import (
    ENVELOPES,
    MAX_RMS_SHARE,
    VEHICLE_ENVELOPES,
    SyntheticConfig,
    synthetic_recording,
    synthetic_reference,
)

G = 9.81
# Limit load factors (n_min, n_max) of the certification bases: 14 CFR / CS 23.337 normal and
# aerobatic categories, 14 CFR / CS 25.337, and the +9 / -3 g of current fighters.
LOAD_FACTORS = {
    "light": (-1.52, 3.8),
    "aerobatic": (-3.0, 6.0),
    "transport": (-1.0, 2.5),
    "fighter": (-3.0, 9.0),
}
# Level, unaccelerated flight in the recording channels omega_x..f_z (the conventions).
LEVEL = np.array([0.0, 0.0, 0.0, 0.0, 0.0, G])


def _samples(recording) -> np.ndarray:
    """omega_x, omega_y, omega_z, f_x, f_y, f_z, shape (T, 6)."""
    return np.column_stack([recording.omega, recording.f])


def _bounds(name: str) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest value of each channel: the envelope's rates and horizontal forces,
    the load factors from LOAD_FACTORS."""
    envelope = ENVELOPES[name]
    n_min, n_max = LOAD_FACTORS[name]
    high = np.array([*envelope.max_rates, *envelope.max_horizontal_force, n_max * G])
    low = np.array([*(-np.array(high[:5])), n_min * G])
    return low, high


def _nearer_limit(name: str) -> np.ndarray:
    """Distance from level flight to the nearer bound of each channel, shape (6,)."""
    low, high = _bounds(name)
    return np.minimum(LEVEL - low, high - LEVEL)


def test_envelopes_carry_the_certification_load_factors():
    assert set(ENVELOPES) == set(LOAD_FACTORS)
    for name, (n_min, n_max) in LOAD_FACTORS.items():
        assert ENVELOPES[name].load_factors == pytest.approx((n_min, n_max), abs=1e-12)
        # every bound is positive and leaves level flight inside
        low, high = ENVELOPES[name].channel_bounds()
        assert np.all(low < LEVEL) and np.all(LEVEL < high)


def test_every_fleet_vehicle_has_an_envelope():
    assert set(VEHICLE_ENVELOPES) == set(VEHICLE_CLASSES)
    assert set(VEHICLE_ENVELOPES.values()) <= set(ENVELOPES)
    assert not set(RESERVED_MODELS) & set(VEHICLE_ENVELOPES)
    assert VEHICLE_ENVELOPES["A320"] == "transport" and VEHICLE_ENVELOPES["f16"] == "fighter"


@pytest.mark.parametrize("name", sorted(LOAD_FACTORS))
@pytest.mark.parametrize("share", [0.25, MAX_RMS_SHARE])
def test_every_sample_is_inside_the_envelope(name, share):
    low, high = _bounds(name)
    for seed in range(12):
        config = SyntheticConfig(envelope=name, duration_s=30.0, seed=seed, rms_share=(share,) * 6)
        x = _samples(synthetic_recording(config))
        assert np.all(x >= low) and np.all(x <= high), (name, share, seed)
    if share == MAX_RMS_SHARE:
        # the extreme share presses the signal towards both limits of every channel
        assert np.all(x.max(axis=0) > high - 0.1 * (high - LEVEL))
        assert np.all(x.min(axis=0) < low + 0.1 * (LEVEL - low))


def test_a_synthetic_recording_reads_as_level_flight_with_gravity():
    """Specific force with gravity, z up: median f_z near +9.81, the units checks pass."""
    for name in LOAD_FACTORS:
        recording = synthetic_recording(SyntheticConfig(envelope=name, duration_s=120.0))
        check_units(recording, where=name)
        assert np.median(recording.f[:, 2]) == pytest.approx(G, rel=0.05)
        assert np.median(recording.f[:, :2], axis=0) == pytest.approx([0, 0], abs=0.1 * G)
        assert recording.t[0] == 0.0 and np.allclose(np.diff(recording.t), 0.01)


@pytest.mark.parametrize("band", [(0.05, 2.0), (0.5, 5.0)])
def test_the_power_lies_in_the_band(band):
    """Welch PSD of the mean-removed signal, 300 s at 100 Hz, 0.012 Hz bins.

    The band-pass run forward and back (|H|^4 of an 8th-order Butterworth band-pass) keeps
    97 % of white noise's power inside either band (for 0.05 to 2 Hz, 2.9 % leaks above the
    upper cut-off and 0.06 % below the lower, integrated from its frequency response). The
    default share's gentle saturation adds weak odd harmonics and Welch's Hann window spreads
    the lowest bins: the measured share over 40 seeds was at least 95.7 %. 94 % leaves room
    for other seeds and still catches an upper cut-off 20 % too high (86 %) or a filter of
    half the order (91 %)."""
    low, high = band
    fs = 100.0
    for seed in range(3):
        config = SyntheticConfig(
            envelope="fighter", duration_s=300.0, seed=seed, band_low_hz=low, band_high_hz=high
        )
        x = _samples(synthetic_recording(config))
        frequency, psd = welch(x - x.mean(axis=0), fs=fs, nperseg=2**13, axis=0)
        inside = (frequency >= low) & (frequency <= high)
        share = psd[inside].sum(axis=0) / psd.sum(axis=0)
        assert np.all(share >= 0.94), (band, seed, share)
        # beyond three times the upper cut-off the filter passes 3e-9 of white noise's power
        # and the saturation's harmonics measured 1e-6 (20 seeds)
        far = frequency > 3 * high
        assert np.all(psd[far].sum(axis=0) / psd.sum(axis=0) < 1e-4)


@pytest.mark.parametrize("name", sorted(LOAD_FACTORS))
def test_the_rms_is_the_configured_share(name):
    """RMS of the deviation from level flight against share x the nearer limit.

    Before the saturation each channel has exactly the gain that gives the target RMS after
    it for a Gaussian signal; what remains is how far one finite recording's compression
    differs from the expected one. It grows with the saturation and shrinks with the length:
    at the default share (a gain 7 % above the target) the largest error over 50 recordings
    of 60 s (300 channels) was 1.6 %, at a share of 0.5 it was 3.1 %. Tolerances: 3 % and
    5 %. A tiny share is almost unsaturated and hits the target to 1e-4."""
    for share, tolerance in ((0.25, 0.03), (0.5, 0.05), (0.01, 1e-4)):
        target = share * _nearer_limit(name)
        for seed in range(4):
            config = SyntheticConfig(
                envelope=name, duration_s=60.0, seed=seed, rms_share=(share,) * 6
            )
            deviation = _samples(synthetic_recording(config)) - LEVEL
            rms = np.sqrt(np.mean(deviation**2, axis=0))
            np.testing.assert_allclose(rms, target, rtol=tolerance, err_msg=f"{share}, {seed}")


def test_per_channel_shares():
    shares = (0.1, 0.2, 0.3, 0.4, 0.5, 0.15)
    config = SyntheticConfig(envelope="transport", duration_s=120.0, rms_share=shares)
    deviation = _samples(synthetic_recording(config)) - LEVEL
    rms = np.sqrt(np.mean(deviation**2, axis=0))
    np.testing.assert_allclose(rms, np.array(shares) * _nearer_limit("transport"), rtol=0.05)


def test_the_seed_decides_everything():
    config = SyntheticConfig(envelope="aerobatic", duration_s=20.0, seed=7)
    first, again = synthetic_recording(config), synthetic_recording(config)
    assert np.array_equal(first.as_array(), again.as_array())
    other = synthetic_recording(SyntheticConfig(envelope="aerobatic", duration_s=20.0, seed=8))
    assert np.all(np.abs(first.as_array()[:, 1:] - other.as_array()[:, 1:]).max(axis=0) > 0)
    # the channels are independent draws, not copies of one another
    x = _samples(first) - LEVEL
    correlation = np.corrcoef(x.T)
    assert np.all(np.abs(correlation[~np.eye(6, dtype=bool)]) < 0.5)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"duration_s": -1.0}, r"duration_s must be in"),
        ({"duration_s": 0.0}, r"duration_s must be in"),
        ({"duration_s": float("nan")}, r"duration_s must be a finite number"),
        ({"band_low_hz": 2.0, "band_high_hz": 2.0}, r"0.01 Hz <= band_low_hz < band_high_hz"),
        ({"band_low_hz": 3.0, "band_high_hz": 1.0}, r"band_low_hz = 3.0 Hz, band_high_hz = 1.0"),
        ({"band_low_hz": 0.0}, r"0.01 Hz <= band_low_hz < band_high_hz"),
        ({"band_low_hz": -0.5}, r"0.01 Hz <= band_low_hz < band_high_hz"),
        ({"band_low_hz": 1.0, "band_high_hz": 1.001}, r"at least 0.01 Hz apart"),
        ({"band_high_hz": 50.0}, r"below the Nyquist frequency 50 Hz"),
        ({"band_high_hz": 80.0}, r"below the Nyquist frequency 50 Hz"),
        ({"band_high_hz": 20.0, "time_step": 0.05}, r"Nyquist frequency 10 Hz"),
        ({"band_low_hz": float("nan")}, r"band_low_hz must be a finite number"),
        ({"envelope": "glider"}, r"unknown envelope 'glider'; valid: light, aerobatic"),
        ({"envelope": "737"}, r"unknown envelope '737'"),
        ({"rms_share": (0.25,) * 5}, r"rms_share must be 6 values"),
        ({"rms_share": (0.25,) * 5 + (1.0,)}, r"rms_share must be 6 values .* in \(0, 0.9\]"),
        ({"rms_share": (0.0,) * 6}, r"rms_share must be"),
        ({"rms_share": (0.25,) * 5 + (float("nan"),)}, r"rms_share must be a finite number"),
        ({"seed": -1}, r"seed must be in"),
        ({"time_step": 0.0}, r"time_step must be in"),
    ],
)
def test_bad_configs_are_refused_by_name(changes, message):
    config = SyntheticConfig(**changes)
    with pytest.raises(ValueError, match=message):
        config.validate()
    with pytest.raises(ValueError, match=message):
        synthetic_recording(config)


def test_the_reference_is_scaled_as_flights_are():
    config = SyntheticConfig(envelope="light", duration_s=12.0, seed=3)
    recording = synthetic_recording(config)
    reference = synthetic_reference(config)
    assert reference.y.shape == (1201, 6)
    assert reference.time_step == pytest.approx(0.01, abs=1e-12)
    # y_ref = [0.5 omega, 0.5 f_x, 0.5 f_y, 0.5 (f_z - 9.81)]
    expected = 0.5 * np.column_stack([recording.omega, recording.f[:, :2], recording.f[:, 2] - G])
    np.testing.assert_allclose(reference.y, expected, rtol=0, atol=1e-12)
    assert "synthetic" in reference.name and "light" in reference.name
    scaled = synthetic_reference(config, ReferenceScaling(angular_scale=1.0, force_scale=0.25))
    np.testing.assert_allclose(scaled.y[:, :3], recording.omega, atol=1e-12)
    np.testing.assert_allclose(scaled.y[:, 5], 0.25 * (recording.f[:, 2] - G), atol=1e-12)


def test_another_sample_period():
    config = SyntheticConfig(duration_s=10.0, time_step=0.02, band_high_hz=5.0)
    recording = synthetic_recording(config)
    assert recording.t.shape == (501,) and recording.t[-1] == pytest.approx(10.0)
    assert synthetic_reference(config).time_step == pytest.approx(0.02, abs=1e-12)
