"""Cholesky factorisation and solves by LAPACK directly, for the NMPC's small dense QPs.

The converged NMPC factors and solves with matrices of order 120 some fifty times per
control step. scipy.linalg's `cho_factor`, `cho_solve` and `solve_triangular` add 7-10 us
of argument handling per call to LAPACK's 40-100 us (scipy 1.17, one BLAS thread): about
0.4 ms of a 15 ms step. These wrappers call the same LAPACK routines (dpotrf, dpotrs,
dtrtrs, dpotri) with the inputs the NMPC already guarantees (float64, finite where it matters,
checked by the callers) and keep scipy's factor format, (triangle, lower), so either can
be passed where the other is expected.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

# Factors are upper triangles (H = R^T R), as scipy.linalg.cho_factor's default.
LOWER = False


def cho_factor(M: np.ndarray) -> tuple[np.ndarray, bool] | None:
    """(R, False) with M = R^T R (R in the upper triangle; the lower one holds M's entries),
    or None when LAPACK finds a non-positive pivot. M: (n, n) symmetric, float64."""
    triangle, info = lapack.dpotrf(M, lower=LOWER, clean=False)
    if info != 0:
        return None
    return triangle, LOWER


def cho_solve(factor: tuple[np.ndarray, bool], b: np.ndarray) -> np.ndarray:
    """x with M x = b, from `cho_factor(M)` (or scipy's); b: (n,) or (n, k)."""
    triangle, lower = factor
    x, info = lapack.dpotrs(triangle, b, lower=lower)
    if info != 0:  # only an argument LAPACK rejects: a programming error here
        raise ValueError(f"dpotrs: illegal argument {-info}")
    return x


def cho_inverse(factor: tuple[np.ndarray, bool]) -> np.ndarray | None:
    """M^-1 (symmetric, full) from `cho_factor(M)` (dpotri: a third cheaper than solving for
    the identity); None if LAPACK reports a zero pivot."""
    triangle, lower = factor
    inverse, info = lapack.dpotri(triangle, lower=lower)
    if info != 0:
        return None
    half = np.tril(inverse) if lower else np.triu(inverse)
    return half + half.T - np.diag(np.diag(half))


def triangular_solve(
    triangle: np.ndarray, b: np.ndarray, *, lower: bool, transposed: bool
) -> np.ndarray:
    """x with T x = b (or T^T x = b when `transposed`) for the triangle T of `triangle`
    (its `lower` or upper part; the other is ignored); b: (n,) or (n, k).

    A singular triangle gives non-finite x (the callers check their results)."""
    x, info = lapack.dtrtrs(triangle, b, lower=int(lower), trans=int(transposed))
    if info < 0:
        raise ValueError(f"dtrtrs: illegal argument {-info}")
    if info > 0:  # an exactly zero diagonal entry: LAPACK leaves x unsolved
        return np.full(np.shape(b), np.nan)
    return x
