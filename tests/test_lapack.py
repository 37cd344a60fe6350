"""The direct LAPACK wrappers against numpy's dense solves (an independent oracle)."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.qp.active_set import cholesky
from mca_drake.qp.lapack import cho_factor, cho_inverse, cho_solve, triangular_solve


@pytest.fixture
def spd():
    rng = np.random.default_rng(7)
    A = rng.normal(size=(40, 40))
    return A @ A.T + 0.5 * np.eye(40), rng


@pytest.mark.parametrize("columns", [None, 1, 7])
def test_cho_solve_matches_numpy(spd, columns):
    M, rng = spd
    b = rng.normal(size=40 if columns is None else (40, columns))
    x = cho_solve(cho_factor(M), b)
    assert x.shape == b.shape
    np.testing.assert_allclose(x, np.linalg.solve(M, b), rtol=1e-10, atol=1e-12)


def test_factor_is_upper_and_reproduces_the_matrix(spd):
    M, _ = spd
    triangle, lower = cho_factor(M)
    assert lower is False
    R = np.triu(triangle)
    np.testing.assert_allclose(R.T @ R, M, rtol=1e-12, atol=1e-10)


def test_cho_inverse_matches_numpy(spd):
    M, _ = spd
    inverse = cho_inverse(cho_factor(M))
    np.testing.assert_allclose(inverse, np.linalg.inv(M), rtol=1e-9, atol=1e-12)
    assert np.array_equal(inverse, inverse.T)


@pytest.mark.parametrize("transposed", [False, True])
def test_triangular_solve_matches_numpy(spd, transposed):
    M, rng = spd
    triangle, _ = cho_factor(M)
    R = np.triu(triangle)
    b = rng.normal(size=(40, 3)).T.copy().T  # a Fortran-ordered right-hand side too
    x = triangular_solve(triangle, b, lower=False, transposed=transposed)
    np.testing.assert_allclose(x, np.linalg.solve(R.T if transposed else R, b), rtol=1e-9)


def test_not_positive_definite_and_non_finite_are_refused():
    indefinite = np.diag([1.0, -1.0, 2.0])
    assert cho_factor(indefinite) is None
    assert cholesky(indefinite) is None
    assert cholesky(np.full((3, 3), np.nan)) is None
    # positive definite but so badly conditioned that its pivots say singular
    assert cholesky(np.diag([1.0, 1e-14])) is None


def test_singular_triangle_gives_non_finite_not_garbage():
    triangle = np.array([[1.0, 2.0], [0.0, 0.0]])
    x = triangular_solve(triangle, np.ones(2), lower=False, transposed=False)
    assert not np.all(np.isfinite(x))


def test_active_set_solvers_refuse_a_non_finite_gradient():
    """A NaN in g must give no solution, not a NaN one: the raw LAPACK calls skip scipy's
    finite checks, so the solvers check their inputs themselves."""
    from mca_drake.qp.active_set import solve_on_active_set
    from mca_drake.qp.dual_active_set import solve_dual_active_set

    H, C = np.eye(3), np.eye(3)
    g, lo, hi = np.array([np.nan, 1.0, 1.0]), -np.ones(3), np.ones(3)
    assert solve_on_active_set(H, g, C, lo, hi, np.zeros(3, dtype=np.int8)) is None
    assert solve_dual_active_set(H, g, C, lo, hi) is None
