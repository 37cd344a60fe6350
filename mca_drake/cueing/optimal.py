"""The offline-optimal bound: the best cue the robot can give a whole recording, knowing it all.

For a reference r_0..r_(T-1) at the control period h, from the robot at rest at home:

    minimise   (1/T) sum_k ( ||y(x_k, u_k) - r_k||^2_W + lambda_u ||u_k||^2 + lambda_q ||q_k||^2 )
    subject to x_(k+1) = exact double-integrator step of u_k over h       (k = 0..T-1)
               q_min <= q_k <= q_max, |qd_k| <= qd_max                     (k = 1..T)
               |u_k| <= qdd_max

with the NMPC's weights (`NmpcConfig`: the same tracking objective, here with perfect
preview over the whole recording and no horizon). With the perceived objective
(`OptimalConfig.objective`) the tracking term weighs the vestibular model's outputs of the
errors instead, P_k = C eps_k + D (y_k - r_k) with eps_(k+1) = A eps_k + B (y_k - r_k) from
rest (`mca_drake.perception`: the perceived output minus the perceived reference); the
model's states become variables of the program, tied to the errors by its dynamics. The
limits are the robot's own (Table I), at every sample, as the summaries count violations.

Method: sequential quadratic programming. Each QP linearises y at the current trajectory
with the exact Jacobians of `mca_drake.platforms.kinematics`, its Hessian Gauss-Newton's (or, for
the inertial objective, Newton's made convex stage by stage: `curvature`), and is solved in
full by the structured interior-point method of `mca_drake.cueing.stagewise_qp` on the
multiple-shooting program (variables u_k and x_(k+1) per step, and the model's states
with the perceived objective): each of its Newton steps costs O(T). The dynamics are
linear and the constraints are boxes, so a backtracking line search on the true cost that
keeps every iterate within the limits makes the method a descent method: started from a
causal MCA's trajectory, the bound's cost is never above that MCA's. It stops at a KKT
point: the stationarity residual of the last QP (|H d|_inf, which is the nonlinear
program's |grad f + A' lambda|_inf with that QP's multipliers, Gauss-Newton's gradient
being exact) relative to max(1, |grad f|_inf) below `kkt_tolerance`.
"""

import dataclasses
import time

import numpy as np

from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.cueing.nmpc_config import OBJECTIVES, NmpcConfig
from mca_drake.cueing.optimal_legs import BoundLegRows
from mca_drake.cueing.output_curvature import finite_difference_hessians, residual_curvature
from mca_drake.cueing.shooting import double_integrator_step
from mca_drake.cueing.stagewise_qp import solve_stagewise_qp
from mca_drake.input_checks import as_float_array, check_config_numbers
from mca_drake.perception.filters import DiscreteFilter, vestibular_filter
from mca_drake.perception.models import PerceptionConfig
from mca_drake.platforms.kinematics import plant_output, plant_output_jacobians
from mca_drake.platforms.leg_platform import LegPlatform
from mca_drake.platforms.serial import SerialChain
from mca_drake.platforms.usage import limit_violations

# Each QP's tolerance as a share of the last KKT residual (inexact SQP).
QP_TOLERANCE_SHARE = 1e-3
# The scaled residual up to which an unconverged QP's step is still tried.
QP_RESIDUAL_USABLE = 1e-6
# Stages whose output Hessians are formed at once (6 x 18 x 18 values per stage).
# A legged platform's QPs re-solved per iteration at most, with the legs' bounds corrected by
# the linearisation's remainder at the last step (`OptimalCueing._corrected_for_legs`).
SECOND_ORDER_CORRECTIONS = 2
CURVATURE_CHUNK = 2000

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
    # What the output weights weigh: "inertial" (y - r) or "perceived" (the vestibular
    # model's outputs of y against those of r).
    objective: str = "inertial"
    # Vestibular model of the perceived objective: "telban-cardullo" or "ormsby".
    perception_model: str = "telban-cardullo"
    # Control period, s.
    time_step: float = CONTROL_PERIOD_S
    # Inertial objective: Newton's stage Hessians (Gauss-Newton's plus the residual
    # curvature, the output's second derivatives by finite differences of its exact
    # Jacobians), each projected onto the convex ones, instead of Gauss-Newton's. Off by
    # default: on 5 s flights from rest (light and jet, seeds 7 and 8) Gauss-Newton reached
    # the KKT tolerance in 9 to 35 iterations and this in 19 to more than 40, and on a
    # 30 s flight from the NMPC's trajectory it ended 0.7 % higher after 30; on
    # six-sample references Gauss-Newton took 4 iterations, this 5 to 33. The problem is
    # not convex: on one 5 s flight Gauss-Newton stopped at a point 0.25 % costlier than
    # where this went.
    curvature: bool = False
    # Iterations (QPs) at most.
    max_iterations: int = 30
    # Stop once the KKT (stationarity) residual relative to max(1, |grad f|_inf) is below.
    kkt_tolerance: float = 1e-6
    # The interior-point QP solver's tolerance on each QP's scaled residuals and gap near
    # the solution (far from it, 1e-3 of the last KKT residual): two decades below
    # kkt_tolerance's smallest useful value, since the KKT residual is measured on the
    # QP's step (a step 1e-9 off reads as a residual of that size).
    qp_tolerance: float = 1e-11
    # Interior-point iterations per QP at most.
    qp_iterations: int = 100

    def validate(self) -> None:
        """Raises ValueError for settings that cannot run."""
        check_config_numbers(self)
        if self.objective not in OBJECTIVES:
            raise ValueError(f"unknown objective '{self.objective}'; valid: {OBJECTIVES}")
        PerceptionConfig(model=self.perception_model).validate()
        if len(self.output_weights) != 6 or min(self.output_weights) < 0:
            raise ValueError("output_weights must be six non-negative values")
        if min(self.input_weight, self.washout_weight) < 0 or not self.time_step > 0:
            raise ValueError("weights must be non-negative and time_step positive")
        if min(self.max_iterations, self.qp_iterations) < 1:
            raise ValueError("max_iterations and qp_iterations must be at least 1")
        if not (self.kkt_tolerance > 0 and self.qp_tolerance > 0):
            raise ValueError("kkt_tolerance and qp_tolerance must be positive")


@dataclasses.dataclass(frozen=True)
class OptimalResult:
    """The bound's trajectory and how the solver reached it.

    Attributes:
        U: joint accelerations u_k, rad/s^2, shape (T, 6).
        states: x_k = [q_k, qd_k], shape (T + 1, 12) (x_0: the start).
        outputs: y(x_k, u_k), shape (T, 6).
        cost: the objective at U.
        kkt_residual: the last QP's stationarity residual relative to max(1, |grad f|_inf).
        iterations: QPs solved.
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
        robot: the platform (its joints, limits and kinematics).
    """

    def __init__(self, steps: int, config: OptimalConfig | None, robot: SerialChain):
        self.config = config or OptimalConfig()
        self.config.validate()
        if steps < 1:
            raise ValueError(f"steps must be at least 1; got {steps}")
        self.robot = robot
        self.nu = robot_joints = self.robot.num_joints
        self.nx = 2 * robot_joints
        if np.any(self.robot.home != 0.0):
            # the washout term pulls the joints towards q = 0
            raise ValueError(
                f"the bound washes out towards q = 0; platform '{self.robot.name}' has its "
                f"home at {self.robot.home.tolist()}"
            )
        self.T = int(steps)
        h = self.config.time_step
        # the tracking term's model of the errors: none (inertial: P = e) or the vestibular
        # model's (A, B, C, D) with n states
        if self.config.objective == "perceived":
            model = PerceptionConfig(model=self.config.perception_model)
            f = vestibular_filter(model, h)
            self._model = _modal(f.A, f.B, f.C, f.D)
        else:
            self._model = (np.zeros((0, 0)), np.zeros((0, 6)), np.zeros((6, 0)), np.eye(6))
        self._filter = DiscreteFilter(*self._model, time_step=h)
        self.n = self._model[0].shape[0]
        self._build_program()

    def _build_program(self) -> None:
        """The QP's fixed data: its stages are w_k = (de_k, dx_k, dz_k, du_k) for k = 0..T
        (stage T: the last states and an input that nothing weighs or bounds, so that every
        stage has the same shape; dz_k: a legged platform's legs, `optimal_legs`, else
        none), its dynamics w_(k+1)[:ns] = F_k w_k from de_0 = dx_0 = dz_0 = 0; the
        weights, Jacobians and bounds are set per iteration."""
        n, h = self.n, self.config.time_step
        Phi, Gamma = double_integrator_step(h, self.nu)
        self._legs = None
        if isinstance(self.robot, LegPlatform):
            self._legs = BoundLegRows(self.robot, Phi, Gamma)
        self.nz = 0 if self._legs is None else self._legs.size
        self.ns = n + self.nx + self.nz  # a stage's states
        self._F = np.zeros((self.ns, self.ns + self.nu))
        self._F[:n, :n] = self._model[0]
        self._F[n : n + self.nx, n : n + self.nx] = Phi
        self._F[n : n + self.nx, self.ns :] = Gamma

    # ------------------------------------------------------------------ trajectories
    def states(self, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
        """x_0..x_T (T + 1, 2n) of inputs U (T, n) from x0 (2n), by the exact step."""
        h = self.config.time_step
        qd = x0[self.nu :] + h * np.concatenate([np.zeros((1, self.nu)), np.cumsum(U, axis=0)])
        # q_(k+1) = q_k + h qd_k + h^2/2 u_k
        increments = h * qd[:-1] + 0.5 * h * h * U
        q = x0[: self.nu] + np.concatenate([np.zeros((1, self.nu)), np.cumsum(increments, axis=0)])
        return np.concatenate([q, qd], axis=1)

    def cost(self, x0: np.ndarray, U: np.ndarray, reference: np.ndarray) -> float:
        """The objective of inputs U (T, n) from x0 for the reference (T, 6)."""
        x = self.states(x0, U)
        y = plant_output(x[:-1, : self.nu], x[:-1, self.nu :], U, self.robot)
        return self._cost_of(x, U, y - reference)

    def tracked(self, errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(P (T, 6), eps (T + 1, n)): the signals the tracking term weighs, for the errors
        y - r (T, 6): the errors themselves (inertial), or the vestibular model's outputs
        P_k = C eps_k + D e_k and its states from rest (perceived)."""
        if not self.n:  # inertial: the errors themselves
            return errors, np.zeros((errors.shape[0] + 1, 0))
        _, eps = self._filter.trajectory(errors)
        return eps[:-1] @ self._filter.C.T + errors @ self._filter.D.T, eps

    def _cost_of(self, x, U, residual) -> float:
        cfg = self.config
        tracked, _ = self.tracked(residual)
        stage = tracked**2 @ np.asarray(cfg.output_weights) + cfg.input_weight * (U**2).sum(1)
        stage = stage + cfg.washout_weight * (x[:-1, : self.nu] ** 2).sum(1)
        return float(stage.mean())

    # ------------------------------------------------------------------ solving
    def solve(self, reference, U_start=None, x0=None, progress=None) -> OptimalResult:
        """The bound for `reference` (T, 6), from `U_start` (T, n; default zeros, which is
        feasible from rest) and x0 (default rest at q = 0).

        Args:
            progress: optional callable(iteration, cost, kkt_residual, step_length) called
                per iteration (step_length: the line search's share of the QP's step).

        Raises:
            ValueError: a reference or start of the wrong shape, non-finite, or a start
                outside the limits.
        """
        start = time.perf_counter()
        cfg, robot, T = self.config, self.robot, self.T
        reference = as_float_array("reference", reference, last_dim=6)
        if reference.shape != (T, 6):
            raise ValueError(f"reference must have shape ({T}, 6); got {reference.shape}")
        x0 = np.zeros(self.nx) if x0 is None else as_float_array("x0", x0, last_dim=self.nx)
        U = np.zeros((T, self.nu)) if U_start is None else np.array(U_start, dtype=float)
        if U.shape != (T, self.nu) or not np.all(np.isfinite(U)):
            raise ValueError(f"U_start must be finite with shape ({T}, {self.nu}); got {U.shape}")
        x = self.states(x0, U)
        if not self._feasible(x, U):
            raise ValueError("U_start leaves the robot's limits: no feasible start")
        weights = np.asarray(cfg.output_weights)
        w = 1.0 / T
        costs, kkt, iterations = [], float("inf"), 0
        jac = plant_output_jacobians(x[:-1, : self.nu], x[:-1, self.nu :], U, robot)
        cost = self._cost_of(x, U, jac.y - reference)
        costs.append(cost)
        for iterations in range(1, cfg.max_iterations + 1):
            Q, b, J = self._stage_terms(x, U, jac, jac.y - reference, weights, w)
            # inexact SQP: each QP solved only as far as the last KKT residual warrants
            # (1e-3 of it, at most 1e-6), down to qp_tolerance near the solution: on a 30 s
            # flight this saved a fifth of the interior-point iterations at the same
            # Gauss-Newton progress
            qp_tolerance = max(cfg.qp_tolerance, min(1e-6, QP_TOLERANCE_SHARE * kkt))
            d = self._solve_qp(x, U, Q, b, J, qp_tolerance)
            if d is not None and self._legs is not None:
                d = self._corrected_for_legs(x0, x, U, (Q, b, J), qp_tolerance, d)
            if d is None:
                break
            dU, dX, dE = d
            kkt = self._stationarity(Q, b, dU, dX, dE)
            alpha, trial = 1.0, None
            while alpha >= 1e-8:
                U_try = U + alpha * dU
                x_try = self.states(x0, U_try)
                # the QP meets the limits to its tolerance; the states integrated from the
                # inputs must meet them to 1e-9, or the step is shortened (the limits are
                # convex in U, and U is within them)
                if self._feasible(x_try, U_try):
                    jac_try = plant_output_jacobians(
                        x_try[:-1, : self.nu], x_try[:-1, self.nu :], U_try, robot
                    )
                    trial = self._cost_of(x_try, U_try, jac_try.y - reference)
                    if trial <= cost + 1e-12 * max(1.0, abs(cost)):
                        break
                alpha *= 0.5
            if alpha < 1e-8:
                break
            U, x, jac, cost = U_try, x_try, jac_try, trial
            costs.append(cost)
            if progress is not None:
                progress(iterations, cost, kkt, alpha)
            if kkt <= cfg.kkt_tolerance and alpha == 1.0:
                break
        y = plant_output(x[:-1, : self.nu], x[:-1, self.nu :], U, robot)
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

    def within_limits(self, x0: np.ndarray, U: np.ndarray, tol: float = 1e-9) -> bool:
        """Whether inputs U (T, 6) from x0 (12) keep every joint within its position,
        velocity and acceleration limits (to `tol`) at every step."""
        return self._feasible(self.states(x0, U), U, tol)

    def _feasible(self, x, U, tol: float = 1e-9) -> bool:
        """Whether states x (T + 1, 2n) and inputs U (T, n) keep every limit, judged as the
        run summaries count violations (`platforms.usage.limit_violations`: `tol` of each
        limit's half-range), so that no iterate the solver keeps, converged or not, is one a
        summary would count: positions and speeds at every step's end, accelerations (the
        joints', and a legged platform's legs', which depend on the state too) while each
        input acts, at the state it acts from."""
        n = self.nu
        ends = limit_violations(x[1:, :n], x[1:, n:], U, self.robot, tol)
        acting = limit_violations(x[:-1, :n], x[:-1, n:], U, self.robot, tol)
        accelerations = {"qdd", "actuator_acceleration"}
        return not any((acting if name in accelerations else ends)[name] for name in ends)

    def _stage_terms(self, x, U, jac, residual, weights, w):
        """Per stage, the Gauss-Newton Hessian Q_k (T, m, m) and gradient b_k (T, m) of the
        cost on v_k = (de_k, dx_k, du_k) (m = n + 18), and the output Jacobians J_k
        (T, 6, 18) on (dx_k, du_k). The tracked signal is P_k + G_k v_k with G_k =
        [C, D J_k]."""
        cfg, n = self.config, self.n
        _, _, C, D = self._model
        J = np.concatenate([jac.dy_dq, jac.dy_dqd, jac.dy_dqdd], axis=2)  # (T, 6, 18)
        tracked, _ = self.tracked(residual)
        G = np.concatenate([np.broadcast_to(C, (self.T, *C.shape)), D @ J], axis=2)
        WG = weights[None, :, None] * G
        Q = 2 * w * np.einsum("kai,kaj->kij", G, WG)
        washout, inputs = np.full(self.nu, cfg.washout_weight), np.full(self.nu, cfg.input_weight)
        diag = np.r_[np.zeros(n), washout, np.zeros(self.nu), inputs]
        Q = Q + 2 * w * np.diag(diag)[None]
        if cfg.curvature and n == 0:
            # Newton's stage Hessian, Gauss-Newton's plus the residual curvature on
            # (dx_k, du_k), made convex stage by stage: where Gauss-Newton misjudges the
            # cost's curvature its steps overshoot or creep, and one stage's overshoot
            # shortens the whole trajectory's step
            dcost_dy = 2 * w * weights * tracked
            Q = _positive_part(Q + self._residual_curvature(x, U, J, dcost_dy))
        b = 2 * w * np.einsum("kai,ka->ki", WG, tracked)
        b[:, n : n + self.nu] += 2 * w * cfg.washout_weight * x[:-1, : self.nu]
        b[:, n + 2 * self.nu :] += 2 * w * cfg.input_weight * U
        return Q, b, J

    def _residual_curvature(self, x, U, J, weighted) -> np.ndarray:
        """sum_a c_ka d^2 y_a / dv_k^2 per stage (T, 18, 18) for c (T, 6) = dcost/dy, the
        output Hessians by finite differences of the exact Jacobians
        (`output_curvature.finite_difference_hessians`), in chunks of stages."""
        out = np.empty((self.T, self.nx + self.nu, self.nx + self.nu))
        for lo in range(0, self.T, CURVATURE_CHUNK):
            hi = min(lo + CURVATURE_CHUNK, self.T)
            M = finite_difference_hessians(
                x[lo:hi, : self.nu], x[lo:hi, self.nu :], U[lo:hi], self.robot, J[lo:hi]
            )
            out[lo:hi] = residual_curvature(M, weighted[lo:hi])
        return out

    def _corrected_for_legs(self, x0, x, U, terms, tolerance: float, d):
        """A legged platform's QP step d with second-order corrections: where the full step
        takes a leg past its exact limit (the linearised legs bend away from the true ones),
        the QP is solved again with the legs' bounds moved by what the linearisation missed
        at that step (its remainder), up to SECOND_ORDER_CORRECTIONS times; the step that
        keeps every limit, else the last one (the line search shortens it)."""
        for _ in range(SECOND_ORDER_CORRECTIONS):
            U_try = U + d[0]
            x_try = self.states(x0, U_try)
            if self._feasible(x_try, U_try):
                return d
            remainder = self._legs.remainder(x, U, x_try, U_try, self._leg_rows)
            if not np.all(np.isfinite(remainder)):
                return d  # the full step leaves a crank's reach: the line search shortens it
            corrected = self._solve_qp(x, U, *terms, tolerance, leg_shift=remainder)
            if corrected is None:
                return d
            d = corrected
        return d

    def _solve_qp(self, x, U, Q, b, J, tolerance: float, leg_shift=None):
        """The QP step (dU (T, 6), dX (T, 12), dE (T, n)) of the stage-wise QP
        (`stagewise_qp`), or None where it did not converge. `leg_shift` (T, 3L): a legged
        platform's correction of its legs' linearised values (`_corrected_for_legs`); the
        legs' rows about (x, U) are computed once and kept for it."""
        r, n, T, ns = self.robot, self.n, self.T, self.ns
        m = ns + self.nu
        # Q and b are on (de, dx, du); the legs' dz (between dx and du) carry no cost
        cost = np.r_[np.arange(n + self.nx), np.arange(ns, m)]
        # the objective summed rather than averaged over the stages: its multipliers and
        # residuals then have the scale of one stage's
        H = np.zeros((T + 1, m, m))
        g = np.zeros((T + 1, m))
        H[:T, cost[:, None], cost[None, :]], g[:T, cost] = T * Q, T * b
        H[T, ns:, ns:] = np.eye(self.nu)  # stage T's input: nothing weighs it
        lower, upper = np.full((T + 1, m), -np.inf), np.full((T + 1, m), np.inf)
        lower[1:, n : n + self.nx] = np.r_[r.q_min, -r.qd_max] - x[1:]
        upper[1:, n : n + self.nx] = np.r_[r.q_max, r.qd_max] - x[1:]
        lower[:T, ns:] = -r.qdd_max - U
        upper[:T, ns:] = r.qdd_max - U
        F = self._F
        if n or self._legs is not None:
            F = np.broadcast_to(F, (T, *F.shape)).copy()
        if n:  # the model's dynamics, linearised: de_(k+1) = A de_k + B J_k (dx_k, du_k)
            BJ = self._model[1] @ J
            F[:, :n, n : n + self.nx], F[:, :n, ns:] = BJ[..., : self.nx], BJ[..., self.nx :]
        if self._legs is not None:  # the legs, linearised: dz_(k+1) = Fz_k (dx_k, du_k)
            if leg_shift is None:
                self._leg_rows = self._legs.rows(x, U)
            Fz, z = self._leg_rows
            if leg_shift is not None:
                z = z + leg_shift
            legs = slice(n + self.nx, ns)
            F[:, legs, n : n + self.nx], F[:, legs, ns:] = Fz[..., : self.nx], Fz[..., self.nx :]
            lower[1:, legs], upper[1:, legs] = self._legs.lower - z, self._legs.upper - z
        solution = solve_stagewise_qp(
            H,
            g,
            F,
            lower,
            upper,
            np.zeros(ns),
            tolerance=tolerance,
            max_iterations=self.config.qp_iterations,
        )
        # a QP stopped short of its tolerance still gives a step the line search can take
        # or refuse; one far from converged gives none
        if not solution.converged and not solution.residual <= QP_RESIDUAL_USABLE:
            return None
        w = solution.w
        return w[:T, ns:], w[1:, n : n + self.nx], w[1:, :n]

    def _stationarity(self, Q, b, dU, dX, dE) -> float:
        """|H d|_inf / max(1, |g|_inf) of the last QP's step: the nonlinear program's
        stationarity residual with that QP's multipliers."""
        start = np.zeros((1, self.n + self.nx))
        v = np.concatenate([np.vstack([start, np.concatenate([dE, dX], 1)[:-1]]), dU], axis=1)
        fixed = slice(0, self.n + self.nx)  # de_0 and dx_0: data, not variables
        Hd = np.einsum("kij,kj->ki", Q, v)
        Hd[0, fixed] = 0.0
        g = b.copy()
        g[0, fixed] = 0.0
        return float(np.max(np.abs(Hd)) / max(1.0, np.max(np.abs(g))))


def _modal(A, B, C, D):
    """The same filter in modal coordinates, each state scaled so that its input gain is 1:
    A diagonal where its eigenvalues are real and distinct (the vestibular models' poles
    are), which keeps the QP's rows of the model's dynamics well scaled (the controllable
    canonical form's coefficients span five decades, and Clarabel stalls on them). Where A
    has complex or repeated eigenvalues the filter is returned as it is."""
    values, vectors = np.linalg.eig(A)
    if np.any(np.abs(values.imag) > 0) or np.linalg.cond(vectors) > 1e8:
        return A, B, C, D
    vectors = vectors.real
    inverse = np.linalg.inv(vectors)
    B_modal = inverse @ B
    scale = np.abs(B_modal).max(axis=1)
    scale = np.where(scale > 0, scale, 1.0)
    # x = V S z: z_(k+1) = diag(values) z_k + S^-1 V^-1 B e_k; outputs C V S z + D e
    return (
        np.diag(values.real),
        B_modal / scale[:, None],
        C @ vectors * scale[None, :],
        D,
    )


def _positive_part(S: np.ndarray) -> np.ndarray:
    """Each stage's symmetric S_k (T, n, n) with its negative eigenvalues set to zero: the
    nearest positive semidefinite matrix (Frobenius). Projecting Newton's stage Hessian
    keeps the residual curvature's negative part wherever Gauss-Newton's curvature absorbs
    it (Gauss-Newton's Hessian is singular along some of each stage's directions, where
    any negative curvature would make the stage's model indefinite)."""
    S = 0.5 * (S + np.swapaxes(S, -1, -2))
    values, vectors = np.linalg.eigh(S)
    return (vectors * np.maximum(values, 0.0)[..., None, :]) @ np.swapaxes(vectors, -1, -2)
