"""The NMPC's solve: sequential quadratic programming on the condensed problem.

`SequentialQpSolve` is the iteration `MotionCueingOcp` (`mca_drake.cueing.nmpc`) solves with:
from the warm start, each Gauss-Newton QP is solved on a guessed active set (one KKT solve,
used only when verified optimal), else by the dual active-set method, else by Drake's
MathematicalProgram; rti mode takes one full step, converged mode a line search on the true
cost per step, with the learnt output curvature and Marquardt's damping, to a KKT point.
The problem (grid, bounds, constraint matrix, QP back-ends, Gauss-Newton models) is the
class's own (`MotionCueingOcp`); this mixin holds the iteration over it.
"""

import dataclasses
import time

import numpy as np

from mca_drake.conventions import NUM_CHANNELS
from mca_drake.cueing.nmpc_config import MODES
from mca_drake.cueing.output_curvature import (
    finite_difference_hessians,
    psb_update,
    residual_curvature,
)
from mca_drake.qp.active_set import active_rows, cholesky, solve_on_active_set
from mca_drake.qp.dual_active_set import solve_dual_active_set

# The output channels of y and of a reference row.
NY = NUM_CHANNELS
# A row of a full solver's solution within this of a bound is guessed active (the KKT solve
# that follows verifies the guess; OSQP's polished solutions are exact, Clarabel's to 1e-10).
ACTIVE_ROW_TOLERANCE = 1e-6

# `_convex_model`'s multiples of N_A^T N_A (the guessed active rows' normals; H's entries are
# of order 1e-2 to 1) and fractions of the residual curvature, in the order tried.
# Convexification weights of the guessed active rows (`_convex_candidates`). On a 3 g heave
# step the reduced Newton model's smallest eigenvalue is 0.007 against couplings of order 1
# to the constrained directions: rho must reach about 1e4 there, or the iteration falls back
# to Gauss-Newton and converges linearly (18-40 iterations instead of 6-10).
CONVEXIFY_RHO = (1.0, 1e2, 1e4)
SHRINK_THETA = (0.5, 0.25, 0.125)
# A full step whose true cost change is above this share of the model's predicted (negative)
# change re-measures the output Hessians by finite differences (PSB's updates have drifted).
CURVATURE_REFRESH_RATIO = 0.5
# A full step that gained more than EXPANSION_RATIO times the model's promise is tried up to
# EXPANSION_MAX times longer (`SequentialQpSolve._expanded_step`).
EXPANSION_RATIO, EXPANSION_MAX = 1.5, 2.0
# The line search's allowance for a rise after an exact (hot-started) QP step, relative to
# the cost: its round-off, not a solver's accuracy.
EXACT_QP_ALLOWANCE = 1e-12


@dataclasses.dataclass(frozen=True)
class SolveResult:
    """Outcome of one NMPC solve.

    Attributes:
        U: the plan, shape (N, n), rad/s^2 (u_k over interval k).
        cost: the true (nonlinear) cost of U (converged mode; NaN in rti mode, call `cost`).
        iterations: Gauss-Newton QPs solved.
        success: whether the QPs succeeded (else U is a fallback).
        solve_time_s: wall-clock time of the solve.
        message: why a solve failed.
        active: the last QP's active set, shape (`num_rows`,) in {-1, 0, +1}: the next
            solve's `active_guess`.
        kkt_residual: converged mode: the KKT (stationarity) residual of the NLP at U when
            it stopped on it, else the last one measured (NaN: none).
        hot_starts: QPs solved from a guessed active set, on it or by the dual active-set
            method (the rest went to Drake's solver).
        stop: why it stopped: "rti" (one QP), "kkt" (KKT residual below kkt_tolerance),
            "step" (step below step_tolerance), "no_descent" (the line search found none),
            "iterations" (max_iterations reached) or "failed" (a QP failed).
        output_hessians: converged mode: the estimates of d^2 y_a / dv_k^2 at U's nodes,
            shape (N, 6, 3n, 3n) (`output_curvature`): after `shift_output_hessians`, the
            next solve's `output_hessians`; None in rti mode.
    """

    U: np.ndarray
    cost: float
    iterations: int
    success: bool
    solve_time_s: float
    message: str = ""
    active: np.ndarray | None = None
    kkt_residual: float = float("nan")
    hot_starts: int = 0
    stop: str = ""
    output_hessians: np.ndarray | None = None


class SequentialQpSolve:
    """The SQP iteration of `MotionCueingOcp`, which provides the problem: `config`, `N`,
    `nu`, `num_rows`, the constraint matrix `_C`, the QP back-ends (`_shooting`,
    `_solve_qp`, `_update_qp`), the bounds (`input_bounds`, `constraint_bounds`), the
    Gauss-Newton models (`_gauss_newton`) and the perceived objective's references."""

    def solve(
        self,
        x0,
        refs,
        U_guess=None,
        mode: str | None = None,
        active_guess: np.ndarray | None = None,
        output_hessians: np.ndarray | None = None,
        perception_state: np.ndarray | None = None,
    ) -> SolveResult:
        """Solves from state x0 (2n) for references refs (N, 6) (or (6,), held constant).

        Each Gauss-Newton QP is first solved on a guessed active set (`active_set`: one
        KKT solve, used only when verified optimal); when the guess cannot be corrected, the
        QP is solved in full by Drake's MathematicalProgram (OSQP or Clarabel).

        Args:
            U_guess: warm start (N, n); default: zeros.
            mode: override of config.mode ("rti": one QP; "converged": to tolerance).
            active_guess: the active set to try first, shape (`num_rows`,) in {-1, 0, +1}
                (e.g. the previous step's `SolveResult.active`); default: none active.
            output_hessians: converged mode: estimates of the output Hessians at the warm
                start's nodes, shape (N, 6, 3n, 3n) (the previous step's
                `SolveResult.output_hessians` after `shift_output_hessians`); default, or
                when they do not fit or are not finite: finite differences at the warm start.
            perception_state: perceived objective: the vestibular model's state of the
                perceived output minus the perceived reference so far, shape (n,)
                (`perception_filter`; the controller carries it); default zeros (both at
                rest). Ignored by the inertial objective.
        """
        if self._output_form is not None:
            refs = np.broadcast_to(np.asarray(refs, dtype=float), (self.N, NY))
            state = perception_state
            if state is None:
                state = np.zeros(self.perception_filter.num_states)
            refs = self.perceived_references(refs, state)
        # One BLAS thread: these matrices are small (6N = 120), and OpenBLAS's worker threads
        # spin; on a loaded machine they made the step's p99 four times longer.
        with self._blas.limit(limits=1, user_api="blas"):
            return self._solve(x0, refs, U_guess, mode, active_guess, output_hessians)

    def _solve(self, x0, refs, U_guess, mode, active_guess, output_hessians) -> SolveResult:
        start = time.perf_counter()
        cfg = self.config
        mode = mode or cfg.mode
        if mode not in MODES:
            raise ValueError(f"unknown NMPC mode '{mode}'; valid: {', '.join(MODES)}")
        x0, refs, U, row_lo, row_hi, active = self._start(x0, refs, U_guess, active_guess)
        model = self._gauss_newton(x0, U, refs)
        cost = model.cost
        iterations, hot_starts, message, kkt = 0, 0, "", float("nan")
        stop = "rti" if mode == "rti" else "iterations"
        multipliers = None  # of the last full step's verified QP solution
        # converged: the output Hessians that complete Gauss-Newton's model (output_curvature)
        hessians = None
        if mode == "converged":
            hessians = self._starting_hessians(x0, U, model, output_hessians)
        # Marquardt's damping, and the last non-zero one (`_next_damping`)
        damping, shed = 0.0, 0.0
        for _ in range(1 if mode == "rti" else cfg.max_iterations):
            # a legged platform's legs, linearised about this iteration's plan
            self.load_leg_rows(x0, U, row_lo, row_hi)
            g = model.g
            if multipliers is not None:
                # U is the last QP's solution: feasible, its active rows exactly at their
                # bounds and its multipliers >= 0, so the stationarity residual of the
                # Lagrangian with the true gradient is U's KKT residual for the NLP.
                kkt = float(np.max(np.abs(g + self._C.T @ (active * multipliers))))
                if kkt <= cfg.kkt_tolerance * max(1.0, abs(cost)):
                    stop = "kkt"
                    break
            H, factor = self._convex_model(model, hessians, active, damping)
            CU = self._C @ U.reshape(-1)
            step, solution, hot, message = self._qp_step(
                (H, factor), model.H, g, row_lo - CU, row_hi - CU, active, (x0, U, refs, model.jac)
            )
            iterations += 1
            hot_starts += hot
            if step is None:
                elapsed = time.perf_counter() - start
                return _failed(U, cost, iterations, elapsed, message, active, hot_starts)
            multipliers = None
            if solution is not None:
                active = solution.active
            if mode == "rti":
                U = U + step
                break
            alpha, trial_cost, next_model, drifted = self._line_search(
                x0, U, refs, step, cost, model, H, hot, CU, row_lo, row_hi, damping
            )
            if alpha < 1e-6:
                stop = "no_descent"  # none along the Gauss-Newton direction: converged
                break
            if cfg.marquardt_damping:
                # a lengthened step (alpha > 1) counts as one the model got wrong, as a
                # rejected one does: the damping restarts (counted as accepted, the 1 g chirp's
                # worst solve creeps on to the 50-iteration cap; restarted, it stops at a KKT
                # point in 24-31 iterations)
                damping, shed = _next_damping(damping, alpha == 1.0, shed)
            U, cost = U + alpha * step, trial_cost
            model, hessians = self._models_at(
                x0, U, refs, alpha, step, model, next_model, hessians, drifted
            )
            if alpha == 1.0 and solution is not None:
                multipliers = solution.multipliers
            if damping == 0.0 and np.max(np.abs(alpha * step)) < cfg.step_tolerance:
                # (a damped step's length says nothing of convergence: the damping can make
                # it as short as it likes)
                stop = "step"
                break
        return SolveResult(
            U,
            cost,
            iterations,
            True,
            time.perf_counter() - start,
            message,
            active=active,
            kkt_residual=kkt,
            hot_starts=hot_starts,
            stop=stop,
            output_hessians=hessians,
        )

    def _start(self, x0, refs, U_guess, active_guess):
        """A solve's data from its arguments: (x0 (2n), refs (N, 6), the warm start U (N, n)
        clipped into the input bounds, the rows' lower and upper bounds (`num_rows`,), the
        guessed active set (`num_rows`,) in {-1, 0, +1}); loads the first input's box."""
        x0 = np.asarray(x0, dtype=float)
        refs = np.broadcast_to(np.asarray(refs, dtype=float), (self.N, NY))
        U = np.zeros((self.N, self.nu)) if U_guess is None else np.array(U_guess, dtype=float)
        lo, hi = self.input_bounds(x0)
        self._shooting.set_first_input_bounds(lo[: self.nu], hi[: self.nu])
        U = np.clip(U.reshape(-1), lo, hi).reshape(self.N, self.nu)
        lb, ub = self.constraint_bounds(x0)
        legs = np.zeros(self.num_rows - lb.size - lo.size)  # set per iteration (load_leg_rows)
        row_lo, row_hi = np.concatenate([lb, legs, lo]), np.concatenate([ub, legs, hi])
        active = np.zeros(self.num_rows, dtype=np.int8)
        if active_guess is not None and np.shape(active_guess) == (self.num_rows,):
            active = np.clip(np.rint(active_guess), -1, 1).astype(np.int8)
        return x0, refs, U, row_lo, row_hi, active

    def _line_search(self, x0, U, refs, step, cost, model, H, hot, CU, row_lo, row_hi, damping):
        """The length of the QP's step `step` (N, n) from U in converged mode: (alpha,
        the true cost at U + alpha step, the Gauss-Newton model there or None where it is not
        at hand, whether the learnt curvature has drifted); alpha < 1e-6: no descent.

        `model` is the Gauss-Newton model at U (true cost `cost`), H the QP's Hessian, `hot`
        whether the hot start solved the QP, CU the rows' values at U (`num_rows`,) and
        `damping` the QP's Marquardt damping."""
        # Backtracking on the true cost; the segment stays feasible (linear constraints).
        # A rise within the QP's accuracy is accepted, so that the iteration can finish
        # converging in U instead of stalling on round-off: about 1e-9 relative for
        # Drake's solver, only the cost's round-off for the hot start's exact KKT solves
        # (a wider allowance there lets a poor model cycle, rising and falling by 3e-8 on
        # a 3 g step, 50 iterations). A start that breaks a constraint (the shifted plan
        # from a new state) takes the full step, which lands on the feasible set,
        # whatever it costs: a cost line search from outside that set can stall there
        # (on a 3 g step it does, 50 iterations). The full step's model is the next
        # iteration's (its Jacobians are needed there).
        allowance = (EXACT_QP_ALLOWANCE if hot else 1e-9) * max(1.0, abs(cost))
        alpha, next_model = 1.0, self._gauss_newton(x0, U + step, refs)
        trial_cost = next_model.cost
        d = step.reshape(-1)
        predicted = float(model.g @ d + 0.5 * d @ (H @ d))  # the model's change of the cost
        # the full step gained less than that share of what the model promised: the
        # learnt curvature has drifted from the cost's, so it is measured afresh
        drifted = predicted < 0 and trial_cost - cost > CURVATURE_REFRESH_RATIO * predicted
        restoring = bool(np.any(CU < row_lo - 1e-9) or np.any(CU > row_hi + 1e-9))
        while trial_cost > cost + allowance and not restoring:
            alpha, next_model = 0.5 * alpha, None
            if alpha < 1e-6:
                return alpha, trial_cost, next_model, drifted
            trial_cost = self.cost(x0, U + alpha * step, refs)
        if (
            alpha == 1.0
            and damping == 0.0
            and not restoring
            and trial_cost - cost < EXPANSION_RATIO * predicted
        ):
            # the step gained more than the model promised: its curvature overrates the
            # cost's along the step (a convexified or damped model near a saddle; on a
            # 1 g chirp such steps creep on at twice their promise for 40 iterations),
            # so the step is tried longer, as far as the constraints allow
            longer = self._expanded_step(U, step, row_lo, row_hi, CU)
            if longer is not None:
                longer_cost = self.cost(x0, U + longer * step, refs)
                if longer_cost < trial_cost:
                    alpha, trial_cost, next_model = longer, longer_cost, None
        return alpha, trial_cost, next_model, drifted

    def _models_at(self, x0, U, refs, alpha, step, old, model, hessians, drifted):
        """The Gauss-Newton model and the output Hessians at the new plan U, reached from the
        plan of model `old` by alpha times `step` (N, n): (model, hessians). `model` is U's
        model where the line search has it (else None), `hessians` the estimates at the old
        plan, `drifted` whether they are to be measured afresh rather than updated."""
        if model is None:
            model = self._gauss_newton(x0, U, refs)
        if drifted:  # measured afresh: no secant update to make first
            return model, self._starting_hessians(x0, U, model, None)
        node_steps = self._condensing.node_steps(alpha * step)
        return model, psb_update(hessians, node_steps, model.node_jacobian - old.node_jacobian)

    def _expanded_step(self, U, step, row_lo, row_hi, CU) -> float | None:
        """The longest multiple alpha in (1, EXPANSION_MAX] of `step` that keeps U + alpha step
        within the rows' bounds (to the 1e-9 the feasibility checks allow), or None where that
        is not longer than the step by 1 %."""
        Cd = self._C @ step.reshape(-1)
        beyond = CU + Cd  # the rows after the full step
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(
                Cd > 0,
                (row_hi + 1e-9 - beyond) / Cd,
                np.where(Cd < 0, (row_lo - 1e-9 - beyond) / Cd, np.inf),
            )
        alpha = min(EXPANSION_MAX, 1.0 + float(np.min(room, initial=np.inf)))
        return alpha if alpha > 1.01 else None

    def _starting_hessians(self, x0, U, model, guess) -> np.ndarray:
        """The output Hessians to start from: `guess` where it fits, else finite differences
        at U's nodes (shape (N, 6, 3n, 3n))."""
        shape = (self.N, NY, 3 * self.nu, 3 * self.nu)
        if guess is not None and np.shape(guess) == shape and np.all(np.isfinite(guess)):
            return np.array(guess, dtype=float)
        q, qd = self.states(x0, U)
        return finite_difference_hessians(q[:-1], qd[:-1], U, self.robot, model.node_jacobian)

    def _convex_model(self, model, hessians, active, damping):
        """The QP's Hessian and its Cholesky factor: (H, factor), factor None where even
        Gauss-Newton's H is not positive definite (Drake's solver then takes the QP).

        With output Hessians (converged mode) the first positive definite of
          1. H + S, the Newton model (S: `output_curvature`, the residual curvature);
          2. H + S + rho N_A^T N_A (N_A: the rows of the guessed active set), rho in
             CONVEXIFY_RHO: a Newton model may be indefinite where the active rows hold the
             step anyway (at a local minimum only its reduction to their null space must be
             positive); on the right active set the QP's solution is Newton's;
          3. H + theta S, theta in SHRINK_THETA: less of the curvature where it is negative
             in free directions;
          4. H, Gauss-Newton's.
        After a full step the line search rejected, each with Marquardt's damping (the model
        overshot: shorter steps, scaled per variable)."""
        candidates = [model.H]
        if hessians is not None:
            S = self._condensing.assemble(residual_curvature(hessians, model.weighted_residual))
            candidates = _convex_candidates(model.H, S, self._C[active != 0])
        for M in candidates:
            if damping > 0.0:
                M = M + damping * np.diag(np.diag(M))
            factor = cholesky(M)
            if factor is not None:
                return M, factor
        return model.H, None

    def _qp_step(self, model, gauss_newton, g, d_lo, d_hi, active, linearisation):
        """The step d (N, n) of the QP min 1/2 d'Hd + g'd, d_lo <= C d <= d_hi: (d, verified
        `ActiveSetSolution` or None, whether the hot start solved it, message); d is None
        when the QP could not be solved.

        `model` is (H, its Cholesky factor or None), H with the learnt residual curvature
        where there is one; `gauss_newton` is the plain Gauss-Newton H. The hot start (the
        guess, then the dual active-set method from it) tries `model`; Drake's solver (and
        the KKT solve that makes its active set exact) takes the Gauss-Newton H, which is
        what its sparse program holds (factored here only when it differs from the model's:
        this path is the exception)."""
        H, factor = model
        if factor is not None:
            # the dual method from the guess is itself one KKT solve where the guess is right;
            # corrections (config.active_set_corrections > 0) are a heuristic tried first
            solution = None
            if self._corrections > 0:
                solution = self._on_active_set(H, factor, g, d_lo, d_hi, active)
            if solution is None:
                solution = solve_dual_active_set(
                    H,
                    g,
                    self._C,
                    d_lo,
                    d_hi,
                    active,
                    cholesky_of_H=factor,
                    row_norms=self._row_norms,
                    groups=self._parallel,
                )
            if solution is not None:
                return solution.d.reshape(self.N, self.nu), solution, True, ""
        if gauss_newton is not H:
            H, factor = gauss_newton, cholesky(gauss_newton)
        x0, U, refs, jac = linearisation
        if self._output_form is None and self._legs is None:
            x_bar = self._update_qp(x0, U, refs, jac)
            U_qp, message = self._solve_qp(U, x_bar)
            if U_qp is None:
                return None, None, False, message
            d = (U_qp - U).reshape(-1)
        else:
            # the perceived cost couples the nodes, and the legs' rows move with the plan:
            # the sparse program's stage costs and fixed rows hold neither, so Drake's
            # solver takes the condensed QP in the step itself
            d, message = self._condensed_qp.solve(gauss_newton, g, d_lo, d_hi)
            if d is None:
                return None, None, False, message
        if factor is not None:
            # the solver's active set, made exact (and given multipliers) by one KKT solve;
            # a couple of corrections at most: the solver's active set is nearly right, and
            # where it is not, its own answer serves (rti) or the next iteration goes on
            guess = active_rows(self._C, d, d_lo, d_hi, ACTIVE_ROW_TOLERANCE)
            solution = self._on_active_set(H, factor, g, d_lo, d_hi, guess, corrections=2)
            if solution is not None:
                return solution.d.reshape(self.N, self.nu), solution, False, ""
        return d.reshape(self.N, self.nu), None, False, ""

    def _on_active_set(self, H, factor, g, d_lo, d_hi, guess, corrections=None):
        """`solve_on_active_set` of this OCP's rows from `guess` (None: not settled) with
        `corrections` (default config.active_set_corrections)."""
        return solve_on_active_set(
            H,
            g,
            self._C,
            d_lo,
            d_hi,
            guess,
            cholesky_of_H=factor,
            groups=self._parallel,
            max_corrections=self._corrections if corrections is None else corrections,
        )

    # ----------------------------------------------------------------- warm start and fallback


def _convex_candidates(H: np.ndarray, S: np.ndarray, active_normals: np.ndarray):
    """The models `MotionCueingOcp._convex_model` tries, in order, formed as needed: H + S,
    H + S + rho P (CONVEXIFY_RHO; P = N_A^T N_A), H + theta S (SHRINK_THETA), H."""
    newton = H + S
    yield newton
    if active_normals.shape[0]:
        P = active_normals.T @ active_normals
        for rho in CONVEXIFY_RHO:
            yield newton + rho * P
    for theta in SHRINK_THETA:
        yield H + theta * S
    yield H


# Marquardt's damping mu of the converged iterations: it starts at DAMPING_START after the
# first rejected full step, grows by DAMPING_GROWTH per rejection, shrinks by it per accepted
# full step and is dropped once below DAMPING_FLOOR (plain Gauss-Newton steps again).
DAMPING_START, DAMPING_GROWTH, DAMPING_FLOOR = 1e-2, 4.0, 1e-4


def _failed(U, cost, iterations, elapsed, message, active, hot_starts) -> SolveResult:
    """The result of a solve whose QP failed: its last plan U (N, n), kept as a fallback."""
    return SolveResult(
        U,
        cost,
        iterations,
        False,
        elapsed,
        message=f"QP failed: {message}",
        active=active,
        hot_starts=hot_starts,
        stop="failed",
    )


def _next_damping(damping: float, accepted_full_step: bool, shed: float) -> tuple[float, float]:
    """(mu for the next iteration, the last non-zero mu) after an iteration with `damping`;
    `shed`: the last non-zero mu before it (0.0: none yet).

    An undamped step that overshoots after the damping has been dropped restarts it from
    DAMPING_GROWTH times the last mu in use (whenever in the solve that was), not from
    DAMPING_START: that mu was enough. A restart from DAMPING_START makes the damping cycle
    at the worst steps (restart at 1e-2, five accepted steps that gain twice their promise
    while it shrinks, an overshoot once dropped): on the 54 slowest converged steps of the
    seven adversarial references and two development flights, with this restart the solves
    take 774 Gauss-Newton iterations against 822, the 3 g surge's onset 37 against 42."""
    if not accepted_full_step:
        if damping == 0.0 and shed > 0.0:
            return DAMPING_GROWTH * shed, shed
        return max(DAMPING_GROWTH * damping, DAMPING_START), shed
    if damping / DAMPING_GROWTH > DAMPING_FLOOR:
        return damping / DAMPING_GROWTH, damping
    return 0.0, damping if damping > 0.0 else shed
