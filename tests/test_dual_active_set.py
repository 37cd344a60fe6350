"""Goldfarb and Idnani's dual active-set method against Drake's Clarabel on the same QPs."""

from __future__ import annotations

import numpy as np
import pytest
from test_active_set import assert_kkt, clarabel, random_qp

from mca_drake.cueing.active_set import active_rows
from mca_drake.cueing.dual_active_set import solve_dual_active_set
from mca_drake.cueing.nmpc import MotionCueingOcp, NmpcConfig


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
    config = NmpcConfig(horizon_steps=64, nodes=10, input_weight=1e-3, qp_solver="clarabel")
    ocp = MotionCueingOcp(config, robot)
    x0 = np.r_[0.9 * robot.q_max * np.array([1, 0.5, -0.5, 1, 0.5, -1]), 0.5 * robot.qd_max]
    refs = np.broadcast_to(6 * np.array([0.15, -0.1, 0.2, 1.2, -0.8, 0.6]), (ocp.N, 6))
    lo, hi = ocp.input_bounds(x0)
    ocp._first_input_box.set_bounds(lo[:6], hi[:6])
    U = np.zeros((ocp.N, 6))
    model = ocp._gauss_newton(x0, U, refs)
    lb, ub = ocp.constraint_bounds(x0)
    row_lo, row_hi = np.r_[lb, lo], np.r_[ub, hi]
    x_bar = ocp._update_qp(x0, U, refs, model.jac)
    U_drake, message = ocp._solve_qp(U, x_bar)
    assert U_drake is not None, message
    oracle = (U_drake - U).reshape(-1)
    right = active_rows(ocp._C, oracle, row_lo, row_hi, 1e-6)
    assert np.count_nonzero(right) >= 10  # many rows bind
    rng = np.random.default_rng(0)
    for guess in (None, np.roll(right, 6), rng.permutation(right)):
        solution = solve_dual_active_set(model.H, model.g, ocp._C, row_lo, row_hi, guess)
        assert solution is not None
        np.testing.assert_allclose(solution.d, oracle, atol=1e-6)
        assert_kkt(model.H, model.g, ocp._C, row_lo, row_hi, solution)
