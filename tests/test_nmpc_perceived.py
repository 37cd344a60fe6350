"""The NMPC's perceived objective: its cost is the vestibular model of the tracking errors
(checked against the model run sample by sample), its gradient is exact, its optimum agrees
with an independent solver, the controller carries the model's state exactly, and the
fallback solver takes the QPs where the hot start fails."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize
from pydrake.systems.analysis import Simulator

from mca_drake.cueing.nmpc import MotionCueingOcp, NmpcConfig
from mca_drake.perception import PerceptionConfig, vestibular_filter
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.kinematics import plant_output
from mca_drake.references.reference import Reference
from mca_drake.simulation.builders import MakeAnalyticalClosedLoop
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")

SMALL = dict(horizon_steps=40, nodes=6)
REF = np.array([0.15, -0.1, 0.2, 1.2, -0.8, 0.6])


def _ocp(robot, model="telban-cardullo", **overrides) -> MotionCueingOcp:
    settings = dict(
        mode="converged",
        qp_solver="clarabel",
        step_tolerance=1e-9,
        max_iterations=100,
        objective="perceived",
        perception_model=model,
    )
    return MotionCueingOcp(NmpcConfig(**(settings | SMALL | overrides)), robot)


def _start(robot, rng, ocp):
    x0 = np.r_[0.3 * robot.q_max * np.array([1, 0.5, -0.5, 1, 0.5, -1]), 0.2 * robot.qd_max]
    U = rng.uniform(-0.3, 0.3, size=(ocp.N, 6)) * robot.qdd_max
    refs = REF * (1 + 0.3 * rng.standard_normal((ocp.N, 6)))
    eps0 = 0.1 * rng.standard_normal(ocp.perception_filter.num_states)
    return x0, U, refs, eps0


@pytest.mark.parametrize("model", ["telban-cardullo", "ormsby"])  # ormsby: D != 0
def test_cost_is_the_vestibular_model_of_the_errors(robot, rng, model):
    ocp = _ocp(robot, model)
    x0, U, refs, eps0 = _start(robot, rng, ocp)
    cfg = ocp.config
    # the oracle: the model at the control period, sample by sample, with each node's error
    # held over its interval, from eps0; the perceived error at the end of interval k
    q, qd = ocp.states(x0, U)
    errors = plant_output(q[:-1], qd[:-1], U, robot) - refs
    held = np.repeat(errors, ocp.interval_steps, axis=0)
    f = vestibular_filter(PerceptionConfig(model=model), cfg.time_step)
    states = [eps0]
    for e in held:
        states.append(f.A @ states[-1] + f.B @ e)
    ends = np.array([f.C @ states[m] for m in ocp.node_steps[1:]]) + errors @ f.D.T
    output = np.sum(ocp.weights[:, None] * np.asarray(cfg.output_weights) * ends**2)
    stage = cfg.input_weight * (U**2).sum(1) + cfg.washout_weight * (q[:-1] ** 2).sum(1)
    terminal = cfg.terminal_position_weight * (q[-1] ** 2).sum()
    terminal += cfg.terminal_velocity_weight * (qd[-1] ** 2).sum()
    expected = output + ocp.weights @ stage + terminal
    shifted = ocp.perceived_references(refs, eps0)
    assert ocp.cost(x0, U, shifted) == pytest.approx(expected, rel=1e-10)


def test_gradient_is_exact(robot, rng):
    ocp = _ocp(robot)
    x0, U, refs, eps0 = _start(robot, rng, ocp)
    refs = ocp.perceived_references(refs, eps0)
    _, g = ocp.gauss_newton_terms(x0, U, refs)
    numeric = np.zeros(U.size)
    for i in range(U.size):
        d = np.zeros(U.size)
        d[i] = 1e-6
        plus = ocp.cost(x0, U + d.reshape(U.shape), refs)
        minus = ocp.cost(x0, U - d.reshape(U.shape), refs)
        numeric[i] = (plus - minus) / 2e-6
    np.testing.assert_allclose(g, numeric, atol=1e-7, rtol=1e-6)


def test_converged_agrees_with_scipy_slsqp(robot, rng):
    ocp = _ocp(robot)
    x0, _, refs, eps0 = _start(robot, rng, ocp)
    ours = ocp.solve(x0, refs, perception_state=eps0)
    shifted = ocp.perceived_references(refs, eps0)
    lb, ub = ocp.constraint_bounds(x0)
    lo, hi = ocp.input_bounds(x0)
    A = ocp.A
    finite_lb, finite_ub = np.isfinite(lb), np.isfinite(ub)
    theirs = scipy.optimize.minimize(
        lambda u: ocp.cost(x0, u.reshape(-1, 6), shifted),
        np.zeros(A.shape[1]),
        jac=lambda u: ocp.gauss_newton_terms(x0, u.reshape(-1, 6), shifted)[1],
        method="SLSQP",
        bounds=list(zip(lo, hi, strict=True)),
        constraints=[
            {"type": "ineq", "fun": lambda u: ub[finite_ub] - A[finite_ub] @ u},
            {"type": "ineq", "fun": lambda u: A[finite_lb] @ u - lb[finite_lb]},
        ],
        options={"ftol": 1e-14, "maxiter": 1000},
    )
    assert theirs.success, theirs.message
    assert ours.success and ours.stop in ("kkt", "step", "no_descent")
    assert ours.cost == pytest.approx(theirs.fun, abs=1e-6 * max(1.0, abs(theirs.fun)))
    assert ours.cost <= theirs.fun + 1e-8


def _pulse() -> Reference:
    t = np.arange(301) * 0.01
    y = np.zeros((t.size, 6))
    y[:, 0] = 0.2 * np.sin(2 * np.pi * 0.5 * t)
    y[:, 3] = np.where((t > 0.5) & (t < 2.0), 2.0, 0.0)
    y[:, 5] = np.sin(2 * np.pi * 0.8 * t)
    return Reference(y, 0.01, "pulse")


def test_controller_carries_the_state_of_the_perceived_error(robot):
    config = NmpcConfig(objective="perceived")
    diagram, handles = MakeAnalyticalClosedLoop(_pulse(), config, robot)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(1.005)  # updates at t = 0, 0.01, ..., 1.0: 101 of them
    context = simulator.get_context()
    controller = handles["mca"]
    log = lambda name: handles[name].FindLog(context).data().T  # noqa: E731
    states, references = log("state_log")[:101], log("reference_log")[:101]
    commands = log("command_log")[1:101]  # u_0..u_99; u_100 is the controller's output now
    last = controller.GetOutputPort("joint_acceleration").Eval(
        controller.GetMyContextFromRoot(context)
    )
    commands = np.vstack([commands, last])
    outputs = plant_output(states[:, :6], states[:, 6:], commands, robot)
    f = vestibular_filter(PerceptionConfig(), 0.01)
    _, expected = f.run(outputs - references)
    got = controller.perception_state(controller.GetMyContextFromRoot(context))
    np.testing.assert_allclose(got, expected, atol=1e-12)
    assert np.linalg.norm(expected) > 1e-3  # the check has something to check


def test_drakes_solver_takes_the_perceived_qps_the_dual_method_cannot_solve(monkeypatch):
    from mca_drake.cueing import nmpc_qp, nmpc_sqp

    calls = {"drake": 0}
    original = nmpc_qp.CondensedQp.solve

    def counted(self, *args):
        calls["drake"] += 1
        return original(self, *args)

    config = NmpcConfig(objective="perceived")
    hot = run_closed_loop(mca=config, reference=_pulse(), progress=False, robot=KR500)
    monkeypatch.setattr(nmpc_sqp, "solve_dual_active_set", lambda *args, **kwargs: None)
    monkeypatch.setattr(nmpc_qp.CondensedQp, "solve", counted)
    result = run_closed_loop(mca=config, reference=_pulse(), progress=False, robot=KR500)
    assert calls["drake"] > 0
    assert result.summary["solver_failures"] == 0
    assert result.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    # the same QPs, solved by OSQP to its tolerance instead of exactly: the same cueing
    np.testing.assert_allclose(result.outputs, hot.outputs, atol=0.02)
    assert result.summary["perceived"]["pi"] == pytest.approx(
        hot.summary["perceived"]["pi"], abs=0.01
    )


def test_bad_objective_and_state_are_refused(robot):
    with pytest.raises(ValueError, match="unknown NMPC objective"):
        NmpcConfig(objective="felt").validate()
    with pytest.raises(ValueError, match="unknown vestibular model"):
        NmpcConfig(objective="perceived", perception_model="young").validate()
    ocp = _ocp(robot)
    with pytest.raises(ValueError, match="perception_state"):
        ocp.solve(np.zeros(12), REF, perception_state=np.zeros(3))
