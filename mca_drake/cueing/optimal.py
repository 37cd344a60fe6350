"""The offline-optimal bound: the best cue the robot can give a whole recording, knowing it all.

For a reference r_0..r_(T-1) at the control period h, from the robot at rest at home:

    minimise   (1/T) sum_k ( ||y(x_k, u_k) - r_k||^2_W + lambda_u ||u_k||^2 + lambda_q ||q_k||^2 )
    subject to x_(k+1) = exact double-integrator step of u_k over h       (k = 0..T-1)
               q_min <= q_k <= q_max, |qd_k| <= qd_max                     (k = 1..T)
               |u_k| <= qdd_max

with the NMPC's weights (`NmpcConfig`: the same tracking objective, here with perfect
preview over the whole recording and no horizon). The limits are the robot's own (Table I),
at every sample, as the summaries count violations.

Method: Gauss-Newton sequential quadratic programming. Each QP linearises y at the current
trajectory with the exact Jacobians of `mca_drake.kinematics` and is solved in full by
Drake's Clarabel (interior point) on the sparse multiple-shooting program (variables u_k and
x_(k+1) per step: banded, linear in T). The dynamics are linear and the constraints are
boxes, so every iterate is feasible and a backtracking line search on the true cost makes
the method a descent method: started from a causal MCA's trajectory, the bound's cost is
never above that MCA's. It stops at a KKT point: the stationarity residual of the last QP
(|H d|_inf, which is the nonlinear program's |grad f + A' lambda|_inf with that QP's
multipliers, Gauss-Newton's gradient being exact) relative to max(1, |grad f|_inf) below
`kkt_tolerance`.
"""

import dataclasses
import time

import numpy as np
import scipy.sparse as sp
from pydrake.solvers import ClarabelSolver, MathematicalProgram, SolverOptions

from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.cueing.nmpc import NmpcConfig
from mca_drake.input_checks import as_float_array, check_config_numbers
from mca_drake.kinematics import plant_output, plant_output_jacobians
from mca_drake.robot import KR500, NUM_JOINTS, load_kr500

NU, NX = NUM_JOINTS, 2 * NUM_JOINTS

_TUNED = NmpcConfig()


@dataclasses.dataclass
class OptimalConfig:
    """Settings of the offline-optimal bound; the weights default to the shipped NMPC's."""

    # Weights of the six output channels (w_x, w_y, w_z, f_x, f_y, a_z) in ||y - r||^2.
    output_weights: list[float] = dataclasses.field(
        default_factory=lambda: list(_TUNED.output_weights)
    )
    # Weight of ||u||^2, (rad/s^2)^-2.
    input_weight: float = _TUNED.input_weight
    # Washout weight of ||q||^2, rad^-2.
    washout_weight: float = _TUNED.washout_weight
    # Control period, s.
    time_step: float = CONTROL_PERIOD_S
    # Gauss-Newton iterations at most.
    max_iterations: int = 30
    # Stop once the KKT (stationarity) residual relative to max(1, |grad f|_inf) is below.
    kkt_tolerance: float = 1e-6
    # Clarabel's gap and feasibility tolerances on each QP.
    qp_tolerance: float = 1e-9

    def validate(self) -> None:
        """Raises ValueError for settings that cannot run."""
        check_config_numbers(self)
        if len(self.output_weights) != 6 or min(self.output_weights) < 0:
            raise ValueError("output_weights must be six non-negative values")
        if min(self.input_weight, self.washout_weight) < 0 or not self.time_step > 0:
            raise ValueError("weights must be non-negative and time_step positive")
        if self.max_iterations < 1 or not self.kkt_tolerance > 0 or not self.qp_tolerance > 0:
            raise ValueError("max_iterations >= 1; kkt_tolerance and qp_tolerance > 0")


@dataclasses.dataclass(frozen=True)
class OptimalResult:
    """The bound's trajectory and how the solver reached it.

    Attributes:
        U: joint accelerations u_k, rad/s^2, shape (T, 6).
        states: x_k = [q_k, qd_k], shape (T + 1, 12) (x_0: the start).
        outputs: y(x_k, u_k), shape (T, 6).
        cost: the objective at U.
        kkt_residual: the last QP's stationarity residual relative to max(1, |grad f|_inf).
        iterations: Gauss-Newton QPs solved.
        converged: whether kkt_residual reached the tolerance.
        costs: the objective after each iteration (the start first).
        solve_time_s: wall-clock time.
    """

    U: np.ndarray
    states: np.ndarray
    outputs: np.ndarray
    cost: float
    kkt_residual: float
    iterations: int
    converged: bool
    costs: list[float]
    solve_time_s: float


class OptimalCueing:
    """The whole-recording problem for T steps, its sparse QP built once.

    Args:
        steps: T, the reference's samples.
        config: the bound's settings (default OptimalConfig()).
        robot: the KR500 description.
    """

    def __init__(self, steps: int, config: OptimalConfig | None = None, robot: KR500 | None = None):
        self.config = config or OptimalConfig()
        self.config.validate()
        if steps < 1:
            raise ValueError(f"steps must be at least 1; got {steps}")
        self.robot = robot if robot is not None else load_kr500()
        self.T = int(steps)
        h = self.config.time_step
        eye = np.eye(NU)
        self._Phi = np.block([[eye, h * eye], [np.zeros((NU, NU)), eye]])
        self._Gamma = np.vstack([0.5 * h * h * eye, h * eye])
        self._build_program()

    def _build_program(self) -> None:
        """Variables: the steps du_k and dx_(k+1); dynamics dx_(k+1) = Phi dx_k + Gamma du_k
        (dx_0 = 0); a quadratic cost per stage on (dx_k, du_k); bounds set per iteration."""
        T = self.T
        prog = self.prog = MathematicalProgram()
        self.dU = prog.NewContinuousVariables(T, NU, "du")
        self.dX = prog.NewContinuousVariables(T, NX, "dx")  # dx_1..dx_T
        nz = NU * T + NX * T
        rows, cols, vals = [], [], []

        def put(r0, c0, block):
            ii, jj = np.nonzero(block)
            rows.extend(r0 + ii)
            cols.extend(c0 + jj)
            vals.extend(block[ii, jj])

        for k in range(T):
            r0 = NX * k
            put(r0, NU * T + NX * k, np.eye(NX))
            put(r0, NU * k, -self._Gamma)
            if k > 0:
                put(r0, NU * T + NX * (k - 1), -self._Phi)
        A = sp.csc_matrix((vals, (rows, cols)), shape=(NX * T, nz))
        all_vars = np.concatenate([self.dU.reshape(-1), self.dX.reshape(-1)])
        prog.AddLinearEqualityConstraint(A, np.zeros(NX * T), all_vars)
        self._box_u = prog.AddBoundingBoxConstraint(
            np.zeros(NU * T), np.zeros(NU * T), self.dU.reshape(-1)
        ).evaluator()
        self._box_x = prog.AddBoundingBoxConstraint(
            np.zeros(NX * T), np.zeros(NX * T), self.dX.reshape(-1)
        ).evaluator()
        self._costs = [prog.AddQuadraticCost(np.eye(NU), np.zeros(NU), self.dU[0], is_convex=True)]
        for k in range(1, T):
            v = np.concatenate([self.dX[k - 1], self.dU[k]])
            self._costs.append(
                prog.AddQuadraticCost(np.eye(NX + NU), np.zeros(NX + NU), v, is_convex=True)
            )
        self._costs = [c.evaluator() for c in self._costs]
        self._solver = ClarabelSolver()
        self._options = SolverOptions()
        for option in ("tol_gap_abs", "tol_gap_rel", "tol_feas"):
            self._options.SetOption(self._solver.solver_id(), option, self.config.qp_tolerance)

    # ------------------------------------------------------------------ trajectories
    def states(self, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
        """x_0..x_T (T + 1, 12) of inputs U (T, 6) from x0 (12), by the exact step."""
        h = self.config.time_step
        qd = x0[NU:] + h * np.concatenate([np.zeros((1, NU)), np.cumsum(U, axis=0)])
        # q_(k+1) = q_k + h qd_k + h^2/2 u_k
        increments = h * qd[:-1] + 0.5 * h * h * U
        q = x0[:NU] + np.concatenate([np.zeros((1, NU)), np.cumsum(increments, axis=0)])
        return np.concatenate([q, qd], axis=1)

    def cost(self, x0: np.ndarray, U: np.ndarray, reference: np.ndarray) -> float:
        """The objective of inputs U (T, 6) from x0 for the reference (T, 6)."""
        x = self.states(x0, U)
        y = plant_output(x[:-1, :NU], x[:-1, NU:], U, self.robot)
        return self._cost_of(x, U, y - reference)

    def _cost_of(self, x, U, residual) -> float:
        cfg = self.config
        stage = residual**2 @ np.asarray(cfg.output_weights) + cfg.input_weight * (U**2).sum(1)
        stage = stage + cfg.washout_weight * (x[:-1, :NU] ** 2).sum(1)
        return float(stage.mean())

    # ------------------------------------------------------------------ solving
    def solve(self, reference, U_start=None, x0=None, progress=None) -> OptimalResult:
        """The bound for `reference` (T, 6), from `U_start` (T, 6; default zeros, which is
        feasible from rest) and x0 (default rest at q = 0).

        Args:
            progress: optional callable(iteration, cost, kkt_residual) called per iteration.

        Raises:
            ValueError: a reference or start of the wrong shape, non-finite, or a start
                outside the limits.
        """
        start = time.perf_counter()
        cfg, robot, T = self.config, self.robot, self.T
        reference = as_float_array("reference", reference, last_dim=6)
        if reference.shape != (T, 6):
            raise ValueError(f"reference must have shape ({T}, 6); got {reference.shape}")
        x0 = np.zeros(NX) if x0 is None else as_float_array("x0", x0, last_dim=NX)
        U = np.zeros((T, NU)) if U_start is None else np.array(U_start, dtype=float)
        if U.shape != (T, NU) or not np.all(np.isfinite(U)):
            raise ValueError(f"U_start must be finite with shape ({T}, 6); got {U.shape}")
        x = self.states(x0, U)
        if not self._feasible(x, U):
            raise ValueError("U_start leaves the robot's limits: no feasible start")
        weights = np.asarray(cfg.output_weights)
        w = 1.0 / T
        costs, kkt, iterations = [], float("inf"), 0
        jac = plant_output_jacobians(x[:-1, :NU], x[:-1, NU:], U, robot)
        cost = self._cost_of(x, U, jac.y - reference)
        costs.append(cost)
        for iterations in range(1, cfg.max_iterations + 1):
            Q, b = self._stage_terms(x, U, jac, jac.y - reference, weights, w)
            d = self._solve_qp(x, U, Q, b)
            if d is None:
                break
            dU, dX = d
            kkt = self._stationarity(Q, b, dU, dX)
            alpha, trial = 1.0, None
            while alpha >= 1e-8:
                U_try = U + alpha * dU
                x_try = self.states(x0, U_try)
                jac_try = plant_output_jacobians(x_try[:-1, :NU], x_try[:-1, NU:], U_try, robot)
                trial = self._cost_of(x_try, U_try, jac_try.y - reference)
                if trial <= cost + 1e-12 * max(1.0, abs(cost)):
                    break
                alpha *= 0.5
            if alpha < 1e-8:
                break
            U, x, jac, cost = U_try, x_try, jac_try, trial
            costs.append(cost)
            if progress is not None:
                progress(iterations, cost, kkt)
            if kkt <= cfg.kkt_tolerance and alpha == 1.0:
                break
        y = plant_output(x[:-1, :NU], x[:-1, NU:], U, robot)
        return OptimalResult(
            U=U,
            states=x,
            outputs=y,
            cost=cost,
            kkt_residual=kkt,
            iterations=iterations,
            converged=kkt <= cfg.kkt_tolerance,
            costs=costs,
            solve_time_s=time.perf_counter() - start,
        )

    def _feasible(self, x, U, tol: float = 1e-9) -> bool:
        r = self.robot
        q, qd = x[1:, :NU], x[1:, NU:]
        return bool(
            np.all(q >= r.q_min - tol)
            and np.all(q <= r.q_max + tol)
            and np.all(np.abs(qd) <= r.qd_max + tol)
            and np.all(np.abs(U) <= r.qdd_max + tol)
        )

    def _stage_terms(self, x, U, jac, residual, weights, w):
        """Per stage, the Gauss-Newton Hessian Q_k (T, 18, 18) and gradient b_k (T, 18) on
        v_k = (dx_k, du_k) of the cost."""
        cfg = self.config
        J = np.concatenate([jac.dy_dq, jac.dy_dqd, jac.dy_dqdd], axis=2)  # (T, 6, 18)
        WJ = weights[None, :, None] * J
        Q = 2 * w * np.einsum("kai,kaj->kij", J, WJ)
        diag = np.r_[np.full(NU, cfg.washout_weight), np.zeros(NU), np.full(NU, cfg.input_weight)]
        Q = Q + 2 * w * np.diag(diag)[None]
        b = 2 * w * np.einsum("kai,ka->ki", WJ, residual)
        b[:, :NU] += 2 * w * cfg.washout_weight * x[:-1, :NU]
        b[:, 2 * NU :] += 2 * w * cfg.input_weight * U
        return Q, b

    def _solve_qp(self, x, U, Q, b):
        """The QP step (dU (T, 6), dX (T, 12)) or None where Clarabel fails."""
        r = self.robot
        lower_x = np.tile(np.r_[r.q_min, -r.qd_max], self.T) - x[1:].reshape(-1)
        upper_x = np.tile(np.r_[r.q_max, r.qd_max], self.T) - x[1:].reshape(-1)
        self._box_x.set_bounds(lower_x, upper_x)
        u = U.reshape(-1)
        u_max = np.tile(r.qdd_max, self.T)
        self._box_u.set_bounds(-u_max - u, u_max - u)
        self._costs[0].UpdateCoefficients(Q[0, NX:, NX:], b[0, NX:], 0.0, is_convex=True)
        for k in range(1, self.T):
            self._costs[k].UpdateCoefficients(Q[k], b[k], 0.0, is_convex=True)
        result = self._solver.Solve(self.prog, None, self._options)
        if not result.is_success():
            return None
        return result.GetSolution(self.dU), result.GetSolution(self.dX)

    def _stationarity(self, Q, b, dU, dX) -> float:
        """|H d|_inf / max(1, |g|_inf) of the last QP's step: the nonlinear program's
        stationarity residual with that QP's multipliers."""
        v = np.concatenate([np.vstack([np.zeros((1, NX)), dX[:-1]]), dU], axis=1)  # (T, 18)
        v[0, :NX] = 0.0
        Hd = np.einsum("kij,kj->ki", Q, v)
        Hd[0, :NX] = 0.0
        g = b.copy()
        g[0, :NX] = 0.0
        return float(np.max(np.abs(Hd)) / max(1.0, np.max(np.abs(g))))
