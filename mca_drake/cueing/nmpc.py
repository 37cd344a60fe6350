"""Nonlinear MPC motion cueing on the exact joint-space plant, on Drake's MathematicalProgram.

Optimal control problem over a horizon of N intervals of a non-uniform grid (short intervals
first, longer later: downsampling), with u_k (n, one per joint) constant over interval k of
duration T_k:

    minimise   sum_k w_k ( ||y(x_k, u_k) - r_k||^2_Wy + lambda_u ||u_k||^2 + lambda_q ||q_k||^2 )
               + lambda_qN ||q_N||^2 + lambda_qdN ||qd_N||^2
    subject to x_(k+1) = exact double-integrator step of duration T_k     (linear)
               -qdd_max <= u_k <= qdd_max
               q_min <= q_k <= q_max, |qd_k| <= qd_max                  (k = 1..N)
               u_0 inside the exact viability interval of `mca_drake.safety`: the robot
               can always brake to rest inside its limits (the safety guarantee)
               stoppability at the later nodes, q + qd^2 / (2 qdd_max) <= q_max (and
               mirrored), by tangents of that parabola: a linear outer approximation
               that every braking trajectory from a viable state satisfies, so the QP
               is always feasible while the exact constraint on u_0 keeps it safe.

w_k = T_k / horizon, so the cost approximates the time average of the paper's loss
(equation 9: output tracking, 0.1 u^2, washout q^2). With the perceived objective
(`NmpcConfig.objective`), the tracking term weighs the vestibular model's outputs instead:
the model (`mca_drake.perception`) of y - r over the grid, started from the controller's
state of it, which turns the output cost into a constant quadratic form in the residuals
(`MotionCueingOcp._build_perceived_objective`); the rest of the method is the same. The
dynamics are linear, so the states are condensed out: the decision variables are
U = (u_0, ..., u_(N-1)) only and every constraint is linear in U with a matrix fixed at
build time; only the bounds move with x_0.
The cost is nonlinear through y; each Gauss-Newton QP linearises y with the exact Jacobians
of `mca_drake.platforms.kinematics`. Because the constraints are exact and linear, every QP
iterate is feasible, and a backtracking line search on the true cost makes the `converged` mode a
descent method that stops at a KKT point of the nonlinear program.

Solving (`mca_drake.cueing.nmpc_sqp.SequentialQpSolve`, the iteration this problem class
inherits; the QP back-ends are `mca_drake.cueing.nmpc_qp`'s). Each QP is first solved on a
guessed active set (the previous step's or iteration's; `mca_drake.qp.active_set`): one
dense KKT solve, used only when it is
verified optimal (feasible, multipliers >= 0), so it is exact to round-off. Where the guess
is wrong, Goldfarb and Idnani's dual active-set method (`mca_drake.qp.dual_active_set`)
solves the QP exactly from the guess's dual-feasible part, in steps that each change one
row; the next solve's guess is therefore always an exact active set. Only if that fails
(round-off) does Drake's MathematicalProgram solve the QP (OSQP in rti mode, Clarabel in
converged mode), and a KKT solve on that answer's active set makes it exact.
Converged mode adds to the Gauss-Newton Hessian the term it leaves out, the residual-weighted
second derivatives of the output, from estimates of the output Hessians at every node that are
learnt along the iterations and carried from one control step to the next
(`mca_drake.cueing.output_curvature`; with large residuals Gauss-Newton alone converges
slowly); where a full step gains less than half what that model promised, the estimates are
measured afresh (`CURVATURE_REFRESH_RATIO`). Where the model is not convex it is convexified
(`_convex_model`) and, after a full step the line search rejected, damped (Marquardt,
`NmpcConfig.marquardt_damping`). It stops
once the KKT residual is below `kkt_tolerance` (relative to the cost), the step below
`step_tolerance`, or no descent is left.
"""

import dataclasses

import numpy as np
from threadpoolctl import ThreadpoolController

from mca_drake.conventions import NUM_CHANNELS
from mca_drake.cueing.nmpc_config import NmpcConfig
from mca_drake.cueing.nmpc_legs import LegRows
from mca_drake.cueing.nmpc_qp import CondensedQp, ShootingQp
from mca_drake.cueing.nmpc_sqp import SequentialQpSolve
from mca_drake.cueing.output_curvature import (
    NodeCondensing,
    node_jacobians,
)
from mca_drake.perception.filters import DiscreteFilter, vestibular_filter
from mca_drake.perception.models import PerceptionConfig
from mca_drake.platforms.kinematics import plant_output, plant_output_jacobians
from mca_drake.platforms.leg_platform import LegPlatform
from mca_drake.platforms.serial import SerialChain
from mca_drake.qp.active_set import (
    parallel_groups,
)
from mca_drake.safety import viable_acceleration_bounds

# The output channels of y and of a reference row.
NY = NUM_CHANNELS


def make_grid(horizon_steps: int, nodes: int) -> np.ndarray:
    """Interval lengths in control periods, shape (nodes,): non-decreasing integers that start
    at 1 and sum to `horizon_steps`, growing geometrically (short intervals first)."""
    if nodes == horizon_steps:
        return np.ones(nodes, dtype=int)
    if nodes == 1:
        return np.array([horizon_steps])
    # ratio rho with sum_k rho^k = horizon_steps, by bisection
    lo, hi = 1.0, 10.0
    for _ in range(100):
        rho = 0.5 * (lo + hi)
        total = (rho**nodes - 1) / (rho - 1)
        lo, hi = (rho, hi) if total < horizon_steps else (lo, rho)
    lengths = np.maximum(np.floor(rho ** np.arange(nodes)).astype(int), 1)
    # hand the rounding remainder to the longest intervals, keeping the order non-decreasing
    k = nodes - 1
    while lengths.sum() < horizon_steps:
        lengths[k] += 1
        k = k - 1 if k > 0 and lengths[k - 1] + 1 <= lengths[k] else nodes - 1
    while lengths.sum() > horizon_steps:  # floor never overshoots, but guard anyway
        lengths[np.argmax(lengths)] -= 1
    return np.sort(lengths)


@dataclasses.dataclass(frozen=True)
class PlanningLimits:
    """The limits the plan respects: the platform's, less a small reserve (shape (n,) each)."""

    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    qdd_max: np.ndarray


def _planning_limits(robot: SerialChain, margin: float) -> PlanningLimits:
    if not 0 <= margin < 0.1:
        raise ValueError(f"limit_margin must be in [0, 0.1); got {margin}")
    reserve = margin * (robot.q_max - robot.q_min)
    return PlanningLimits(
        robot.q_min + reserve,
        robot.q_max - reserve,
        (1 - margin) * robot.qd_max,
        (1 - margin) * robot.qdd_max,
    )


@dataclasses.dataclass(frozen=True)
class _GaussNewtonModel:
    """The Gauss-Newton model of the cost at a plan U: H (6N, 6N) and the exact gradient g
    (nN,); jac: the output Jacobians at the nodes; residual (N, 6): y - r; cost: the true
    cost at U; node_jacobian (N, 6, 3n): dy/dv_k;
    weighted_residual (N, 6): c_ka = d cost / d y_ka (2 w_k W_a (y - r)_ka for the inertial
    objective), the weights of the output Hessians in the cost's Hessian."""

    H: np.ndarray
    g: np.ndarray
    jac: object
    residual: np.ndarray
    cost: float
    node_jacobian: np.ndarray
    weighted_residual: np.ndarray


class MotionCueingOcp(SequentialQpSolve):
    """The condensed optimal control problem, built once; solved from (x0, references).

    Args:
        config: the NMPC settings.
        robot: the platform (n joints): the plan's inputs and states are sized from it.
    """

    def __init__(self, config: NmpcConfig | None, robot: SerialChain):
        self.config = config or NmpcConfig()
        self.config.validate()
        self.robot = robot
        self.nu = nu = robot.num_joints
        if np.any(robot.home != 0.0):
            # the washout and terminal terms pull the joints towards q = 0
            raise ValueError(
                f"the NMPC washes out towards q = 0; platform '{robot.name}' has its home at "
                f"{robot.home.tolist()}: give it a home of zeros (its URDF's joint origins at "
                "the neutral pose)"
            )
        cfg, r = self.config, self.robot
        self.limits = r = _planning_limits(r, cfg.limit_margin)
        self.interval_steps = make_grid(cfg.horizon_steps, cfg.nodes)
        N = self.N = self.interval_steps.size
        T = self.durations = self.interval_steps * cfg.time_step  # (N,)
        self.node_times = np.concatenate([[0.0], np.cumsum(T)])  # (N + 1,)
        self.node_steps = np.concatenate([[0], np.cumsum(self.interval_steps)])
        self.weights = T / T.sum()
        # Condensing: q_k = q0 + t_k qd0 + sum_j Sq[k, j] u_j; qd_k = qd0 + sum_j Sqd[k, j] u_j
        t = self.node_times
        Sq, Sqd = np.zeros((N + 1, N)), np.zeros((N + 1, N))
        for k in range(1, N + 1):
            for j in range(k):
                Sqd[k, j] = T[j]
                Sq[k, j] = (t[k] - t[j + 1]) * T[j] + 0.5 * T[j] ** 2
        self.Sq, self.Sqd = Sq, Sqd
        eye = np.eye(nu)
        self._Gq = np.kron(Sq, eye)  # (n(N+1), nN): d q_k / d U
        self._Gqd = np.kron(Sqd, eye)

        # Constraint rows, fixed: A U + (x0 terms) within bounds, for nodes 1..N.
        rows, self._row_q0, self._row_qd0, lower, upper = [], [], [], [], []
        for k in range(1, N + 1):
            Aq, Aqd = self._Gq[nu * k : nu * k + nu], self._Gqd[nu * k : nu * k + nu]
            rows += [Aq, Aqd]
            # q_k = q0 + t_k qd0 + Aq U, qd_k = qd0 + Aqd U
            self._row_q0 += [eye, np.zeros((nu, nu))]
            self._row_qd0 += [t[k] * eye, eye]
            lower += [r.q_min, -r.qd_max]
            upper += [r.q_max, r.qd_max]
            for side in (+1.0, -1.0):
                for slope, offset in self._tangents():
                    # Upper side (side = +1): q + slope qd <= q_max + offset; the lower side
                    # is its mirror image (q -> -q, qd -> -qd).
                    rows.append(side * (Aq + slope[:, None] * Aqd))
                    self._row_q0.append(side * eye)
                    self._row_qd0.append(side * (t[k] * eye + np.diag(slope)))
                    lower.append(np.full(nu, -np.inf))
                    upper.append((r.q_max if side > 0 else -r.q_min) + offset)
        self.A = np.vstack(rows)
        # A legged platform's legs: rows linearised about the plan at every iteration
        # (`nmpc_legs`), between the fixed node rows and the box, rewritten in place.
        self._legs = None
        if isinstance(robot, LegPlatform) and cfg.leg_constraints:
            self._legs = LegRows(
                robot, self._Gq, self._Gqd, cfg.limit_margin, cfg.stoppability_tangents
            )
        leg_rows = 0 if self._legs is None else self._legs.num_rows
        self._leg_rows = slice(self.A.shape[0], self.A.shape[0] + leg_rows)
        # Every row of the QP in U: the node constraints A, the legs', the box on U itself.
        self._C = np.vstack([self.A, np.zeros((leg_rows, nu * N)), np.eye(nu * N)])
        self.num_rows = self._C.shape[0]
        # node 1's rows are multiples of u_0's box rows (the exact viability interval); the
        # legs' rows change with the plan and are counted parallel to none
        self._parallel = parallel_groups(self._C)
        self._parallel[self._leg_rows] = -1
        self._row_norms = np.linalg.norm(self._C, axis=1)
        self._blas = ThreadpoolController()
        self._corrections = cfg.active_set_corrections
        if self._corrections is None:
            self._corrections = 0
        self._A_q0, self._A_qd0 = np.vstack(self._row_q0), np.vstack(self._row_qd0)
        self._lower0, self._upper0 = np.concatenate(lower), np.concatenate(upper)

        # Constant quadratic terms: input and washout (over nodes 0..N-1) and terminal cost.
        w6 = np.repeat(self.weights, nu)
        Gq_nodes = self._Gq[: nu * N]
        self._H_const = 2 * (
            cfg.input_weight * np.diag(w6)
            + cfg.washout_weight * Gq_nodes.T @ (w6[:, None] * Gq_nodes)
            + cfg.terminal_position_weight * self._Gq[nu * N :].T @ self._Gq[nu * N :]
            + cfg.terminal_velocity_weight * self._Gqd[nu * N :].T @ self._Gqd[nu * N :]
        )
        self._output_weights = np.asarray(cfg.output_weights, float)
        # The perceived objective's quadratic form in the stacked residuals (6N, 6N) and the
        # map from the perception state to its equivalent reference shift; None: inertial.
        self.perception_filter: DiscreteFilter | None = None
        self._output_form = self._state_to_reference = None
        if cfg.objective == "perceived":
            self._build_perceived_objective()

        self._u_max = np.tile(r.qdd_max, N)
        self._condensing = NodeCondensing(Sq, Sqd, nu)
        # Gauss-Newton stage Hessian terms beside J^T W J, on v = [q, qd, u]: washout, input.
        self._stage_regularisation = np.diag(
            np.r_[np.full(nu, cfg.washout_weight), np.zeros(nu), np.full(nu, cfg.input_weight)]
        )
        self._build_program()

    def _build_perceived_objective(self) -> None:
        """The perceived objective as a quadratic form in the residuals e_k = y_k - r_k.

        The vestibular model is linear, so the perceived error (perceived y minus perceived r)
        is the model applied to e, from the difference of the two models' states, eps. Over
        the grid, with e_k held over interval k (the model's exact steps of T_k):

            eps_(k+1) = Phi_k eps_k + Gamma_k e_k,   P_(k+1) = C eps_(k+1) + D e_k,

        P_(k+1) the perceived error at the end of interval k, weighed by w_k W. Stacked,
        P = M e + L eps_0, and the output cost is (M e + L eps_0)' diag(w W) (M e + L eps_0).
        M is block lower-triangular with the invertible C Gamma_k + D on its diagonal, so
        M e + L eps_0 = M (e + M^-1 L eps_0): eps_0 shifts the reference by -M^-1 L eps_0 and
        the cost is e' S e with S = M' diag(w W) M, a constant matrix (`_output_form`).
        """
        cfg, N = self.config, self.N
        f = vestibular_filter(PerceptionConfig(model=cfg.perception_model), cfg.time_step)
        Phi, Gamma = f.steps(self.interval_steps)
        n = f.num_states
        M, L = np.zeros((NY * N, NY * N)), np.zeros((NY * N, n))
        free, forced = np.eye(n), np.zeros((n, NY * N))  # eps_k = free eps_0 + forced e
        for k in range(N):
            free, forced = Phi[k] @ free, Phi[k] @ forced
            forced[:, NY * k : NY * k + NY] += Gamma[k]
            rows = slice(NY * k, NY * k + NY)  # P_(k+1)
            M[rows] = f.C @ forced
            M[rows, NY * k : NY * k + NY] += f.D
            L[rows] = f.C @ free
        weights = np.repeat(self.weights, NY) * np.tile(self._output_weights, N)
        self.perception_filter = f
        self._output_form = M.T @ (weights[:, None] * M)
        self._state_to_reference = np.linalg.solve(M, L)

    def perceived_references(self, refs: np.ndarray, perception_state) -> np.ndarray:
        """The references (N, 6) that make the inertial-form cost of the perceived objective
        start from `perception_state` (the model's state of perceived y minus perceived r,
        shape (n,); `perception_filter`): refs - M^-1 L eps_0 (`_build_perceived_objective`).
        """
        eps = np.asarray(perception_state, dtype=float)
        if eps.shape != (self.perception_filter.num_states,) or not np.all(np.isfinite(eps)):
            raise ValueError(
                f"perception_state must be {self.perception_filter.num_states} finite values; "
                f"got shape {eps.shape}"
            )
        return refs - (self._state_to_reference @ eps).reshape(self.N, NY)

    def _build_program(self) -> None:
        """Drake's QP back-ends of the Gauss-Newton step (`cueing.nmpc_qp`): the sparse
        multiple-shooting program, built now, and the condensed one for the perceived
        objective, built at its first use."""
        cfg = self.config
        # Drake's solver when the hot start does not settle; its answer is made exact (and
        # given multipliers) by a KKT solve on its active set when that verifies. "auto":
        # OSQP in rti mode, Clarabel in converged mode. (OSQP first and Clarabel after it in
        # converged mode made the worst steps on a 3 g step twice as slow: where the hot
        # start fails, OSQP's answer rarely verifies either.)
        auto = "osqp" if cfg.mode == "rti" else "clarabel"
        self.qp_solver_name = auto if cfg.qp_solver == "auto" else cfg.qp_solver
        self._shooting = ShootingQp(
            cfg, self.limits, self.durations, self._tangents(), self.qp_solver_name
        )
        # On the dense, condensed QP OSQP's answer at rti's tolerance is too rough to cue
        # with (jumps of 0.3 m/s^2 on a surge pulse): "auto" takes Clarabel in both modes.
        name = "clarabel" if cfg.qp_solver == "auto" else self.qp_solver_name
        self._condensed_qp = CondensedQp(cfg, self._C, name)

    def _tangents(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(slope, offset) per tangent of the stopping parabola q = q_max - v^2 / (2 a) at
        v = qd_max i / n (i = 1..n): q + (v / a) qd <= q_max + v^2 / (2 a)."""
        n, lim = self.config.stoppability_tangents, self.limits
        return [
            (v / lim.qdd_max, v * v / (2 * lim.qdd_max))
            for v in (lim.qd_max * i / n for i in range(1, n + 1))
        ]

    # ----------------------------------------------------------------- evaluation
    def states(self, x0: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Node positions and velocities for plan U (N, n): q, qd each (N + 1, n)."""
        q0, qd0 = x0[: self.nu], x0[self.nu :]
        q = q0 + self.node_times[:, None] * qd0 + self.Sq @ U
        qd = qd0 + self.Sqd @ U
        return q, qd

    def cost(self, x0: np.ndarray, U: np.ndarray, refs: np.ndarray) -> float:
        """The true nonlinear cost of plan U (N, n) for references refs (N, 6)."""
        q, qd = self.states(x0, U)
        return self._cost_of(q, qd, U, plant_output(q[:-1], qd[:-1], U, self.robot) - refs)

    def _cost_of(self, q, qd, U, residual) -> float:
        """The cost from node states q, qd (N + 1, n), U (N, n) and y - r (N, 6)."""
        cfg = self.config
        stage = cfg.input_weight * (U**2).sum(1) + cfg.washout_weight * (q[:-1] ** 2).sum(1)
        if self._output_form is None:
            output = self.weights @ (residual**2 @ self._output_weights)
        else:
            e = residual.reshape(-1)
            output = e @ self._output_form @ e
        terminal = cfg.terminal_position_weight * (q[-1] ** 2).sum() + (
            cfg.terminal_velocity_weight * (qd[-1] ** 2).sum()
        )
        return float(output + self.weights @ stage + terminal)

    def constraint_bounds(self, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bounds lb <= A U <= ub for the current state (shape (rows,) each)."""
        shift = self._A_q0 @ x0[: self.nu] + self._A_qd0 @ x0[self.nu :]
        return self._lower0 - shift, self._upper0 - shift

    def input_bounds(self, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bounds on U (6N each): the acceleration limits, and for u_0 the exact viability
        interval (`mca_drake.safety`), which keeps the robot able to stop inside its
        (planning) limits whatever the rest of the plan does."""
        lim = self.limits
        lo0, hi0, _ = viable_acceleration_bounds(
            x0[: self.nu],
            x0[self.nu :],
            lim.q_min,
            lim.q_max,
            lim.qd_max,
            lim.qdd_max,
            self.config.time_step,
        )
        lo, hi = -self._u_max.copy(), self._u_max.copy()
        lo[: self.nu], hi[: self.nu] = lo0, hi0
        return lo, hi

    def is_feasible(self, x0: np.ndarray, U: np.ndarray, tol: float = 1e-7) -> bool:
        """Whether plan U satisfies every constraint from state x0 (a legged platform's
        legs: their planned stroke and speed, exactly, at nodes 2..N)."""
        lb, ub = self.constraint_bounds(x0)
        AU = self.A @ U.reshape(-1)
        lo, hi = self.input_bounds(x0)
        u = U.reshape(-1)
        legs_within = self._legs is None or self._legs.violation(*self.states(x0, U)) <= tol
        return bool(
            np.all(AU >= lb - tol)
            and np.all(AU <= ub + tol)
            and np.all(u >= lo - tol)
            and np.all(u <= hi + tol)
            and legs_within
        )

    def load_leg_rows(self, x0, U, row_lo: np.ndarray, row_hi: np.ndarray) -> None:
        """A legged platform's leg rows linearised about plan U (N, n) from x0: written into
        the QP's rows and into `row_lo`, `row_hi` (`num_rows` each, bounds on C U) in place,
        so that the step's bounds (row - C U) are the linearisation's. No-op elsewhere."""
        if self._legs is None:
            return
        C, lo, hi = self._legs.rows(*self.states(x0, U))
        rows = self._leg_rows
        self._C[rows] = C
        self._row_norms[rows] = np.linalg.norm(C, axis=1)
        CU = C @ U.reshape(-1)
        row_lo[rows], row_hi[rows] = lo + CU, hi + CU

    def gauss_newton_terms(self, x0, U, refs) -> tuple[np.ndarray, np.ndarray]:
        """Hessian H (6N, 6N) and gradient g (6N,) of the Gauss-Newton model at U."""
        model = self._gauss_newton(x0, U, refs)
        return model.H, model.g

    def _gauss_newton(self, x0, U, refs) -> "_GaussNewtonModel":
        """The Gauss-Newton model at U, with the Jacobians and residuals it used."""
        cfg, N = self.config, self.N
        q, qd = self.states(x0, U)
        jac = plant_output_jacobians(q[:-1], qd[:-1], U, self.robot)
        residual = jac.y - refs  # (N, 6)
        cost = self._cost_of(q, qd, U, residual)
        # Node by node, on v_k = (q_k, qd_k, u_k): dy_k/dv_k (N, 6, 18), Gauss-Newton's
        # 2 w_k J_k^T W J_k and the output part of the gradient, 2 w_k J_k^T W r_k, mapped to U
        # by the condensing (the condensed 6N x 6N Jacobian is never formed: 3x faster).
        node_jacobian = node_jacobians(jac)
        if self._output_form is None:
            weighted = 2 * self.weights[:, None] * self._output_weights[None, :] * residual
            W = self.weights[:, None] * self._output_weights[None, :]
            WJ = W[:, :, None] * node_jacobian
            H = self._condensing.assemble(2 * np.swapaxes(node_jacobian, 1, 2) @ WJ)
        else:
            # perceived: the output cost e' S e couples the nodes; with the condensed
            # Jacobian J (6N, 6N), Gauss-Newton's Hessian is 2 J' S J and dcost/dy = 2 S e
            weighted = (2 * self._output_form @ residual.reshape(-1)).reshape(N, NY)
            J = self._condensing.jacobian(node_jacobian)
            H = 2 * J.T @ self._output_form @ J
        H = H + self._H_const
        # gradient of the true cost at U (exact: Gauss-Newton changes only the Hessian)
        Uf = U.reshape(-1)
        q_nodes = q[:-1].reshape(-1)
        w6 = np.repeat(self.weights, self.nu)
        g = (
            self._condensing.gradient(np.einsum("kai,ka->ki", node_jacobian, weighted))
            + 2 * cfg.input_weight * w6 * Uf
            + 2 * cfg.washout_weight * self._Gq[: self.nu * N].T @ (w6 * q_nodes)
            + 2 * cfg.terminal_position_weight * self._Gq[self.nu * N :].T @ q[-1]
            + 2 * cfg.terminal_velocity_weight * self._Gqd[self.nu * N :].T @ qd[-1]
        )
        return _GaussNewtonModel(H, g, jac, residual, cost, node_jacobian, weighted)

    # ----------------------------------------------------------------- solving
    def _update_qp(self, x0: np.ndarray, U: np.ndarray, refs: np.ndarray, jac) -> np.ndarray:
        """Loads the QP of y linearised around plan U from x0 (`jac`: the output Jacobians
        at U's nodes); returns the node states (N + 1, 2n) of U."""
        N = self.N
        q, qd = self.states(x0, U)
        W = self._output_weights
        x_bar = np.concatenate([q, qd], axis=1)
        c = jac.y - refs  # residual at the linearisation point
        # Stage k >= 1 is a quadratic in v_k = [x_k, u_k] (3n); stage 0 in u_0 alone (x_0 is
        # given). All stages are formed at once; only the coefficient updates loop.
        J = np.concatenate([jac.dy_dq, jac.dy_dqd, jac.dy_dqdd], axis=2)  # (N, 6, 3n)
        v_bar = np.concatenate([x_bar[:N], U], axis=1)  # (N, 3n)
        v_bar[0, : 2 * self.nu] = 0.0  # x_0 is fixed: stage 0 is linearised in u_0 only
        WJ = W[None, :, None] * J
        w = self.weights[:, None, None]
        Q = 2 * w * (np.einsum("kai,kaj->kij", J, WJ) + self._stage_regularisation)
        b = (
            2
            * self.weights[:, None]
            * np.einsum("kai,ka->ki", WJ, c - np.einsum("kai,ki->ka", J, v_bar))
        )
        self._shooting.load(x0, Q, b)
        return x_bar

    def _solve_qp(self, U: np.ndarray, x_bar: np.ndarray):
        """Solves the loaded QP warm-started at (U, x_bar); (U_new, message)."""
        return self._shooting.solve(U, x_bar)

    def shift(self, U: np.ndarray, steps: int = 1) -> np.ndarray:
        """The plan U moved `steps` control periods ahead: u_new(interval k) = u(t_k + steps dt),
        the last value held past the horizon."""
        return U[self._shifted_intervals(steps)]

    def shift_output_hessians(self, hessians: np.ndarray, steps: int = 1) -> np.ndarray:
        """Output Hessians (N, 6, 3n, 3n) of a plan, moved with it (`shift`): node k takes
        those of the interval that holds t_k + steps dt."""
        return hessians[self._shifted_intervals(steps)]

    def _shifted_intervals(self, steps: int) -> np.ndarray:
        """The interval of the old grid that holds each node time t_k + steps dt, shape (N,)."""
        idx = np.searchsorted(self.node_steps[1:], self.node_steps[:-1] + steps, side="right")
        return np.minimum(idx, self.N - 1)

    def braking_plan(self, x0: np.ndarray) -> np.ndarray:
        """The safest plan when no solve succeeds: brake every joint to rest as fast as the
        acceleration limits allow, then hold, shape (N, n)."""
        qd = np.array(x0[self.nu :], dtype=float)
        U = np.zeros((self.N, self.nu))
        for k, T in enumerate(self.durations):
            U[k] = np.clip(-qd / T, -self.robot.qdd_max, self.robot.qdd_max)
            qd = qd + T * U[k]
        return U
