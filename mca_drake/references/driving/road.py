"""Road roughness: random road profiles of the ISO 8608 classes.

ISO 8608 gives a road's vertical profile as a displacement power spectral density over the
spatial frequency n (cycles/m), G_d(n) = G_d(n0) (n / n0)^-w with n0 = 0.1 cycles/m and
waviness w = 2, and sorts roads into classes by G_d(n0): class A (very good) 16e-6 m^3,
each class after it four times the one before (B 64e-6, C 256e-6, D 1024e-6, E, F, G, H),
the geometric means of the standard's bands. `road_profile` draws one profile by spectral
synthesis: random phases over the standard's band 0.011 to 2.83 cycles/m (wavelengths of
90 m down to 0.35 m), amplitudes from the class's PSD, on a uniform grid.
"""

from __future__ import annotations

import numpy as np

# ISO 8608 classes and their G_d(n0), m^3 (geometric mean of each class's band).
ROAD_CLASSES = {c: 16e-6 * 4.0**i for i, c in enumerate("ABCDEFGH")}
REFERENCE_FREQUENCY = 0.1  # n0, cycles/m
WAVINESS = 2.0
# The spatial-frequency band ISO 8608 defines the classes over, cycles/m.
BAND = (0.011, 2.83)


def road_psd(n: np.ndarray, road_class: str) -> np.ndarray:
    """G_d(n) of an ISO 8608 class, m^3, at spatial frequencies n (cycles/m)."""
    if road_class not in ROAD_CLASSES:
        raise ValueError(f"unknown road class '{road_class}'; valid: {', '.join(ROAD_CLASSES)}")
    n = np.asarray(n, dtype=float)
    return ROAD_CLASSES[road_class] * (n / REFERENCE_FREQUENCY) ** -WAVINESS


def road_profile(
    length_m: float, road_class: str, rng: np.random.Generator, spacing_m: float = 0.05
) -> np.ndarray:
    """Heights of one random road profile of `road_class`, m, at 0, spacing_m, ... up to
    `length_m` (shape (N,)): the sum of cosines at the band's spatial frequencies on the
    grid 1 / (N spacing_m) apart, each of amplitude sqrt(2 G_d(n) dn) and a uniform random
    phase, so that its one-sided PSD is G_d(n) in the band and zero outside it."""
    if not (np.isfinite(length_m) and length_m > 0 and np.isfinite(spacing_m) and spacing_m > 0):
        raise ValueError(f"length_m and spacing_m must be positive; got {length_m}, {spacing_m}")
    count = int(np.ceil(length_m / spacing_m)) + 1
    # at least one of the band's longest waves, so that its lowest frequencies are on the grid
    size = max(count, int(np.ceil(1.0 / (BAND[0] * spacing_m))) + 1)
    n = np.fft.rfftfreq(size, spacing_m)
    dn = 1.0 / (size * spacing_m)
    inside = (n >= BAND[0]) & (n <= BAND[1])
    amplitude = np.zeros_like(n)
    amplitude[inside] = np.sqrt(2.0 * road_psd(n[inside], road_class) * dn)
    phase = rng.uniform(0.0, 2.0 * np.pi, n.size)
    # irfft of (size / 2) A e^{i phi} is sum_k A_k cos(2 pi n_k x + phi_k)
    spectrum = 0.5 * size * amplitude * np.exp(1j * phase)
    return np.fft.irfft(spectrum, size)[:count]
