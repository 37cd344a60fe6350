"""Drake's QP back-ends of the NMPC's Gauss-Newton step (`mca_drake.cueing.nmpc`).

Where the active-set hot start does not settle, Drake's MathematicalProgram solves the step's
QP (OSQP or Clarabel):

- `ShootingQp`: the sparse multiple-shooting program of the inertial objective, variables
  u_0..u_(N-1) and x_1..x_N, built once; each step updates its stage costs and the first
  dynamics block's bounds (x_0). Multiple shooting keeps every matrix sparse: condensing
  makes the constraint matrix dense and the QP ten times slower.
- `CondensedQp`: min 1/2 d'Hd + g'd subject to d_lo <= C d <= d_hi over the condensed plan
  step d, for the perceived objective, whose cost couples the nodes so that stage costs
  cannot hold it, and for a legged platform, whose leg rows move with the plan; built at
  its first use, its rows reloaded at each solve.

Both are sized from the platform's joint count n (the OCP's `PlanningLimits`).
"""

import numpy as np
import scipy.sparse as sp
from pydrake.solvers import (
    ClarabelSolver,
    MathematicalProgram,
    OsqpSolver,
    SolutionResult,
    SolverOptions,
)

from mca_drake.cueing.nmpc_config import NmpcConfig
from mca_drake.cueing.shooting import shooting_dynamics

# Clarabel's tolerance on the perceived objective's dense condensed QP: at 1e-10 it stops
# short on it (insufficient progress); the KKT solve on its active set that follows makes a
# verified answer exact anyway.
CONDENSED_CLARABEL_TOLERANCE = 1e-8


def make_qp_solver(config: NmpcConfig, name: str, clarabel_tolerance: float | None = None):
    """(solver, options) of one of Drake's QP solvers ("osqp" or "clarabel") with the
    config's settings (Clarabel's tolerance `clarabel_tolerance` where given)."""
    solver = ClarabelSolver() if name == "clarabel" else OsqpSolver()
    options = SolverOptions()
    sid = solver.solver_id()
    if name == "clarabel":
        for option in ("tol_gap_abs", "tol_gap_rel", "tol_feas"):
            options.SetOption(sid, option, clarabel_tolerance or config.clarabel_tolerance)
    else:
        for option, value in (
            ("eps_abs", config.osqp_tolerance),
            ("eps_rel", config.osqp_tolerance),
            ("max_iter", config.osqp_max_iterations or 20000),
            ("polishing", 1),
            ("verbose", 0),
        ):
            options.SetOption(sid, option, value)
    return solver, options


def _solution(result, variables, shape):
    """(solution reshaped to `shape`, "") of a solve, or (None, why) when it failed. OSQP
    stopped by its iteration limit still holds a usable approximate step (rti takes one
    approximate step by design; the viability clamp guards the command)."""
    status = result.get_solution_result()
    if not (result.is_success() or status == SolutionResult.kIterationLimit):
        return None, str(status)
    value = result.GetSolution(variables)
    if not np.all(np.isfinite(value)):
        return None, "non-finite QP solution"
    return value.reshape(shape), ""


class ShootingQp:
    """The sparse QP of one Gauss-Newton step, built once.

    Args:
        config: the NMPC settings (terminal weights, solver tolerances).
        limits: the planning limits (`nmpc.PlanningLimits`, n joints each).
        durations: the grid's interval lengths T_k, s, shape (N,).
        tangents: the stoppability tangents [(slope (n,), offset (n,))] on every node.
        solver_name: "osqp" or "clarabel".
    """

    def __init__(self, config: NmpcConfig, limits, durations, tangents, solver_name: str):
        r, N, nu = limits, len(durations), limits.q_min.size
        self.N, self.nu = N, nu
        prog = self.prog = MathematicalProgram()
        self.U_var = prog.NewContinuousVariables(N, nu, "u")
        self.X_var = prog.NewContinuousVariables(N, 2 * nu, "x")  # x_1..x_N
        u_all, x_all = self.U_var.reshape(-1), self.X_var.reshape(-1)
        self._first_input_box = prog.AddBoundingBoxConstraint(
            -r.qdd_max, r.qdd_max, self.U_var[0]
        ).evaluator()
        if N > 1:
            u_max = np.tile(r.qdd_max, N - 1)
            prog.AddBoundingBoxConstraint(-u_max, u_max, self.U_var[1:].reshape(-1))
        prog.AddBoundingBoxConstraint(
            np.tile(np.r_[r.q_min, -r.qd_max], N), np.tile(np.r_[r.q_max, r.qd_max], N), x_all
        )
        # Dynamics x_(k+1) = Phi_k x_k + Gamma_k u_k; the first row block carries x_0 in its
        # bounds. Columns: [u (nN), x (2nN)].
        A_eq, self._Phi = shooting_dynamics(durations, nu)
        self._dynamics = prog.AddLinearEqualityConstraint(
            A_eq, np.zeros(2 * nu * N), np.concatenate([u_all, x_all])
        ).evaluator()
        # Stoppability tangents on every node: rows side * (q_j + slope_j qd_j) <= bound_j.
        if tangents:
            rows, cols, vals, upper = [], [], [], []
            n_rows = 0
            for k in range(N):
                for side in (+1.0, -1.0):
                    limit = r.q_max if side > 0 else -r.q_min
                    for slope, offset in tangents:
                        for j in range(nu):
                            rows += [n_rows, n_rows]
                            cols += [2 * nu * k + j, 2 * nu * k + nu + j]
                            vals += [side, side * slope[j]]
                            upper.append(limit[j] + offset[j])
                            n_rows += 1
            A_stop = sp.csc_matrix((vals, (rows, cols)), shape=(n_rows, 2 * nu * N))
            prog.AddLinearConstraint(A_stop, np.full(n_rows, -np.inf), np.array(upper), x_all)
        # Gauss-Newton stage costs: node 0 on u_0 (x_0 is given), nodes k >= 1 on [x_k, u_k].
        stage_costs = [
            prog.AddQuadraticCost(np.eye(nu), np.zeros(nu), self.U_var[0], is_convex=True)
        ]
        for k in range(1, N):
            v = np.concatenate([self.X_var[k - 1], self.U_var[k]])
            stage_costs.append(
                prog.AddQuadraticCost(np.eye(3 * nu), np.zeros(3 * nu), v, is_convex=True)
            )
        self._stage_costs = [c.evaluator() for c in stage_costs]
        terminal = 2 * np.diag(
            [config.terminal_position_weight] * nu + [config.terminal_velocity_weight] * nu
        )
        prog.AddQuadraticCost(terminal, np.zeros(2 * nu), self.X_var[-1], is_convex=True)
        self._solver, self._options = make_qp_solver(config, solver_name)

    def set_first_input_bounds(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Bounds of u_0 (n each): its exact viability interval from this step's x_0."""
        self._first_input_box.set_bounds(lo, hi)

    def load(self, x0: np.ndarray, Q: np.ndarray, b: np.ndarray) -> None:
        """This step's stage costs 1/2 v'Q_k v + b_k'v on v_k = [x_k, u_k] (Q (N, 3n, 3n),
        b (N, 3n); stage 0 keeps its u_0 block: x_0 is data) and x_0 (2n)."""
        nx = 2 * self.nu
        self._stage_costs[0].UpdateCoefficients(Q[0, nx:, nx:], b[0, nx:], 0.0, is_convex=True)
        for k in range(1, self.N):
            self._stage_costs[k].UpdateCoefficients(Q[k], b[k], 0.0, is_convex=True)
        bounds = np.zeros(nx * self.N)
        bounds[:nx] = self._Phi[0] @ x0
        self._dynamics.set_bounds(bounds, bounds)

    def solve(self, U: np.ndarray, x_bar: np.ndarray):
        """Solves the loaded QP warm-started at plan U (N, n) and its node states x_bar
        (N + 1, 2n): (U_new (N, n), "") or (None, why it failed)."""
        guess = np.concatenate([U.reshape(-1), x_bar[1:].reshape(-1)])
        result = self._solver.Solve(self.prog, guess, self._options)
        return _solution(result, self.U_var, (self.N, self.nu))


class CondensedQp:
    """min 1/2 d'Hd + g'd subject to d_lo <= C d <= d_hi by Drake's solver, on a dense
    program built at the first `solve`.

    Args:
        config: the NMPC settings (solver tolerances).
        C: the constraint rows, shape (rows, nN).
        solver_name: "osqp" or "clarabel" (Clarabel at CONDENSED_CLARABEL_TOLERANCE).
    """

    def __init__(self, config: NmpcConfig, C: np.ndarray, solver_name: str):
        self._config, self._C, self._solver_name = config, C, solver_name
        self._program = None

    def solve(self, H, g, d_lo, d_hi):
        """(d (nN,), "") or (None, why it failed)."""
        if self._program is None:
            rows, size = self._C.shape
            prog = MathematicalProgram()
            d = prog.NewContinuousVariables(size, "d")
            cost = prog.AddQuadraticCost(np.eye(size), np.zeros(size), d, True)
            limits = prog.AddLinearConstraint(
                self._C, np.full(rows, -np.inf), np.full(rows, np.inf), d
            )
            solver = make_qp_solver(self._config, self._solver_name, CONDENSED_CLARABEL_TOLERANCE)
            self._program = (prog, d, cost.evaluator(), limits.evaluator(), solver)
        prog, d, cost, limits, (solver, options) = self._program
        cost.UpdateCoefficients(H, g, 0.0, is_convex=True)
        # C is the OCP's own array: a legged platform's leg rows change with the plan
        limits.UpdateCoefficients(self._C, d_lo, d_hi)
        result = solver.Solve(prog, None, options)
        return _solution(result, d, (-1,))
