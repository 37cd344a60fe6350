"""The hot-started active-set QP solve against Drake's Clarabel on the same QPs."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.solvers import ClarabelSolver, MathematicalProgram, SolverOptions

from mca_drake.cueing.nmpc import MotionCueingOcp, NmpcConfig
from mca_drake.qp.active_set import active_rows, solve_on_active_set


def random_qp(rng, n=12, m=30):
    """A strictly convex QP whose unconstrained minimum violates some of its rows."""
    M = rng.normal(size=(n, n))
    H = M @ M.T + 0.1 * np.eye(n)
    g = rng.normal(size=n) * 5
    C = rng.normal(size=(m, n))
    lo = -rng.uniform(0.2, 1.0, m)
    hi = rng.uniform(0.2, 1.0, m)
    lo[::4] = -np.inf  # one-sided rows
    hi[1::5] = np.inf
    return H, g, C, lo, hi


def clarabel(H, g, C, lo, hi):
    prog = MathematicalProgram()
    d = prog.NewContinuousVariables(H.shape[0])
    prog.AddQuadraticCost(H, g, d, is_convex=True)
    prog.AddLinearConstraint(C, lo, hi, d)
    options = SolverOptions()
    for name in ("tol_gap_abs", "tol_gap_rel", "tol_feas"):
        options.SetOption(ClarabelSolver().solver_id(), name, 1e-11)
    result = ClarabelSolver().Solve(prog, None, options)
    assert result.is_success()
    return result.GetSolution(d)


def assert_kkt(H, g, C, lo, hi, solution):
    """Feasible, complementary, lambda >= 0, stationary: the QP's optimum."""
    d, lam, side = solution.d, solution.multipliers, solution.active
    value = C @ d
    assert np.all(value <= hi + 1e-8) and np.all(value >= lo - 1e-8)
    assert np.all(lam >= 0) and np.all(lam[side == 0] == 0)
    at = np.where(side > 0, hi, np.where(side < 0, lo, value))
    np.testing.assert_allclose(value[side != 0], at[side != 0], atol=1e-9)
    np.testing.assert_allclose(H @ d + g + C.T @ (side * lam), 0.0, atol=1e-8)


@pytest.mark.parametrize("seed", range(8))
def test_a_corrected_guess_finds_clarabels_optimum(seed):
    rng = np.random.default_rng(seed)
    H, g, C, lo, hi = random_qp(rng)
    oracle = clarabel(H, g, C, lo, hi)
    exact_guess = active_rows(C, oracle, lo, hi, 1e-7)
    assert np.count_nonzero(exact_guess) > 0  # the test exercises active rows
    solution = solve_on_active_set(H, g, C, lo, hi, exact_guess)
    assert solution is not None and solution.corrections == 0
    np.testing.assert_allclose(solution.d, oracle, atol=1e-6)
    assert_kkt(H, g, C, lo, hi, solution)
    # From nothing active, corrections either reach the same optimum or give up (None):
    # never anything else.
    cold = solve_on_active_set(H, g, C, lo, hi, np.zeros(C.shape[0]), max_corrections=10)
    if cold is not None:
        np.testing.assert_allclose(cold.d, oracle, atol=1e-6)
        assert_kkt(H, g, C, lo, hi, cold)


def test_a_wrong_guess_is_never_returned():
    """A guess missing one active row: refused outright without corrections; with them,
    either corrected to the optimum or refused (the caller then solves in full)."""
    corrected = 0
    for seed in range(6):
        rng = np.random.default_rng(seed)
        H, g, C, lo, hi = random_qp(rng)
        oracle = clarabel(H, g, C, lo, hi)
        right = active_rows(C, oracle, lo, hi, 1e-7)
        for row in np.flatnonzero(right)[:3]:
            wrong = right.copy()
            wrong[row] = 0
            assert solve_on_active_set(H, g, C, lo, hi, wrong, max_corrections=0) is None
            fixed = solve_on_active_set(H, g, C, lo, hi, wrong, max_corrections=10)
            if fixed is not None:
                assert fixed.corrections >= 1
                np.testing.assert_allclose(fixed.d, oracle, atol=1e-6)
                assert_kkt(H, g, C, lo, hi, fixed)
                corrected += 1
    assert corrected >= 3  # the corrections do work


def test_dependent_active_rows_are_reduced_to_an_independent_set():
    """The same row twice, both active (as the box on u_0 and the node row it comes from are
    at the robot's limits): solved on one of them, with the optimum Clarabel finds."""
    H, g = np.eye(2), np.array([-5.0, -5.0])
    C = np.array([[1.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    lo, hi = np.full(3, -1.0), np.array([1.0, 2.0, 10.0])
    solution = solve_on_active_set(H, g, C, lo, hi, np.array([1, 1, 0]))
    assert solution is not None
    np.testing.assert_allclose(solution.d, clarabel(H, g, C, lo, hi), atol=1e-6)
    np.testing.assert_allclose(solution.d, [1.0, 5.0], atol=1e-12)
    assert_kkt(H, g, C, lo, hi, solution)
    # dependent rows that cannot both hold with equality (x <= 1 and 2 x <= 1): the one
    # kept first may be the wrong one; the result is still verified, or refused
    hi_tight = np.array([1.0, 1.0, 10.0])
    oracle = clarabel(H, g, C, lo, hi_tight)
    np.testing.assert_allclose(oracle, [0.5, 5.0], atol=1e-6)
    tight = solve_on_active_set(H, g, C, lo, hi_tight, np.array([1, 1, 0]))
    assert tight is not None
    np.testing.assert_allclose(tight.d, oracle, atol=1e-6)
    assert_kkt(H, g, C, lo, hi_tight, tight)


def nmpc_qp_at_the_limits(robot, **config):
    """The real OCP's first Gauss-Newton QP from a state that pushes joints to their limits,
    with Drake's Clarabel solution of it as the oracle: (ocp, model, row_lo, row_hi, the
    oracle's step (6N,))."""
    ocp = MotionCueingOcp(NmpcConfig(qp_solver="clarabel", **config), robot)
    x0 = np.r_[0.9 * robot.q_max * np.array([1, 0.5, -0.5, 1, 0.5, -1]), 0.5 * robot.qd_max]
    refs = np.broadcast_to(6 * np.array([0.15, -0.1, 0.2, 1.2, -0.8, 0.6]), (ocp.N, 6))
    lo, hi = ocp.input_bounds(x0)
    ocp._shooting.set_first_input_bounds(lo[:6], hi[:6])
    U = np.zeros((ocp.N, 6))
    model = ocp._gauss_newton(x0, U, refs)
    lb, ub = ocp.constraint_bounds(x0)
    row_lo, row_hi = np.r_[lb, lo], np.r_[ub, hi]
    x_bar = ocp._update_qp(x0, U, refs, model.jac)
    U_drake, message = ocp._solve_qp(U, x_bar)
    assert U_drake is not None, message
    return ocp, model, row_lo, row_hi, (U_drake - U).reshape(-1)


def test_the_nmpc_step_equals_drakes_qp_solution(robot):
    """On the real OCP, from a state that pushes joints to their limits, the hot-started
    Gauss-Newton step equals the step Drake's Clarabel finds for the same QP."""
    ocp, model, row_lo, row_hi, oracle = nmpc_qp_at_the_limits(robot, horizon_steps=40, nodes=6)
    guess = active_rows(ocp._C, oracle, row_lo, row_hi, 1e-6)
    assert np.count_nonzero(guess) > 0
    solution = solve_on_active_set(model.H, model.g, ocp._C, row_lo, row_hi, guess)
    assert solution is not None
    # Clarabel's interior point is accurate to a few 1e-6 here (the tuned weights, up to 233,
    # make H stiffer than the paper's): the steps agree to that, and the exact step is
    # feasible and costs no more than the oracle's.
    np.testing.assert_allclose(solution.d, oracle, atol=1e-5)
    rows = ocp._C @ solution.d
    assert np.all(rows >= row_lo - 1e-9) and np.all(rows <= row_hi + 1e-9)

    def cost(d):
        return 0.5 * d @ model.H @ d + model.g @ d

    assert cost(solution.d) <= cost(oracle) + 1e-9 * abs(cost(oracle))


def test_converged_mode_stops_on_its_kkt_tolerance(robot):
    config = NmpcConfig(
        mode="converged", horizon_steps=40, nodes=6, kkt_tolerance=1e-9, step_tolerance=1e-12
    )
    ocp = MotionCueingOcp(config, robot)
    x0 = np.r_[0.3 * robot.q_max, 0.2 * robot.qd_max]
    result = ocp.solve(x0, 6 * np.array([0.15, -0.1, 0.2, 1.2, -0.8, 0.6]))
    assert result.success and result.iterations < config.max_iterations
    assert result.stop == "kkt" and result.kkt_residual <= 1e-9 * max(1.0, result.cost)
    assert ocp.is_feasible(x0, result.U, tol=1e-9)
