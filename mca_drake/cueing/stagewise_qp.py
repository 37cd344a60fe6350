"""A primal-dual interior-point solver for QPs with the structure of an optimal control
problem over N stages: linear dynamics between consecutive stages and boxes on each
stage's variables.

    minimise    sum_k  1/2 w_k' Q_k w_k + b_k' w_k              (k = 0..N-1)
    subject to  s_0 = initial,   s_(k+1) = F_k w_k              (k = 0..N-2)
                lower_k <= w_k <= upper_k

where each stage's variables w_k (m) start with its states s_k (the first ns of them) and
F_k (ns, m) maps a stage to its successor's states. The offline-optimal bound's QPs have
this shape with N = T + 1 up to 30,001 stages; a general sparse solver (Clarabel on Drake's
MathematicalProgram) takes about 50 s per QP on them, because it sees an unstructured
sparse matrix. Here each Newton step costs O(N) in a few batched array operations:

- the stage Hessians plus the barrier terms, K_k = Q_k + Sigma_k, are inverted stage by
  stage (m x m each);
- the dynamics' multipliers solve M lambda = rhs with M = E K^-1 E', E the dynamics'
  rows: M is block tridiagonal (ns x ns blocks) and positive definite, and is factored by
  LAPACK's banded Cholesky (bandwidth 2 ns - 1);
- the steps follow stage by stage.

Method: Mehrotra's predictor-corrector on the box constraints' slacks and multipliers,
one step length for primal and dual, 0.99 of the way to the boundary. A small static
regularisation delta I in K keeps every stage invertible where a direction carries no
curvature (e.g. an unbounded state with no cost), and a smaller one keeps M factorable
where active bounds fix every variable a dynamics row touches; iterative refinement
against the unregularised system, until the step is as accurate as the iterate needs,
removes their effect on the step.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

# K_k = Q_k + Sigma_k + delta I with delta this share of max(1, the largest |Q_kii|) at
# first, 100 times more each time M's factorisation meets a non-positive pivot (M = E K^-1
# E' is positive definite in exact arithmetic; a direction of K with no curvature and no
# active bound makes K^-1 of order 1 / delta, and M's entries cancel that much).
REGULARISATION = 1e-8
# M + rho I with rho this share of max(1, the largest diagonal entry of M).
DUAL_REGULARISATION = 1e-12
# Iterative-refinement steps per Newton system (against K without delta) at most ...
REFINEMENT_STEPS = 10
# ... and stop once the residual it leaves, scaled as the iterations' are, is this share
# of the larger of their tolerance and the current iterate's residual (an inexact Newton
# step: the iterations recompute their residuals from the iterates, so a direction this
# accurate costs them nothing), or once it stops shrinking (round-off).
REFINEMENT_TARGET = 0.1
# The share of the way to the boundary of the positive orthant each step goes.
STEP_TO_BOUNDARY = 0.99


@dataclasses.dataclass(frozen=True)
class StagewiseSolution:
    """A stage-wise QP's solution.

    Attributes:
        w: the stages' variables, shape (N, m).
        multipliers: the dynamics' multipliers, shape (N, ns) (row 0: the initial
            states').
        bound_multipliers: the boxes' multipliers, upper minus lower, shape (N, m): the
            objective's gradient Q w + b equals minus E' multipliers minus these.
        iterations: interior-point iterations.
        converged: whether every residual met the tolerance.
        residual: the largest scaled residual (stationarity, dynamics, bounds, and the
            complementarity gap) at the end.
    """

    w: np.ndarray
    multipliers: np.ndarray
    bound_multipliers: np.ndarray
    iterations: int
    converged: bool
    residual: float


class _Dynamics:
    """The dynamics' rows E: row 0 is S w_0 (= initial), row k >= 1 is S w_k - F_(k-1)
    w_(k-1) (= 0), S selecting a stage's first ns variables; F constant (ns, m) or per
    stage (N - 1, ns, m)."""

    def __init__(self, F: np.ndarray, N: int, ns: int):
        self.F, self.N, self.ns = F, N, ns
        self.constant = F.ndim == 2

    def apply(self, w: np.ndarray) -> np.ndarray:
        """E w, shape (N, ns)."""
        out = w[:, : self.ns].copy()
        out[1:] -= self._times(w[:-1])
        return out

    def transpose(self, lam: np.ndarray) -> np.ndarray:
        """E' lambda, shape (N, m)."""
        out = np.zeros((self.N, self.m))
        out[:, : self.ns] = lam
        if self.constant:
            out[:-1] -= lam[1:] @ self.F
        else:
            out[:-1] -= np.matmul(lam[1:, None, :], self.F)[:, 0]
        return out

    @property
    def m(self) -> int:
        return self.F.shape[-1]

    def _times(self, w: np.ndarray) -> np.ndarray:
        """F_k w_k for stages 0..N-2, shape (N - 1, ns)."""
        if self.constant:
            return w @ self.F.T
        return np.matmul(self.F, w[:, :, None])[:, :, 0]

    def schur(self, Kinv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The blocks of M = E K^-1 E': diagonal (N, ns, ns) and below the diagonal
        M_(k, k-1) (N - 1, ns, ns)."""
        ns = self.ns
        diagonal = Kinv[:, :ns, :ns].copy()
        FK = np.matmul(self.F, Kinv[:-1])  # F_k K_k^-1 (a constant F broadcasts)
        diagonal[1:] += np.matmul(FK, np.swapaxes(self.F, -1, -2))
        return diagonal, -FK[:, :, :ns]


class _BandedSchur:
    """M = E K^-1 E' (block tridiagonal, ns x ns blocks) in LAPACK's lower band storage
    (bandwidth 2 ns - 1), factored once per Newton step."""

    def __init__(self, N: int, ns: int):
        self.N, self.ns = N, ns

    def factor(self, diagonal: np.ndarray, below: np.ndarray) -> np.ndarray:
        """M's lower banded Cholesky factor; LinAlgError where a pivot is not positive."""
        N, ns = self.N, self.ns
        # band[d, ns j + c] = M[ns j + c + d, ns j + c], viewed as (2 ns, N, ns)
        band = np.zeros((2 * ns, N, ns))
        for d in range(ns):  # the diagonal blocks' d-th subdiagonals: D_j[c + d, c]
            band[d, :, : ns - d] = np.diagonal(diagonal, offset=-d, axis1=1, axis2=2)
        for d in range(1, 2 * ns):  # blocks (j + 1, j): M_(j+1, j)[c + d - ns, c]
            offset = ns - d  # that entry lies on M_(j+1, j)'s diagonal `offset`
            values = np.diagonal(below, offset=offset, axis1=1, axis2=2)
            if offset >= 0:
                band[d, : N - 1, offset:] = values
            else:
                band[d, : N - 1, : ns + offset] = values
        band = band.reshape(2 * ns, N * ns)
        return scipy.linalg.cholesky_banded(band, lower=True, check_finite=False)

    @staticmethod
    def solve(factor: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """M^-1 rhs for rhs (N, ns)."""
        flat = scipy.linalg.cho_solve_banded((factor, True), rhs.reshape(-1), check_finite=False)
        return flat.reshape(rhs.shape)


def solve_stagewise_qp(
    Q,
    b,
    F,
    lower,
    upper,
    initial,
    *,
    tolerance: float = 1e-9,
    max_iterations: int = 100,
) -> StagewiseSolution:
    """Solves the stage-wise QP of this module's docstring.

    Args:
        Q: the stage Hessians, symmetric positive semidefinite, shape (N, m, m).
        b: the stage gradients, shape (N, m).
        F: the dynamics, one (ns, m) for every stage or one per stage (N - 1, ns, m).
        lower: the boxes' lower ends, shape (N, m); -inf where a variable has none.
        upper: their upper ends, shape (N, m); inf where a variable has none.
        initial: the first stage's states s_0, shape (ns,).
        tolerance: on the scaled residuals (stationarity relative to 1 + |b|_inf; the
            dynamics and bounds relative to 1 + the data's size) and on the duality gap
            relative to 1 + |objective|.
        max_iterations: interior-point iterations at most.

    Returns:
        The solution; `converged` False where the residuals did not reach the tolerance
        within max_iterations (the last iterate is returned).

    Raises:
        ValueError: shapes that do not fit, non-finite data, or lower > upper.
    """
    Q, b, F = (np.asarray(a, dtype=float) for a in (Q, b, F))
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    initial = np.asarray(initial, dtype=float)
    _check(Q, b, F, lower, upper, initial)
    method = _InteriorPoint(Q, b, F, lower, upper, initial, tolerance)
    converged, iterations = False, 0
    for iterations in range(max_iterations + 1):
        worst = method.measure()
        if worst <= tolerance:
            converged = True
            break
        if not np.isfinite(worst) or iterations == max_iterations:
            break  # a breakdown (reported, never iterated on) or the cap
        method.step()
    return StagewiseSolution(
        w=method.w,
        multipliers=method.lam,
        bound_multipliers=method.zu - method.zl,
        iterations=iterations,
        converged=converged,
        residual=method.worst if np.isfinite(method.worst) else np.inf,
    )


class _InteriorPoint:
    """The iterates of Mehrotra's method on a stage-wise QP and one step of it: w, the
    dynamics' multipliers lam, the boxes' slacks sl, su and multipliers zl, zu (those of
    a missing bound held at 1 and 0)."""

    def __init__(self, Q, b, F, lower, upper, initial, tolerance: float):
        N, m = b.shape
        ns = initial.shape[0]
        self.Q, self.b, self.tolerance = Q, b, tolerance
        self.dynamics, self.schur = _Dynamics(F, N, ns), _BandedSchur(N, ns)
        self.has_lo, self.has_hi = np.isfinite(lower), np.isfinite(upper)
        self.lo = np.where(self.has_lo, lower, 0.0)
        self.hi = np.where(self.has_hi, upper, 0.0)
        self.count = max(1, int(self.has_lo.sum() + self.has_hi.sum()))
        self.rhs_p = np.zeros((N, ns))
        self.rhs_p[0] = initial
        self.delta = REGULARISATION * max(1.0, float(np.abs(np.diagonal(Q, 0, 1, 2)).max()))
        self.scale_d = 1.0 + float(np.abs(b).max())
        self.scale_p = 1.0 + max(
            float(np.abs(initial).max(initial=0.0)),
            float(np.abs(self.lo).max()),
            float(np.abs(self.hi).max()),
        )
        # the start: w = 0 moved into the boxes (where the SQP's steps start, which meets
        # the dynamics from s_0 = 0 exactly: Newton's steps then keep them), slacks at
        # least 1, multipliers 1
        self.w = np.clip(
            np.zeros((N, m)),
            np.where(self.has_lo, self.lo, -np.inf),
            np.where(self.has_hi, self.hi, np.inf),
        )
        self.lam = np.zeros((N, ns))
        self.sl = np.where(self.has_lo, np.maximum(self.w - self.lo, 1.0), 1.0)
        self.su = np.where(self.has_hi, np.maximum(self.hi - self.w, 1.0), 1.0)
        self.zl, self.zu = self.has_lo.astype(float), self.has_hi.astype(float)
        self.worst = np.inf

    def measure(self) -> float:
        """The residuals at the iterate (kept for the step) and the largest scaled one."""
        d, w = self.dynamics, self.w
        Qw = _matvec(self.Q, w)
        self.r_d = Qw + self.b + d.transpose(self.lam) - self.zl + self.zu
        self.r_p = d.apply(w) - self.rhs_p
        self.r_l = np.where(self.has_lo, w - self.sl - self.lo, 0.0)
        self.r_u = np.where(self.has_hi, w + self.su - self.hi, 0.0)
        gap = float(
            (self.sl * self.zl * self.has_lo).sum() + (self.su * self.zu * self.has_hi).sum()
        )
        self.mu = gap / self.count
        self.worst = max(
            float(np.abs(self.r_d).max()) / self.scale_d,
            float(np.abs(self.r_p).max()) / self.scale_p,
            float(max(np.abs(self.r_l).max(), np.abs(self.r_u).max())) / self.scale_p,
            # the duality gap relative to the objective: the objective is this close to
            # the optimum's
            gap / (1.0 + abs(float(np.sum(w * (0.5 * Qw + self.b))))),
        )
        return self.worst

    def step(self) -> None:
        """One predictor-corrector step from the measured iterate."""
        sigma_barrier = np.where(self.has_lo, self.zl / self.sl, 0.0)
        sigma_barrier += np.where(self.has_hi, self.zu / self.su, 0.0)
        self.K0 = self.Q + sigma_barrier[:, :, None] * np.eye(self.Q.shape[-1])
        self.Kinv, self.band = _factor(self.K0, self.delta, self.dynamics, self.schur)
        slacks = (self.sl, self.su, self.zl, self.zu)
        # predictor: the affine-scaling direction, and how far it could go
        aff = self._direction(-self.sl * self.zl, -self.su * self.zu)
        alpha = _step_to_boundary(slacks, aff[2:])
        gap = ((self.sl + alpha * aff[2]) * (self.zl + alpha * aff[4]) * self.has_lo).sum()
        gap += ((self.su + alpha * aff[3]) * (self.zu + alpha * aff[5]) * self.has_hi).sum()
        sigma = (gap / self.count / self.mu) ** 3 if self.mu > 0 else 0.0
        # corrector: centred towards sigma mu, with the predictor's second-order term
        rc_l = sigma * self.mu - self.sl * self.zl - aff[2] * aff[4]
        rc_u = sigma * self.mu - self.su * self.zu - aff[3] * aff[5]
        dw, dlam, dsl, dsu, dzl, dzu = self._direction(rc_l, rc_u)
        alpha = min(1.0, STEP_TO_BOUNDARY * _step_to_boundary(slacks, (dsl, dsu, dzl, dzu)))
        self.w = self.w + alpha * dw
        self.lam = self.lam + alpha * dlam
        self.sl = np.where(self.has_lo, self.sl + alpha * dsl, 1.0)
        self.su = np.where(self.has_hi, self.su + alpha * dsu, 1.0)
        self.zl = np.where(self.has_lo, self.zl + alpha * dzl, 0.0)
        self.zu = np.where(self.has_hi, self.zu + alpha * dzu, 0.0)

    def _direction(self, rc_l, rc_u):
        """(dw, dlam, dsl, dsu, dzl, dzu) of Newton's step towards the complementarity
        targets sl dzl + zl dsl = rc_l, su dzu + zu dsu = rc_u."""
        has_lo, has_hi, sl, su, zl, zu = (
            self.has_lo,
            self.has_hi,
            self.sl,
            self.su,
            self.zl,
            self.zu,
        )
        rhs_w = -self.r_d + np.where(has_lo, (rc_l - zl * self.r_l) / sl, 0.0)
        rhs_w -= np.where(has_hi, (rc_u + zu * self.r_u) / su, 0.0)
        dw, dlam = self._newton(rhs_w, -self.r_p)
        dsl = np.where(has_lo, dw + self.r_l, 0.0)
        dsu = np.where(has_hi, -dw - self.r_u, 0.0)
        dzl = np.where(has_lo, (rc_l - zl * dsl) / sl, 0.0)
        dzu = np.where(has_hi, (rc_u - zu * dsu) / su, 0.0)
        return dw, dlam, dsl, dsu, dzl, dzu

    def _newton(self, rhs_w, rhs_dyn):
        """(dw, dlam) of [K0 E'; E 0] (dw, dlam) = (rhs_w, rhs_dyn), refined. A residual
        left in the first rows becomes one of stationarity, in the second one of the
        dynamics, at the next iterate: each is measured on its own scale."""
        d = self.dynamics
        dw, dlam = np.zeros_like(rhs_w), np.zeros_like(rhs_dyn)
        res_w, res_p = rhs_w, rhs_dyn
        target = REFINEMENT_TARGET * max(self.tolerance, self.worst)
        last = np.inf
        for _ in range(1 + REFINEMENT_STEPS):
            t = _matvec(self.Kinv, res_w)
            step_lam = self.schur.solve(self.band, d.apply(t) - res_p)
            step_w = _matvec(self.Kinv, res_w - d.transpose(step_lam))
            dw, dlam = dw + step_w, dlam + step_lam
            res_w = rhs_w - _matvec(self.K0, dw) - d.transpose(dlam)
            res_p = rhs_dyn - d.apply(dw)
            error = max(np.abs(res_w).max() / self.scale_d, np.abs(res_p).max() / self.scale_p)
            if error <= target or error > 0.5 * last:
                break  # accurate enough, or at round-off
            last = error
        return dw, dlam


def _matvec(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A_k v_k per stage: (N, p, q) by (N, q) -> (N, p)."""
    return np.matmul(A, v[:, :, None])[:, :, 0]


def _factor(K0, delta, dynamics, schur):
    """(K^-1 (N, m, m), M's banded Cholesky factor) with K = K0 + delta' I, delta' the
    smallest of delta, 100 delta, ... whose M factors."""
    eye = np.eye(K0.shape[-1])
    for _ in range(6):
        Kinv = np.linalg.inv(K0 + delta * eye)
        diagonal, below = dynamics.schur(Kinv)
        # M + rho I: where active bounds fix every variable a dynamics row touches, that
        # row of M vanishes (the constraints are degenerate); rho keeps it factorable, and
        # refinement against the unregularised system removes rho's effect elsewhere
        rho = DUAL_REGULARISATION * max(1.0, float(np.abs(diagonal).max()))
        diagonal += rho * np.eye(diagonal.shape[-1])
        try:
            return Kinv, schur.factor(diagonal, below)
        except np.linalg.LinAlgError:
            delta *= 100.0
    raise np.linalg.LinAlgError("the Newton system's Schur complement does not factor")


def _step_to_boundary(values, steps) -> float:
    """The largest alpha in [0, 1 / STEP_TO_BOUNDARY] that keeps every value + alpha step
    non-negative (values positive)."""
    alpha = 1.0 / STEP_TO_BOUNDARY
    for v, d in zip(values, steps, strict=True):
        negative = d < 0
        if np.any(negative):
            alpha = min(alpha, float(np.min(-v[negative] / d[negative])))
    return alpha


def _check(Q, b, F, lower, upper, initial) -> None:
    """ValueError unless the data's shapes fit and its values are usable."""
    if b.ndim != 2:
        raise ValueError(f"b must have shape (N, m); got {b.shape}")
    N, m = b.shape
    ns = initial.shape[0] if initial.ndim == 1 else -1
    if Q.shape != (N, m, m):
        raise ValueError(f"Q must have shape ({N}, {m}, {m}); got {Q.shape}")
    if not 0 < ns <= m:
        raise ValueError(f"initial must have shape (ns,) with 0 < ns <= {m}; got {initial.shape}")
    if F.shape not in ((ns, m), (N - 1, ns, m)):
        raise ValueError(f"F must have shape ({ns}, {m}) or ({N - 1}, {ns}, {m}); got {F.shape}")
    if lower.shape != (N, m) or upper.shape != (N, m):
        raise ValueError(f"lower and upper must have shape ({N}, {m})")
    for name, a in (("Q", Q), ("b", b), ("F", F), ("initial", initial)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} has non-finite values")
    if np.any(np.isnan(lower)) or np.any(np.isnan(upper)) or np.any(lower > upper):
        raise ValueError("the boxes need lower <= upper (no NaN)")
