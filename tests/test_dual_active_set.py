"""Goldfarb and Idnani's dual active-set method against Drake's Clarabel on the same QPs."""

from __future__ import annotations

import numpy as np
import pytest
from test_active_set import assert_kkt, clarabel, nmpc_qp_at_the_limits, random_qp

from mca_drake.qp.active_set import active_rows
from mca_drake.qp.dual_active_set import solve_dual_active_set


@pytest.mark.parametrize("seed", range(10))
def test_from_nothing_it_finds_clarabels_optimum(seed):
    rng = np.random.default_rng(seed)
    H, g, C, lo, hi = random_qp(rng, n=15, m=45)
    oracle = clarabel(H, g, C, lo, hi)
    assert np.count_nonzero(active_rows(C, oracle, lo, hi, 1e-7)) >= 2
    solution = solve_dual_active_set(H, g, C, lo, hi)
    assert solution is not None and solution.corrections >= 2  # it took steps
    np.testing.assert_allclose(solution.d, oracle, atol=1e-6)
    assert_kkt(H, g, C, lo, hi, solution)


@pytest.mark.parametrize("seed", range(6))
def test_any_wrong_guess_ends_at_the_same_optimum(seed):
    """Guesses with rows missing, rows wrongly active (either side) and random noise: the
    dual-feasible part is kept and the method ends at Clarabel's optimum every time."""
    rng = np.random.default_rng(100 + seed)
    H, g, C, lo, hi = random_qp(rng, n=15, m=45)
    oracle = clarabel(H, g, C, lo, hi)
    right = active_rows(C, oracle, lo, hi, 1e-7)
    missing = right.copy()
    missing[np.flatnonzero(right)[: max(1, np.count_nonzero(right) // 2)]] = 0
    flipped = -right
    noise = rng.integers(-1, 2, size=C.shape[0]).astype(np.int8)
    for guess in (right, missing, flipped, noise):
        solution = solve_dual_active_set(H, g, C, lo, hi, guess)
        assert solution is not None
        np.testing.assert_allclose(solution.d, oracle, atol=1e-6)
        assert_kkt(H, g, C, lo, hi, solution)
    exact = solve_dual_active_set(H, g, C, lo, hi, right)
    assert exact.corrections == 0  # the right guess needs no step


def test_infeasible_constraints_are_refused():
    """x >= 1 and x <= -1 on the same variable: no point satisfies both, so None."""
    H, g = np.eye(2), np.zeros(2)
    C = np.array([[1.0, 0.0], [1.0, 0.0]])
    lo, hi = np.array([1.0, -np.inf]), np.array([np.inf, -1.0])
    assert solve_dual_active_set(H, g, C, lo, hi) is None


def test_non_finite_input_is_refused_not_iterated():
    rng = np.random.default_rng(3)
    H, g, C, lo, hi = random_qp(rng)
    g[2] = np.nan
    assert solve_dual_active_set(H, g, C, lo, hi) is None
    g[2], hi[4] = 0.0, np.nan
    assert solve_dual_active_set(H, g, C, lo, hi) is None


def test_the_step_cap_bounds_the_work():
    """Capped below the steps a cold start needs: refused (the NMPC then asks Drake)."""
    rng = np.random.default_rng(0)
    H, g, C, lo, hi = random_qp(rng, n=15, m=45)
    steps = solve_dual_active_set(H, g, C, lo, hi).corrections
    assert steps >= 2
    assert solve_dual_active_set(H, g, C, lo, hi, max_steps=steps - 1) is None


def test_parallel_rows_are_handled_by_dropping_the_weaker():
    """The box on u_0 and the node-1 row that is its multiple (x <= 1 and 2 x <= 1): the
    tighter one ends active, as in the closed-form optimum (0.5, 5)."""
    H, g = np.eye(2), np.array([-5.0, -5.0])
    C = np.array([[1.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    lo, hi = np.full(3, -1.0), np.array([1.0, 1.0, 10.0])
    for guess in (None, np.array([1, 0, 0]), np.array([1, 1, 0])):
        solution = solve_dual_active_set(H, g, C, lo, hi, guess)
        assert solution is not None
        np.testing.assert_allclose(solution.d, [0.5, 5.0], atol=1e-12)
        assert_kkt(H, g, C, lo, hi, solution)


def test_the_nmpc_qp_at_its_limits_equals_drakes_solution(robot):
    """The real OCP's Gauss-Newton QP from a state that pushes joints to their limits, at
    weights that put many inputs on their bounds: from nothing, from a stale guess and from
    a shuffled one, the step equals the one Drake's Clarabel finds."""
    ocp, model, row_lo, row_hi, oracle = nmpc_qp_at_the_limits(
        robot, horizon_steps=64, nodes=10, input_weight=1e-3
    )
    right = active_rows(ocp._C, oracle, row_lo, row_hi, 1e-6)
    assert np.count_nonzero(right) >= 10  # many rows bind
    rng = np.random.default_rng(0)
    for guess in (None, np.roll(right, 6), rng.permutation(right)):
        solution = solve_dual_active_set(model.H, model.g, ocp._C, row_lo, row_hi, guess)
        assert solution is not None
        np.testing.assert_allclose(solution.d, oracle, atol=1e-6)
        assert_kkt(model.H, model.g, ocp._C, row_lo, row_hi, solution)
