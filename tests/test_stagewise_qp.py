"""The stage-wise interior-point QP solver: it reaches the optimum of a dense KKT solve
(no bounds) and of Clarabel on Drake's MathematicalProgram (with bounds), its multipliers
satisfy the KKT conditions, and it refuses bad input."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.cueing.stagewise_qp import solve_stagewise_qp


def _problem(seed: int, N: int = 25, m: int = 5, ns: int = 3, per_stage: bool = False):
    """A random stage-wise QP: PSD stage Hessians with a direction of no curvature,
    dynamics constant or per stage, boxes some of which are one-sided or absent."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(N, m, m))
    Q = 0.5 * A @ np.swapaxes(A, 1, 2)
    Q[:, 0, :] = Q[:, :, 0] = 0.0  # the first state: no curvature of its own
    b = rng.normal(size=(N, m))
    F = 0.5 * rng.normal(size=(N - 1, ns, m) if per_stage else (ns, m))
    lower, upper = np.full((N, m), -0.3), np.full((N, m), 0.4)
    lower[:, 1], upper[:, 2] = -np.inf, np.inf
    lower[:, m - 1], upper[:, m - 1] = -np.inf, np.inf
    initial = np.array([0.1, -0.2, 0.05])[:ns]
    return Q, b, F, lower, upper, initial


def _objective(Q, b, w) -> float:
    return float(0.5 * np.einsum("ki,kij,kj->", w, Q, w) + np.einsum("ki,ki->", b, w))


def _dynamics_residual(F, w, initial) -> float:
    ns = initial.shape[0]
    successors = (
        np.einsum("ij,kj->ki", F, w[:-1]) if F.ndim == 2 else np.einsum("kij,kj->ki", F, w[:-1])
    )
    return max(np.abs(w[0, :ns] - initial).max(), np.abs(w[1:, :ns] - successors).max())


def test_without_bounds_it_is_the_dense_kkt_solution():
    """Closed form: with no boxes the QP's solution is that of its KKT linear system,
    solved densely here (the Hessians made positive definite so that it is unique)."""
    Q, b, F, _, _, initial = _problem(1, N=12)
    N, m = b.shape
    ns = initial.shape[0]
    Q = Q + 0.1 * np.eye(m)
    H = np.zeros((N * m, N * m))
    for k in range(N):
        H[k * m : (k + 1) * m, k * m : (k + 1) * m] = Q[k]
    E = np.zeros((N * ns, N * m))
    E[:ns, :ns] = np.eye(ns)
    for k in range(1, N):
        E[k * ns : (k + 1) * ns, k * m : k * m + ns] = np.eye(ns)
        E[k * ns : (k + 1) * ns, (k - 1) * m : k * m] = -F
    f = np.zeros(N * ns)
    f[:ns] = initial
    kkt = np.block([[H, E.T], [E, np.zeros((N * ns, N * ns))]])
    expected = np.linalg.solve(kkt, np.concatenate([-b.reshape(-1), f]))
    unbounded = np.full((N, m), np.inf)
    ours = solve_stagewise_qp(Q, b, F, -unbounded, unbounded, initial, tolerance=1e-12)
    assert ours.converged
    np.testing.assert_allclose(ours.w.reshape(-1), expected[: N * m], atol=1e-9)
    np.testing.assert_allclose(ours.multipliers.reshape(-1), expected[N * m :], atol=1e-8)


@pytest.mark.parametrize(
    "per_stage", [False, True], ids=["constant dynamics", "per-stage dynamics"]
)
@pytest.mark.parametrize("seed", [2, 3])
def test_with_bounds_it_is_clarabels_optimum_and_meets_the_kkt_conditions(seed, per_stage):
    from pydrake.solvers import ClarabelSolver, MathematicalProgram, SolverOptions

    Q, b, F, lower, upper, initial = _problem(seed, per_stage=per_stage)
    N, m = b.shape
    ns = initial.shape[0]
    ours = solve_stagewise_qp(Q, b, F, lower, upper, initial, tolerance=1e-10)
    assert ours.converged and ours.residual <= 1e-10

    prog = MathematicalProgram()
    W = prog.NewContinuousVariables(N, m)
    for k in range(N):
        prog.AddQuadraticCost(Q[k], b[k], W[k], is_convex=True)
        prog.AddBoundingBoxConstraint(lower[k], upper[k], W[k])
    prog.AddLinearEqualityConstraint(np.eye(ns), initial, W[0, :ns])
    for k in range(N - 1):
        Fk = F if F.ndim == 2 else F[k]
        prog.AddLinearEqualityConstraint(
            np.hstack([np.eye(ns), -Fk]), np.zeros(ns), np.concatenate([W[k + 1, :ns], W[k]])
        )
    solver, options = ClarabelSolver(), SolverOptions()
    for option in ("tol_gap_abs", "tol_gap_rel", "tol_feas"):
        options.SetOption(solver.solver_id(), option, 1e-10)
    theirs = solver.Solve(prog, None, options)
    assert theirs.is_success()
    assert _objective(Q, b, ours.w) == pytest.approx(theirs.get_optimal_cost(), abs=1e-8)
    np.testing.assert_allclose(ours.w, theirs.GetSolution(W), atol=1e-5)

    # the KKT conditions, from the returned multipliers
    assert _dynamics_residual(F, ours.w, initial) <= 1e-9
    assert np.all(ours.w >= lower - 1e-9) and np.all(ours.w <= upper + 1e-9)
    lam = ours.multipliers
    Etlam = np.zeros((N, m))
    Etlam[:, :ns] = lam
    Fs = np.broadcast_to(F, (N - 1, ns, m)) if F.ndim == 2 else F
    Etlam[:-1] -= np.einsum("kij,ki->kj", Fs, lam[1:])
    gradient = np.einsum("kij,kj->ki", Q, ours.w) + b
    np.testing.assert_allclose(gradient + Etlam + ours.bound_multipliers, 0.0, atol=1e-8)
    z = ours.bound_multipliers
    # a box's multiplier pushes back only where the box holds w, and never pulls
    assert np.all(z[ours.w < upper - 1e-6].clip(min=0) <= 1e-7), z[ours.w < upper - 1e-6].max()
    assert np.all(np.abs(z[ours.w > lower + 1e-6].clip(max=0)) <= 1e-7)


def test_a_qp_with_no_feasible_point_reports_that_it_did_not_converge():
    """Boxes the dynamics cannot meet: the first state is held at 0.1 by the initial
    value but boxed to [-0.05, 0.05]; the solver stops at its iteration cap, converged
    False, without an exception."""
    Q, b, F, lower, upper, initial = _problem(4, N=10)
    lower[0, 0], upper[0, 0] = -0.05, 0.05
    solution = solve_stagewise_qp(Q, b, F, lower, upper, initial, max_iterations=40)
    assert not solution.converged and solution.iterations == 40
    assert solution.residual > 1e-6


def test_bad_input_is_refused():
    Q, b, F, lower, upper, initial = _problem(5, N=6)
    with pytest.raises(ValueError, match="Q must have shape"):
        solve_stagewise_qp(Q[:-1], b, F, lower, upper, initial)
    with pytest.raises(ValueError, match="F must have shape"):
        solve_stagewise_qp(Q, b, F[:, :-1], lower, upper, initial)
    with pytest.raises(ValueError, match="initial must have shape"):
        solve_stagewise_qp(Q, b, F, lower, upper, np.zeros(9))
    bad = b.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="b has non-finite values"):
        solve_stagewise_qp(Q, bad, F, lower, upper, initial)
    with pytest.raises(ValueError, match="lower <= upper"):
        solve_stagewise_qp(Q, b, F, upper, lower, initial)
