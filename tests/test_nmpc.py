"""NMPC: optimality (KKT, an independent solver), grid, warm start, limits and fallbacks."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize

from mca_drake.cueing.nmpc import MotionCueingOcp, NmpcConfig, make_grid
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")

SMALL = dict(horizon_steps=40, nodes=6)
REF = np.array([0.15, -0.1, 0.2, 1.2, -0.8, 0.6])


@pytest.fixture(scope="module")
def small_ocp(robot):
    config = NmpcConfig(
        mode="converged", qp_solver="clarabel", step_tolerance=1e-9, max_iterations=100, **SMALL
    )
    return MotionCueingOcp(config, robot)


def x_start(robot):
    return np.r_[0.3 * robot.q_max * np.array([1, 0.5, -0.5, 1, 0.5, -1]), 0.2 * robot.qd_max]


def test_grid_is_non_uniform_and_covers_the_horizon():
    grid = make_grid(256, 20)
    assert grid.sum() == 256 and grid[0] == 1 and np.all(np.diff(grid) >= 0)
    assert grid[-1] > 10 * grid[0]
    np.testing.assert_array_equal(make_grid(8, 8), np.ones(8))


def test_gradient_is_exact(small_ocp, robot, rng):
    x0 = x_start(robot)
    U = rng.uniform(-0.5, 0.5, size=(small_ocp.N, 6)) * robot.qdd_max
    refs = np.broadcast_to(REF, (small_ocp.N, 6))
    _, g = small_ocp.gauss_newton_terms(x0, U, refs)
    eps = 1e-6
    numeric = np.zeros(U.size)
    for i in range(U.size):
        d = np.zeros(U.size)
        d[i] = eps
        plus = small_ocp.cost(x0, U + d.reshape(U.shape), refs)
        minus = small_ocp.cost(x0, U - d.reshape(U.shape), refs)
        numeric[i] = (plus - minus) / (2 * eps)
    np.testing.assert_allclose(g, numeric, atol=1e-7, rtol=1e-6)


def active_constraints(ocp, x0, U, tol=1e-5):
    """Outward normals of the active constraints at U (condensed rows and input bounds)."""
    lb, ub = ocp.constraint_bounds(x0)
    AU = ocp.A @ U.reshape(-1)
    normals = [ocp.A[i] for i in np.flatnonzero(AU >= ub - tol)]
    normals += [-ocp.A[i] for i in np.flatnonzero(AU <= lb + tol)]
    u, u_max = U.reshape(-1), np.tile(ocp.limits.qdd_max, ocp.N)
    eye = np.eye(u.size)
    normals += [eye[i] for i in np.flatnonzero(u >= u_max - tol)]
    normals += [-eye[i] for i in np.flatnonzero(u <= -u_max + tol)]
    return np.array(normals).reshape(-1, u.size)


@pytest.mark.parametrize("ref_scale", [1.0, 6.0])  # 6x pushes constraints active
def test_converged_solution_satisfies_kkt(small_ocp, robot, ref_scale):
    x0 = x_start(robot)
    result = small_ocp.solve(x0, ref_scale * REF)
    assert result.success
    U = result.U
    assert small_ocp.is_feasible(x0, U, tol=1e-6)
    refs = np.broadcast_to(ref_scale * REF, (small_ocp.N, 6))
    # stationarity: g + N_act' lambda = 0 with lambda >= 0 (non-negative least squares)
    residual, gradient = stationarity_residual(small_ocp, x0, U, refs)
    assert residual <= 1e-5 * max(1.0, gradient), (residual, gradient)
    if ref_scale > 1:  # the test exercised active constraints
        assert active_constraints(small_ocp, x0, U).shape[0] > 0


def stationarity_residual(ocp, x0, U, refs) -> tuple[float, float]:
    """(min over lambda >= 0 of |g + N_act' lambda|, |g|) at U: zero at a KKT point."""
    _, g = ocp.gauss_newton_terms(x0, U, refs)
    N_act = active_constraints(ocp, x0, U)
    residual = scipy.optimize.nnls(N_act.T, -g)[1] if N_act.size else np.linalg.norm(g)
    return residual, np.linalg.norm(g)


def test_marquardt_damping_reaches_a_kkt_point_on_a_3g_surge_step(robot):
    """From rest, a 3 g surge (scaled: 14.7 m/s^2) that the robot cannot render: undamped
    Gauss-Newton steps overshoot and are cut back by the line search for 50 iterations;
    with Marquardt's damping the solve stops at a KKT point (checked independently), no
    costlier."""
    x0, refs = np.zeros(12), np.array([0.0, 0.0, 0.0, 14.715, 0.0, 0.0])
    ocp = MotionCueingOcp(NmpcConfig(mode="converged"), robot)
    damped = ocp.solve(x0, refs)
    plain = MotionCueingOcp(NmpcConfig(mode="converged", marquardt_damping=False), robot).solve(
        x0, refs
    )
    assert damped.success and damped.stop == "kkt", damped.stop
    residual, gradient = stationarity_residual(ocp, x0, damped.U, np.tile(refs, (ocp.N, 1)))
    assert residual <= 1e-5 * max(1.0, gradient), (residual, gradient)
    # no costlier, to the cost's accuracy at the KKT tolerance (1e-7 of the gradient):
    # the two stop at nearby KKT points whose costs agree to 1e-9 relative
    assert damped.cost <= plain.cost + 1e-9 * abs(plain.cost)


@pytest.mark.parametrize("ref_scale", [1.0, 6.0])
def test_converged_agrees_with_scipy_slsqp(small_ocp, robot, ref_scale):
    """An independent solver (SciPy SLSQP) on the same nonlinear program reaches the same
    cost to 1e-4."""
    x0 = x_start(robot)
    refs = np.broadcast_to(ref_scale * REF, (small_ocp.N, 6))
    ours = small_ocp.solve(x0, refs)
    lb, ub = small_ocp.constraint_bounds(x0)
    finite_lb, finite_ub = np.isfinite(lb), np.isfinite(ub)
    A = small_ocp.A
    constraints = [
        {
            "type": "ineq",
            "fun": lambda u: ub[finite_ub] - A[finite_ub] @ u,
            "jac": lambda u: -A[finite_ub],
        },
        {
            "type": "ineq",
            "fun": lambda u: A[finite_lb] @ u - lb[finite_lb],
            "jac": lambda u: A[finite_lb],
        },
    ]
    u_max = np.tile(small_ocp.limits.qdd_max, small_ocp.N)

    def fun(u):
        return small_ocp.cost(x0, u.reshape(-1, 6), refs)

    def jac(u):
        return small_ocp.gauss_newton_terms(x0, u.reshape(-1, 6), refs)[1]

    theirs = scipy.optimize.minimize(
        fun,
        np.zeros(6 * small_ocp.N),
        jac=jac,
        method="SLSQP",
        bounds=list(zip(-u_max, u_max, strict=True)),
        constraints=constraints,
        options={"ftol": 1e-14, "maxiter": 1000},
    )
    assert theirs.success, theirs.message
    assert ours.cost == pytest.approx(theirs.fun, abs=1e-4)
    assert ours.cost <= theirs.fun + 1e-6


def test_shift_moves_the_plan_one_period(robot):
    ocp = MotionCueingOcp(NmpcConfig(horizon_steps=40, nodes=6), robot)
    U = np.arange(ocp.N)[:, None] * np.ones(6)
    shifted = ocp.shift(U)
    # u_new(interval k) = u(t_k + h): interval k of length 1 step becomes interval k + 1
    for k, start in enumerate(ocp.node_steps[:-1]):
        owner = np.searchsorted(ocp.node_steps[1:], start + 1, side="right")
        assert shifted[k, 0] == min(owner, ocp.N - 1)


def extreme_reference(duration_s=12.0):
    """Steps of 3 g in each force channel and spinning at 3 rad/s: far beyond the robot."""
    t = np.arange(0.0, duration_s + 1e-9, 0.01)
    y = np.zeros((t.size, 6))
    g3 = 3 * 9.81
    y[:, 3] = np.where((t // 2) % 2 == 0, g3, -g3)
    y[:, 4] = np.where((t // 3) % 2 == 0, -g3, g3)
    y[:, 5] = np.where(t > 4, g3, 0.0)
    y[:, 2] = 3.0
    y[:, 0] = np.where(t > 6, 3.0, -3.0)
    return Reference(y, 0.01, "extreme")


@pytest.mark.parametrize(
    ("mca", "duration"),
    # 6.5 s: past the last switch of the extreme reference (roll rate at 6 s)
    [("nmpc-rti", 6.5), pytest.param("nmpc-converged", 2.0, marks=pytest.mark.slow)],
)
def test_no_violation_with_references_beyond_the_robot(mca, duration):
    result = run_closed_loop(
        mca=mca, reference=extreme_reference(), duration_s=duration, progress=False, robot=KR500
    )
    assert result.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert np.all(np.isfinite(result.commands))
    # it does move towards the targets: the robot is not just parked
    assert np.max(np.abs(result.states[:, 6:])) > 0.1


def test_solver_failures_fall_back_and_stay_in_limits(monkeypatch, robot):
    from mca_drake.cueing import nmpc

    calls = {"n": 0}
    original = nmpc.MotionCueingOcp._qp_step

    def flaky(self, *args):
        # every way of solving the QP (the guess, the dual active-set method, Drake's
        # solver) fails for two seconds while the reference pushes
        calls["n"] += 1
        if 100 <= calls["n"] < 300:
            return None, None, False, "injected failure"
        return original(self, *args)

    monkeypatch.setattr(nmpc.MotionCueingOcp, "_qp_step", flaky)
    result = run_closed_loop(
        mca="nmpc-rti", reference=extreme_reference(), duration_s=4.0, progress=False, robot=KR500
    )
    assert result.summary["solver_failures"] >= 200
    assert result.summary["safety_interventions"] > 0  # the clamp caught the stale plans
    assert result.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert np.all(np.isfinite(result.commands))


def test_drakes_solver_takes_the_qps_the_dual_method_cannot_solve(monkeypatch):
    """With the dual active-set method failing (as round-off could make it), every QP whose
    guess is wrong goes to Drake's solver, and the loop still cues within the limits."""
    from mca_drake.cueing import nmpc, nmpc_sqp

    calls = {"drake": 0}
    original = nmpc.MotionCueingOcp._solve_qp

    def counted(self, U, x_bar):
        calls["drake"] += 1
        return original(self, U, x_bar)

    monkeypatch.setattr(nmpc_sqp, "solve_dual_active_set", lambda *args, **kwargs: None)
    monkeypatch.setattr(nmpc.MotionCueingOcp, "_solve_qp", counted)
    result = run_closed_loop(
        mca="nmpc-rti", reference=extreme_reference(), duration_s=2.0, progress=False, robot=KR500
    )
    assert calls["drake"] > 0
    assert result.summary["solver_failures"] == 0
    assert result.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    assert np.max(np.abs(result.states[:, 6:])) > 0.1


def test_braking_plan_stops_inside_limits(robot):
    ocp = MotionCueingOcp(NmpcConfig(), robot)
    x0 = np.r_[np.zeros(6), 0.9 * robot.qd_max]
    U = ocp.braking_plan(x0)
    _, qd = ocp.states(x0, U)
    np.testing.assert_allclose(qd[-1], 0.0, atol=1e-12)
    assert np.all(np.abs(U) <= robot.qdd_max + 1e-12)


def test_bad_config(robot):
    with pytest.raises(ValueError, match="unknown NMPC mode"):
        MotionCueingOcp(NmpcConfig(mode="fast"), robot)
    with pytest.raises(ValueError, match="unknown QP solver"):
        MotionCueingOcp(NmpcConfig(qp_solver="gurobi"), robot)


def test_an_overperforming_step_is_lengthened_only_within_the_bounds(small_ocp):
    """`_expanded_step`: the longest multiple of the step that the rows' bounds allow, capped
    at EXPANSION_MAX; None where the full step already reaches a bound it moves towards."""
    from mca_drake.cueing.nmpc_sqp import EXPANSION_MAX

    rng = np.random.default_rng(4)
    U = np.zeros((small_ocp.N, 6))
    step = 0.01 * rng.standard_normal((small_ocp.N, 6))
    Cd = small_ocp._C @ step.reshape(-1)
    CU = np.zeros_like(Cd)
    inf = np.full_like(Cd, np.inf)
    # room for 1.5 steps on the rows the step raises, 3 on those it lowers: 1.5
    hi, lo = np.where(Cd > 0, 1.5 * Cd, inf), np.where(Cd < 0, 3.0 * Cd, -inf)
    assert small_ocp._expanded_step(U, step, lo, hi, CU) == pytest.approx(1.5, abs=1e-6)
    # no bound near: the cap
    assert small_ocp._expanded_step(U, step, -inf, inf, CU) == EXPANSION_MAX
    # one row the full step lands on: no longer step
    k = int(np.argmax(Cd))
    hi[k] = Cd[k]
    assert small_ocp._expanded_step(U, step, lo, hi, CU) is None


def test_damping_restarts_from_the_last_that_was_in_use():
    """`_next_damping`: the first rejection starts mu at DAMPING_START; accepted full steps
    shrink it by DAMPING_GROWTH until it is dropped; a rejection after that restarts from
    DAMPING_GROWTH times the last mu in use, not from DAMPING_START."""
    from mca_drake.cueing.nmpc_sqp import (
        DAMPING_FLOOR,
        DAMPING_GROWTH,
        DAMPING_START,
        _next_damping,
    )

    mu, shed = _next_damping(0.0, False, 0.0)
    assert (mu, shed) == (DAMPING_START, 0.0)
    used = []
    while mu > 0.0:
        used.append(mu)
        mu, shed = _next_damping(mu, True, shed)
    assert used[-1] / DAMPING_GROWTH <= DAMPING_FLOOR < used[-2] / DAMPING_GROWTH
    assert shed == used[-1] and np.allclose(np.diff(np.log(used)), -np.log(DAMPING_GROWTH))
    mu, shed = _next_damping(0.0, False, shed)
    assert mu == pytest.approx(DAMPING_GROWTH * used[-1]) and mu < DAMPING_START
    # a rejection while damped grows it, at least to DAMPING_START
    assert _next_damping(mu, False, shed)[0] == max(DAMPING_GROWTH * mu, DAMPING_START)


def _surge_step() -> Reference:
    """A 1 m/s^2 surge step at 1.5 s, nothing else."""
    t = np.arange(301) * 0.01
    y = np.zeros((t.size, 6))
    y[t >= 1.5, 3] = 1.0
    return Reference(y, 0.01, "surge step")


def test_preview_lets_the_nmpc_anticipate_what_the_causal_one_cannot_know():
    """With a preview the NMPC reads the known future at its nodes and moves before a step;
    causal, it holds the present reference and stays still until the step comes."""
    reference = _surge_step()
    causal = run_closed_loop(mca=NmpcConfig(), reference=reference, progress=False, robot=KR500)
    preview = run_closed_loop(
        mca=NmpcConfig(preview_steps=256), reference=reference, progress=False, robot=KR500
    )
    before = causal.times < 1.5
    assert np.max(np.abs(causal.states[before])) < 1e-12
    assert np.max(np.abs(preview.states[before, 6:])) > 1e-3
    assert preview.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    # knowing the step, it renders it better; its name says it has a preview
    assert preview.summary["rmse"][3] < causal.summary["rmse"][3]
    assert preview.summary["mca"] == "nmpc-rti-preview256"


def test_the_preview_reaches_the_nodes_as_the_ocp_reads_it(robot):
    """The controller's first command from rest is the OCP's own solve for the reference
    samples at the grid's node times."""
    from pydrake.systems.analysis import Simulator

    from mca_drake.systems.nmpc import NmpcController

    config = NmpcConfig(preview_steps=200)
    controller = NmpcController(config, robot)
    context = controller.CreateDefaultContext()
    future = _surge_step().y[:200]  # the step comes 1.5 s ahead, inside the preview
    controller.GetInputPort("state").FixValue(context, np.zeros(12))
    controller.GetInputPort("reference").FixValue(context, future[0])
    controller.GetInputPort("reference_preview").FixValue(context, future.reshape(-1))
    simulator = Simulator(controller, context)  # the control step at t = 0, as in a diagram
    simulator.AdvanceTo(0.005)
    command = controller.GetOutputPort("joint_acceleration").Eval(simulator.get_context())
    ocp = controller.ocp
    rows = np.minimum(ocp.node_steps[:-1], 199)
    expected = ocp.solve(np.zeros(12), future[rows]).U[0]
    assert np.max(np.abs(expected)) > 1e-3  # the step ahead moves it already
    np.testing.assert_allclose(command, expected, atol=1e-9)


def test_preview_longer_than_the_horizon_and_live_preview_are_refused():
    with pytest.raises(ValueError, match="preview_steps"):
        NmpcConfig(preview_steps=300).validate()
    from mca_drake.app.scenarios import LiveScenario

    with pytest.raises(ValueError, match="no future"):
        LiveScenario(mca=NmpcConfig(preview_steps=10)).validate()
