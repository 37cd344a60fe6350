"""A hot-started active-set solve of a small dense convex QP, verified before it is used.

The NMPC's Gauss-Newton QPs change little from one iteration to the next and from one control
step to the next: the set of active constraints is mostly the same. Given a guess of that
set, the QP's solution is one linear (KKT) solve; if the result is primal feasible and its
multipliers have the right signs, it *is* the QP's solution (a convex QP's KKT conditions are
sufficient), exact to round-off. A wrong guess is corrected a few times (violated rows join,
rows with wrong-signed multipliers leave; one row per round once that cycles); if that does
not settle, the caller solves the QP in full (Drake's MathematicalProgram) and hands the new
active set back. Nothing unverified is ever returned.

Problem, in the step d (n):

    minimise 1/2 d^T H d + g^T d   subject to   lo <= C d <= hi   (C: (m, n), m rows)

with H symmetric positive definite. An active set is an int array of shape (m,): +1 for a row
at its upper bound, -1 at its lower bound, 0 inactive.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg.lapack

import mca_drake.qp.lapack as lapack

# A row counts as violated beyond this (absolute, in the units of C d; the NMPC keeps a
# reserve of 1e-3 of every limit, so this never turns into a limit violation).
PRIMAL_TOLERANCE = 1e-9
# A multiplier counts as wrong-signed below -this x max(1, |g|_inf).
DUAL_TOLERANCE = 1e-10


@dataclasses.dataclass(frozen=True)
class ActiveSetSolution:
    """A verified QP solution.

    Attributes:
        d: the minimiser, shape (n,).
        active: the active set, shape (m,) in {-1, 0, +1}.
        multipliers: lambda >= 0 of every row, shape (m,) (0 where inactive): the KKT
            conditions read H d + g + C^T (side * lambda) = 0 with side = active.
        corrections: active-set corrections it took (0: the guess was right).
    """

    d: np.ndarray
    active: np.ndarray
    multipliers: np.ndarray
    corrections: int


def active_rows(C: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray, tol: float):
    """The active set of a solution d found some other way: rows within `tol` of a bound
    (upper first where both are that close, i.e. an equality row)."""
    value = C @ d
    active = np.zeros(C.shape[0], dtype=np.int8)
    active[value <= lo + tol] = -1
    active[value >= hi - tol] = 1
    return active


def solve_on_active_set(
    H: np.ndarray,
    g: np.ndarray,
    C: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    active: np.ndarray,
    *,
    max_corrections: int = 20,
    cholesky_of_H: tuple | None = None,
    groups: np.ndarray | None = None,
) -> ActiveSetSolution | None:
    """Solves the QP from a guessed active set; None when the guess cannot be corrected in
    `max_corrections` rounds (or the active rows are linearly dependent, or g is not
    finite).

    Args:
        H: (n, n) symmetric positive definite. g: (n,). C: (m, n). lo, hi: (m,), may be
            infinite. active: (m,) in {-1, 0, +1}, the guess.
        cholesky_of_H: `cholesky(H)` (or scipy's cho_factor) when the caller has it already.
        groups: `parallel_groups(C)` when the caller has it: of rows that are multiples of
            one another at most one is made active (two would make the KKT system singular).
    """
    if not np.all(np.isfinite(g)):
        return None
    factor = cholesky_of_H if cholesky_of_H is not None else cholesky(H)
    if factor is None:
        return None
    Hinv_g = lapack.cho_solve(factor, g)
    dual_tolerance = DUAL_TOLERANCE * max(1.0, float(np.max(np.abs(g), initial=0.0)))
    active = np.array(active, dtype=np.int8)
    # an active row whose bound on that side is infinite cannot be active
    active[(active > 0) & ~np.isfinite(hi)] = 0
    active[(active < 0) & ~np.isfinite(lo)] = 0
    seen, one_at_a_time = set(), False
    # columns of H^-1 C^T, computed once per row as rows become active
    Hinv_Ct = np.empty((C.shape[1], C.shape[0]))
    known = np.zeros(C.shape[0], dtype=bool)
    for corrections in range(max_corrections + 1):
        if groups is not None:
            active = _one_per_group(active, groups)
        index = np.flatnonzero(active)
        side = active[index].astype(float)
        if index.size:
            rows = C[index]
            rhs = np.where(side > 0, hi[index], lo[index])
            missing = index[~known[index]]
            if missing.size:
                Hinv_Ct[:, missing] = lapack.cho_solve(factor, C[missing].T)
                known[missing] = True
            Y = Hinv_Ct[:, index]  # H^-1 rows^T, (n, k)
            S = rows @ Y
            schur = cholesky(S)
            if schur is None:
                # Dependent active rows (at the robot's limits several node rows bind the
                # same combination of inputs): keep an independent subset; the rows left out
                # hold as equalities too when the set is consistent, and the feasibility
                # check below sees to it.
                keep = _independent_rows(S)
                active[index[~keep]] = 0
                index, side, rows, rhs = index[keep], side[keep], rows[keep], rhs[keep]
                Y = Y[:, keep]
                schur = cholesky(rows @ Y)
                if schur is None:
                    return None
            mu = lapack.cho_solve(schur, -rows @ Hinv_g - rhs)
            d = -Hinv_g - Y @ mu
        else:
            mu = np.zeros(0)
            d = -Hinv_g
        value = C @ d
        lam = side * mu  # >= 0 at an optimum, for either side
        violated_upper = value > hi + PRIMAL_TOLERANCE
        violated_lower = value < lo - PRIMAL_TOLERANCE
        wrong_sign = lam < -dual_tolerance
        if not (violated_upper.any() or violated_lower.any() or wrong_sign.any()):
            multipliers = np.zeros(C.shape[0])
            multipliers[index] = np.maximum(lam, 0.0)
            return ActiveSetSolution(d, active, multipliers, corrections)
        # Every offending row changes at once while that makes progress: in the NMPC several
        # rows change together from one step to the next (on 30 s light and jet flights every
        # one of 6002 hot starts settled this way; one row per round alone left 36 to the
        # full solver). Once a set repeats, one row per round: the most wrong-signed
        # multiplier leaves, else the most violated row joins.
        key = active.tobytes()
        one_at_a_time = one_at_a_time or key in seen
        seen.add(key)
        active = active.copy()
        if not one_at_a_time:
            active[index[wrong_sign]] = 0
            active[violated_upper] = 1
            active[violated_lower] = -1
        elif wrong_sign.any():
            active[index[np.argmin(lam)]] = 0
        else:
            excess = np.maximum(value - hi, lo - value)
            worst = int(np.argmax(excess))
            active[worst] = 1 if value[worst] > hi[worst] else -1
    return None


def parallel_groups(C: np.ndarray) -> np.ndarray:
    """A group number per row of C (m,): rows that are multiples of one another share one;
    -1 for a row parallel to no other."""
    norms = np.linalg.norm(C, axis=1, keepdims=True)
    unit = C / np.where(norms > 0, norms, 1.0)
    # make the sign unique: first non-zero entry positive
    first = np.argmax(np.abs(unit) > 1e-12, axis=1)
    unit *= np.sign(unit[np.arange(len(unit)), first])[:, None]
    _, group, counts = np.unique(unit.round(12), axis=0, return_inverse=True, return_counts=True)
    group = group.reshape(-1)
    return np.where(counts[group] > 1, group, -1)


def _one_per_group(active: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """`active` with at most one active row per group of parallel rows (the first)."""
    index = np.flatnonzero((active != 0) & (groups >= 0))
    if index.size < 2:
        return active
    _, first = np.unique(groups[index], return_index=True)
    if first.size == index.size:
        return active
    active = active.copy()
    drop = np.setdiff1d(index, index[first])
    active[drop] = 0
    return active


def _independent_rows(S: np.ndarray) -> np.ndarray:
    """A mask of linearly independent active rows, from their Schur complement
    S = rows H^-1 rows^T (k, k; H positive definite, so S is singular exactly where the rows
    are dependent): LAPACK's pivoted Cholesky (dpstrf) picks them, in O(k^3) on the small S
    rather than a QR of the rows themselves (ten times slower, at every correction)."""
    keep = np.zeros(S.shape[0], dtype=bool)
    if S.size == 0:
        return keep
    scale = float(np.max(np.diag(S)))
    _, pivots, rank, info = scipy.linalg.lapack.dpstrf(S, tol=PIVOT_RATIO * scale)
    if info < 0:
        return keep
    keep[pivots[:rank] - 1] = True  # LAPACK's pivots count from 1
    return keep


# A Cholesky factor whose smallest pivot is below this fraction of the largest is treated as
# singular: the active rows are (nearly) dependent and the KKT solve would amplify round-off.
PIVOT_RATIO = 1e-12


def cholesky(M: np.ndarray):
    """cho_factor of M, or None when M is not (numerically) positive definite."""
    factor = lapack.cho_factor(M)
    if factor is None:
        return None
    pivots = np.abs(np.diag(factor[0])) ** 2
    if not np.all(np.isfinite(pivots)) or pivots.min() < PIVOT_RATIO * pivots.max():
        return None
    return factor
