"""Goldfarb and Idnani's dual active-set method for a small dense convex QP, hot-started.

    minimise 1/2 d^T H d + g^T d   subject to   lo <= C d <= hi   (C: (m, n))

with H symmetric positive definite (the notation of `mca_drake.qp.active_set`). The
method keeps a primal point d that minimises the cost on a set A of constraints held as
equalities, with multipliers lambda_A >= 0 (dual feasible), and repeatedly takes the most
violated constraint p: it raises p's multiplier from 0, moving d along the direction that
keeps A's rows at their bounds, until p holds (p joins A) or a multiplier of A reaches 0
first (that row leaves A, and p is pursued further). The dual objective rises at every step,
so no active set repeats and the method ends, exactly, in finitely many steps: at the QP's
solution, or with a proof that the constraints cannot all hold (Goldfarb and Idnani, "A
numerically stable dual method for solving strictly convex quadratic programs", Math.
Programming 27, 1983).

Why here: the NMPC's hot start (`active_set.solve_on_active_set`) corrects a guessed active
set by changing every offending row at once; where dozens of rows change between two control
steps (at the tuned weights many inputs sit at their limits and switch) that heuristic does
not settle, and Drake's OSQP, used then, returned active sets so inexact (at its 1e-3
tolerance) that the next step's guess was poor too. This method always returns the exact
active set, in a bounded time that grows with the number of rows that change.

Hot start: the guessed set, less the rows whose multipliers come out negative (dropped
until none is), is a valid starting point: it is dual feasible and d minimises on it. Each
step costs O(n k) with the inverse of the active rows' Schur complement
S = N_A H^-1 N_A^T (k x k) updated, not refactored, as rows join and leave. The result is
checked (stationarity, feasibility, signs) before it is returned, so round-off in those
updates can never pass unnoticed: the caller then falls back.
"""

from __future__ import annotations

import dataclasses

import numpy as np

import mca_drake.qp.lapack as lapack
from mca_drake.qp.active_set import (
    DUAL_TOLERANCE,
    PRIMAL_TOLERANCE,
    ActiveSetSolution,
    _one_per_group,
    cholesky,
    solve_on_active_set,
)

# A direction whose constraint curvature n_p^T z is below this fraction of n_p^T H^-1 n_p
# means the new row depends on the active ones (it cannot be made active without a drop).
DEPENDENCE_RATIO = 1e-10
# The result's stationarity |H d + g + N_A^T lambda|_inf may be at most this times
# max(1, |g|_inf, |H d|_inf), and its active rows at most PRIMAL_TOLERANCE from their
# bounds: beyond either, the rank-one updates have drifted and one KKT solve polishes it.
STATIONARITY_TOLERANCE = 1e-8
# Rounds of dropping wrong-signed multipliers from the guess before starting from nothing.
START_ROUNDS = 20


def solve_dual_active_set(
    H: np.ndarray,
    g: np.ndarray,
    C: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    guess: np.ndarray | None = None,
    *,
    cholesky_of_H: tuple | None = None,
    row_norms: np.ndarray | None = None,
    groups: np.ndarray | None = None,
    max_steps: int | None = None,
) -> ActiveSetSolution | None:
    """Solves the QP from the dual-feasible part of a guessed active set.

    Args:
        H: (n, n) symmetric positive definite. g: (n,). C: (m, n). lo, hi: (m,), may be
            infinite (lo <= hi).
        guess: (m,) in {-1, 0, +1}: rows guessed at their lower (-1) or upper (+1) bound;
            None: start from the unconstrained minimiser.
        cholesky_of_H: `cholesky(H)` (or scipy's cho_factor) when the caller has it already.
        row_norms: the Euclidean norms of C's rows (m,), when the caller has them: the most
            violated row is chosen by its distance, not by its raw residual.
        groups: `active_set.parallel_groups(C)` when the caller has it: of parallel rows in
            the guess only the first is kept (two would make the start singular).
        max_steps: a cap on the steps, which bounds the time; reaching it returns None
            (default 10 n: from a wrong guess the NMPC's QPs took at most 56 steps for
            n = 120; a cold start at the robot's limits took 316 for n = 60).

    Returns:
        The verified solution (its `corrections` counts the steps taken), or None when the
        constraints are infeasible, the cap is reached, an input is not finite, or round-off
        spoilt the result.
    """
    n = H.shape[0]
    if not (np.all(np.isfinite(g)) and not np.any(np.isnan(lo)) and not np.any(np.isnan(hi))):
        return None
    factor = cholesky_of_H if cholesky_of_H is not None else cholesky(H)
    if factor is None:
        return None
    if row_norms is None:
        row_norms = np.linalg.norm(C, axis=1)
    row_norms = np.where(row_norms > 0, row_norms, 1.0)
    max_steps = 10 * n if max_steps is None else max_steps
    H_inv = None  # formed at the first step: a right guess needs none
    H_inv_g = lapack.cho_solve(factor, g)
    # The active set, in arrays of capacity n (independent rows are at most n): row index,
    # signed row (side * C_i, so every active row reads N_i d = b_i with lambda_i >= 0),
    # H^-1 N_i^T, the multipliers, and S^-1.
    index = np.empty(n, dtype=np.intp)
    signed_rows = np.empty((n, n))
    H_inv_rows = np.empty((n, n))
    lam = np.empty(n)
    S_inv = np.empty((n, n))
    if guess is not None and groups is not None:
        guess = _one_per_group(np.asarray(guess), groups)
    k, d, schur = _hot_start(factor, H_inv_g, C, lo, hi, guess, index, signed_rows, lam)
    steps = 0
    while True:
        value = C @ d
        excess = np.maximum(value - hi, lo - value)
        p = int(np.argmax(excess / row_norms))
        if excess[p] <= PRIMAL_TOLERANCE:
            break
        side = 1.0 if value[p] > hi[p] else -1.0
        n_p = side * C[p]
        b_p = hi[p] if side > 0 else -lo[p]
        if H_inv is None:
            H_inv = lapack.cho_inverse(factor)
            if H_inv is None:
                return None
            if k:  # the start's H^-1 N^T and S^-1: only steps need them (a right guess none)
                H_inv_rows[:, :k] = H_inv @ signed_rows[:k].T
                S_inv_k = lapack.cho_inverse(schur)
                if S_inv_k is None:
                    return None
                S_inv[:k, :k] = S_inv_k
        h = H_inv @ n_p
        n_h = float(n_p @ h)
        lam_p = 0.0
        while True:  # raise p's multiplier until p holds
            steps += 1
            if steps > max_steps:
                return None
            if k:
                col = signed_rows[:k] @ h  # N_A H^-1 n_p
                r = S_inv[:k, :k] @ col  # the active multipliers fall at rate r
                z = h - H_inv_rows[:, :k] @ r  # d falls at rate z
                curvature = n_h - float(col @ r)
            else:
                r, z, curvature = None, h, n_h
            # p depends on the active rows (or n rows are active already): it cannot join
            independent = k < n and curvature > DEPENDENCE_RATIO * n_h
            full = float(n_p @ d - b_p) / curvature if independent else np.inf
            partial, leaving = np.inf, -1
            if k:
                falling = np.flatnonzero(r > 0)
                if falling.size:
                    ratios = lam[falling] / r[falling]
                    best = int(np.argmin(ratios))
                    partial, leaving = float(ratios[best]), int(falling[best])
            if full == np.inf and partial == np.inf:
                return None  # no multiplier can block and p cannot be reached: infeasible
            t = min(full, partial)
            d = d - t * z
            if k:
                lam[:k] -= t * r
            lam_p += t
            if partial < full:
                k = _drop(leaving, k, index, signed_rows, H_inv_rows, lam, S_inv)
                continue
            if k:  # S^-1 grows by one row and column (block inverse with Schur complement)
                S_inv[:k, :k] += np.outer(r, r) / curvature
                S_inv[:k, k] = S_inv[k, :k] = -r / curvature
            S_inv[k, k] = 1.0 / curvature
            index[k], signed_rows[k], H_inv_rows[:, k], lam[k] = p, n_p, h, lam_p
            k += 1
            break
    solution = (d, value, index[:k], signed_rows[:k], lam[:k])
    return _verified(H, g, C, lo, hi, solution, steps, factor)


def _hot_start(factor, H_inv_g, C, lo, hi, guess, index, signed_rows, lam):
    """Loads the dual-feasible part of `guess` into the arrays: (k, d, Cholesky factor of
    S = N H^-1 N^T or None), d the minimiser on those k rows held as equalities, with their
    multipliers >= 0. With H = R^T R (R the triangle of `factor`), S = W^T W for
    W = R^-T N^T, formed once for the whole guess: dropping rows only takes sub-blocks.
    H^-1 N^T and S^-1, which only the steps after a wrong guess need, are left to them."""
    n = H_inv_g.shape[0]
    start = 0, -H_inv_g, None
    if guess is None:
        return start
    guess = np.asarray(guess)
    rows = np.flatnonzero(guess)
    rows = rows[np.where(guess[rows] > 0, np.isfinite(hi[rows]), np.isfinite(lo[rows]))]
    if rows.size == 0 or rows.size > n:
        return start
    side = np.sign(guess[rows]).astype(float)
    N = C[rows] * side[:, None]
    triangle, lower = factor
    # R^-T N^T: with an upper factor (H = U^T U) a transposed solve, with a lower one
    # (H = L L^T) a plain one
    W = lapack.triangular_solve(triangle, N.T, lower=lower, transposed=not lower)
    S = W.T @ W
    rhs = -N @ H_inv_g - np.where(side > 0, hi[rows], -lo[rows])
    keep = np.arange(rows.size)
    for _ in range(START_ROUNDS):
        if keep.size == 0:
            break
        schur = cholesky(S[np.ix_(keep, keep)])
        if schur is None:
            break  # dependent rows in the guess: start from nothing instead
        mu = lapack.cho_solve(schur, rhs[keep])
        wrong = mu < 0
        if wrong.any():
            keep = keep[~wrong]
            continue
        k = keep.size
        index[:k], signed_rows[:k], lam[:k] = rows[keep], N[keep], mu
        # d = -H^-1 g - H^-1 N^T mu = -H^-1 g - R^-1 (W mu)
        back = lapack.triangular_solve(triangle, W[:, keep] @ mu, lower=lower, transposed=lower)
        return k, -H_inv_g - back, schur
    return start


def _drop(j, k, index, signed_rows, H_inv_rows, lam, S_inv) -> int:
    """Removes active row j of k (S^-1 of the rest: a rank-one downdate); returns k - 1."""
    column = S_inv[:k, j].copy()
    S_inv[:k, :k] -= np.outer(column, column) / column[j]
    # close the gap: everything after j moves up one place (numpy copies overlapping slices)
    index[j : k - 1] = index[j + 1 : k]
    lam[j : k - 1] = lam[j + 1 : k]
    signed_rows[j : k - 1] = signed_rows[j + 1 : k]
    H_inv_rows[:, j : k - 1] = H_inv_rows[:, j + 1 : k]
    S_inv[j : k - 1, :k] = S_inv[j + 1 : k, :k]
    S_inv[: k - 1, j : k - 1] = S_inv[: k - 1, j + 1 : k]
    return k - 1


def _verified(H, g, C, lo, hi, solution, steps, factor):
    """The solution (d, C d, active rows, their signed rows, multipliers) if it satisfies
    the KKT conditions to round-off; else one KKT solve on its active set (the updates of
    S^-1 drift over many steps) makes it exact, or None."""
    d, value, index, signed_rows, lam = solution
    m = C.shape[0]
    active = np.zeros(m, dtype=np.int8)
    # the side of each active row: its signed row is +C_i (upper bound) or -C_i (lower)
    side = np.where(np.einsum("ij,ij->i", signed_rows, C[index]) > 0, 1, -1).astype(np.int8)
    active[index] = side
    if np.all(np.isfinite(d)) and np.all(np.isfinite(lam)):
        Hd = H @ d
        scale = max(1.0, float(np.max(np.abs(g))), float(np.max(np.abs(Hd))))
        at_bound = np.where(side > 0, hi[index], lo[index])
        if (
            float(np.max(np.abs(Hd + g + signed_rows.T @ lam))) <= STATIONARITY_TOLERANCE * scale
            and np.all(lam >= -DUAL_TOLERANCE * scale)
            and np.all(value <= hi + PRIMAL_TOLERANCE)
            and np.all(value >= lo - PRIMAL_TOLERANCE)
            and np.all(np.abs(value[index] - at_bound) <= PRIMAL_TOLERANCE)
        ):
            multipliers = np.zeros(m)
            multipliers[index] = np.maximum(lam, 0.0)
            return ActiveSetSolution(d, active, multipliers, steps)
    polished = solve_on_active_set(H, g, C, lo, hi, active, max_corrections=0, cholesky_of_H=factor)
    if polished is None:
        return None
    return dataclasses.replace(polished, corrections=steps)
