"""The offline-optimal bound: it reaches the optimum an independent solver finds, holds the
limits, never costs more than the causal trajectory it starts from, and refuses bad input."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize

from mca_drake.cueing.optimal import OptimalConfig, OptimalCueing
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.simulation.closed_loop import run_closed_loop

KR500 = load_platform("kr500")


def _reference(T: int, seed: int = 0) -> np.ndarray:
    t = np.arange(T) * 0.01
    rng = np.random.default_rng(seed)
    return 0.8 * np.sin(np.outer(t, rng.uniform(1.0, 6.0, 6)) + rng.uniform(0, 3, 6))


def _scipy_optimum(ocp, reference, robot):
    """SciPy's SLSQP on the same objective over the inputs, within their limits (the short
    references here keep the positions and velocities far inside theirs)."""
    T = reference.shape[0]
    u_max = np.tile(robot.qdd_max, T)
    theirs = scipy.optimize.minimize(
        lambda u: ocp.cost(np.zeros(12), u.reshape(T, 6), reference),
        np.zeros(6 * T),
        method="SLSQP",
        bounds=list(zip(-u_max, u_max, strict=True)),
        options={"ftol": 1e-15, "maxiter": 3000},
    )
    assert theirs.success, theirs.message
    return theirs


def test_shooting_dynamics_rows_are_the_exact_steps():
    """A trajectory of the exact zero-order-hold step satisfies every row of the sparse
    dynamics, block 0's right-hand side carrying x_0."""
    from mca_drake.cueing.shooting import double_integrator_step, shooting_dynamics

    rng = np.random.default_rng(1)
    durations = np.array([0.01, 0.02, 0.05, 0.1])
    x = [rng.normal(size=12)]
    U = rng.normal(size=(4, 6))
    for T, u in zip(durations, U, strict=True):
        Phi, Gamma = double_integrator_step(T, 6)
        x.append(Phi @ x[-1] + Gamma @ u)
        q, qd = x[-2][:6], x[-2][6:]
        np.testing.assert_allclose(x[-1][:6], q + T * qd + 0.5 * T * T * u)
    A, Phis = shooting_dynamics(durations, 6)
    z = np.concatenate([U.reshape(-1), np.concatenate(x[1:])])
    rhs = np.zeros(48)
    rhs[:12] = Phis[0] @ x[0]
    np.testing.assert_allclose(A @ z, rhs, atol=1e-12)


def _rest_output(robot, T: int) -> np.ndarray:
    """The plant's output (T, 6) with the robot at rest at home (gravity in the specific
    force)."""
    from mca_drake.platforms.kinematics import plant_output

    zeros = np.zeros((T, 6))
    return plant_output(zeros, zeros, zeros, robot)


def test_a_reference_the_robot_renders_at_rest_is_met_by_not_moving(robot):
    """Closed form: where the reference is what the robot at rest outputs, not moving costs
    nothing, and every other trajectory costs more; from a moving start the bound returns
    to rest."""
    T = 40
    reference = _rest_output(robot, T)
    ocp = OptimalCueing(T, OptimalConfig(kkt_tolerance=1e-9, max_iterations=30), robot)
    start = 0.05 * robot.qdd_max * np.sign(np.sin(np.arange(T) / 4.0))[:, None]
    assert ocp.cost(np.zeros(12), start, reference) > 1e-6
    ours = ocp.solve(reference, U_start=start)
    assert ours.cost <= 1e-10
    np.testing.assert_allclose(ours.U, 0.0, atol=1e-4)


def _short_reference(kind: str, T: int, robot) -> np.ndarray:
    """Short references whose optimum SciPy finds by brute force: sines on every channel,
    one channel alone, a constant specific force, and a step in surge."""
    if kind == "sines":
        return _reference(T)
    rest = _rest_output(robot, T)
    if kind == "single channel":  # a roll rate alone
        return rest + np.outer(np.sin(np.arange(T) * 0.5), [0.4, 0, 0, 0, 0, 0])
    if kind == "constant specific force":
        return rest + np.array([0, 0, 0, 1.5, 0, 0])
    steps = np.zeros((T, 6))
    steps[T // 2 :, 3] = 2.0
    return rest + steps


@pytest.mark.parametrize("kind", ["sines", "single channel", "constant specific force", "step"])
def test_a_short_bound_is_the_optimum_scipy_finds(kind, robot):
    T = 6
    reference = _short_reference(kind, T, robot)
    ocp = OptimalCueing(T, OptimalConfig(kkt_tolerance=1e-9), robot)
    ours = ocp.solve(reference)
    theirs = _scipy_optimum(ocp, reference, robot)
    assert ours.converged and ours.kkt_residual <= 1e-9
    assert ours.cost == pytest.approx(theirs.fun, rel=1e-6)


def test_the_bound_holds_the_limits_and_improves_on_its_causal_start(robot):
    T = 300
    y = _reference(T, seed=3) * [1, 1, 1, 4, 4, 4]  # beyond what the robot can render
    reference = Reference(y, 0.01, "sines")
    causal = run_closed_loop(mca="nmpc-rti", reference=reference, progress=False, robot=KR500)
    ocp = OptimalCueing(T, OptimalConfig(max_iterations=15), robot)
    start = causal.commands[:T]
    start_cost = ocp.cost(np.zeros(12), start, y)
    bound = ocp.solve(y, U_start=start)
    assert bound.cost <= start_cost
    assert all(b <= a for a, b in zip(bound.costs, bound.costs[1:], strict=False))
    q, qd = bound.states[:, :6], bound.states[:, 6:]
    assert np.all(q <= robot.q_max + 1e-9) and np.all(q >= robot.q_min - 1e-9)
    assert np.all(np.abs(qd) <= robot.qd_max + 1e-9)
    assert np.all(np.abs(bound.U) <= robot.qdd_max + 1e-9)


def test_the_bound_stopped_at_any_iteration_holds_the_limits_as_summaries_count_them(robot):
    """The solver keeps an iterate only if a run summary would count no violation in it
    (`limit_violations`, each limit's own half-range as the scale): after 1, 2 or 4
    iterations, unconverged, nothing is counted; and a start 0.8e-9 rad/s^2 beyond joint
    4's acceleration limit (0.564 rad/s^2: within 1e-9 absolute, beyond 1e-9 of its
    half-range) is no feasible start."""
    from mca_drake.platforms.usage import limit_violations

    T = 200
    y = _reference(T, seed=5) * [1, 1, 1, 4, 4, 4]  # beyond what the robot can render
    for iterations in (1, 2, 4):
        ocp = OptimalCueing(T, OptimalConfig(max_iterations=iterations), robot)
        bound = ocp.solve(y)
        assert not bound.converged
        q, qd = bound.states[:-1, :6], bound.states[:-1, 6:]
        assert limit_violations(q, qd, bound.U, robot) == {"q": 0, "qd": 0, "qdd": 0}
    start = np.zeros((T, 6))
    start[0, 3] = robot.qdd_max[3] + 0.8e-9
    assert robot.qdd_max[3] < 0.6
    assert limit_violations(np.zeros((T, 6)), np.zeros((T, 6)), start, robot)["qdd"] == 1
    with pytest.raises(ValueError, match="U_start leaves the robot's limits"):
        OptimalCueing(T, OptimalConfig(max_iterations=1), robot).solve(y, U_start=start)


def test_bad_input_is_refused(robot):
    ocp = OptimalCueing(5, None, robot)
    with pytest.raises(ValueError, match="reference must have shape"):
        ocp.solve(np.zeros((4, 6)))
    with pytest.raises(ValueError, match="non-finite"):
        ocp.solve(np.full((5, 6), np.nan))
    with pytest.raises(ValueError, match="U_start leaves the robot's limits"):
        ocp.solve(np.zeros((5, 6)), U_start=np.full((5, 6), 1e3))
    with pytest.raises(ValueError, match="output_weights"):
        OptimalConfig(output_weights=[1.0] * 5).validate()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_bound_costs_no_more_than_any_causal_mca_on_a_flight(seed, robot):
    """Over several flights: the bound, started from the cheapest of the causal MCAs'
    closed-loop trajectories, tracks at a cost no causal MCA beats, within every limit; its
    summary is a closed-loop summary with `mca: optimal` and the solver's figures."""
    from mca_drake.cueing.optimal import OptimalCueing
    from mca_drake.simulation.optimal_bound import run_optimal_bound

    y = _reference(151, seed) * [0.3, 0.3, 0.3, 2.0, 2.0, 2.0]
    reference = Reference(y, 0.01, f"sines {seed}")
    mcas = ("dpc", "nmpc-rti", "washout")
    result = run_optimal_bound(
        reference=reference,
        config=OptimalConfig(max_iterations=10),
        starts=mcas,
        progress=False,
        robot=KR500,
    )
    s = result.summary
    assert s["mca"] == "optimal" and s["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    ocp = OptimalCueing(y.shape[0], None, robot)
    for mca in mcas:
        causal = run_closed_loop(mca=mca, reference=reference, progress=False, robot=KR500)
        causal_cost = ocp.cost(np.zeros(12), causal.commands[: y.shape[0]], y)
        assert s["solver"]["cost"] <= causal_cost + 1e-12, mca
        assert s["solver"]["start_costs"][mca] == pytest.approx(causal_cost)
    # the summary's outputs are the plant's for the bound's inputs: its cost recomputed
    assert ocp.cost(np.zeros(12), result.commands, y) == pytest.approx(s["solver"]["cost"])
    assert s["pi"] < s["pi_zero_motion"] and "perceived" in s


def test_the_perceived_bound_weighs_what_the_occupant_perceives(robot):
    """objective "perceived": the cost is the vestibular model's outputs of y against those
    of r (computed here by `perceive` on each signal apart), and the bound reaches the
    optimum an independent solver finds on it."""
    from mca_drake.perception import PerceptionConfig, perceive

    T = 8
    reference = _reference(T, seed=5)
    config = OptimalConfig(objective="perceived", kkt_tolerance=1e-9)
    ocp = OptimalCueing(T, config, robot)
    U = np.random.default_rng(2).uniform(-0.3, 0.3, (T, 6)) * robot.qdd_max
    x = ocp.states(np.zeros(12), U)
    from mca_drake.platforms.kinematics import plant_output

    y = plant_output(x[:-1, :6], x[:-1, 6:], U, robot)
    model = PerceptionConfig(model=config.perception_model)
    perceived_error = perceive(y, model) - perceive(reference, model)
    expected = np.mean(
        perceived_error**2 @ np.asarray(config.output_weights)
        + config.input_weight * (U**2).sum(1)
        + config.washout_weight * (x[:-1, :6] ** 2).sum(1)
    )
    assert ocp.cost(np.zeros(12), U, reference) == pytest.approx(expected, rel=1e-12)
    ours = ocp.solve(reference)
    theirs = _scipy_optimum(ocp, reference, robot)
    assert ours.converged
    assert ours.cost == pytest.approx(theirs.fun, rel=1e-6)
    assert ours.cost <= theirs.fun * (1 + 1e-9)


def test_the_rail_bound_is_at_most_the_kr500s(robot):
    """The rail's motions are a superset of the KR500's: from the KR500's bound with the rail
    still (the same cost, its outputs equal), the rail's bound descends to at most that cost,
    within the rail's limits, and uses the rail."""
    rail = load_platform("kr500-rail")
    reference = _reference(120, seed=3)
    kr500 = OptimalCueing(120, OptimalConfig(max_iterations=30), robot).solve(reference)
    start = np.hstack([np.zeros((120, 1)), kr500.U])
    ocp = OptimalCueing(120, OptimalConfig(max_iterations=30), rail)
    assert ocp.cost(np.zeros(14), start, reference) == pytest.approx(kr500.cost, rel=1e-9)
    on_rail = ocp.solve(reference, U_start=start)
    assert on_rail.cost <= kr500.cost
    assert ocp.within_limits(np.zeros(14), on_rail.U)
    assert np.abs(on_rail.U[:, 0]).max() > 0.0
