"""The legs' limits in the offline-optimal bound: their linearisation against finite
differences of the legs' exact motion, a short bound against SciPy's optimum of the same
nonlinear program, and a flight's bound on a hexapod converging inside every leg limit."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize

from mca_drake.cueing.optimal import OptimalConfig, OptimalCueing
from mca_drake.cueing.optimal_legs import BoundLegRows
from mca_drake.cueing.shooting import double_integrator_step
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.kinematics import plant_output
from mca_drake.platforms.usage import limit_violations

H = 0.01


@pytest.fixture(scope="module")
def hexapod():
    return load_platform("hexapod")


def _step(x, u, k):
    """The exact double-integrator step of one period (the oracle's own)."""
    q, qd = x[..., :k], x[..., k:]
    return np.concatenate([q + H * qd + 0.5 * H * H * u, qd + H * u], axis=-1)


def _z(platform, x, u):
    """(l, l') after the step and l'' while u acts at x, from the legs' exact motion."""
    k = platform.num_joints
    after = _step(x, u, k)
    lengths, speeds, _ = platform.actuator_motion(after[..., :k], after[..., k:], 0 * u)
    _, _, accelerations = platform.actuator_motion(x[..., :k], x[..., k:], u)
    return np.concatenate([lengths, speeds, accelerations], axis=-1)


@pytest.mark.parametrize("name", ["hexapod", "rig-3dof"])
def test_the_bounds_leg_rows_are_the_derivatives_of_the_legs_exact_motion(name):
    platform = load_platform(name)
    k = platform.num_joints
    rng = np.random.default_rng(2)
    U = rng.uniform(-0.5, 0.5, (5, k)) * platform.qdd_max
    x = np.zeros((6, 2 * k))
    x[0, :k] = rng.uniform(0.3 * platform.q_min, 0.3 * platform.q_max)
    x[0, k:] = rng.uniform(-0.3, 0.3, k) * platform.qd_max
    for i in range(5):
        x[i + 1] = _step(x[i], U[i], k)
    rows = BoundLegRows(platform, *double_integrator_step(H, k))
    Fz, z = rows.rows(x, U)
    np.testing.assert_allclose(z, _z(platform, x[:-1], U), atol=1e-12)
    step = 1e-6
    v = np.concatenate([x[:-1], U], axis=1)
    for j in range(3 * k):
        e = np.zeros(3 * k)
        e[j] = step
        ahead = _z(platform, (v + e)[:, : 2 * k], (v + e)[:, 2 * k :])
        behind = _z(platform, (v - e)[:, : 2 * k], (v - e)[:, 2 * k :])
        np.testing.assert_allclose(Fz[:, :, j], (ahead - behind) / (2 * step), atol=2e-6)


def test_a_short_hexapod_bound_is_the_optimum_scipy_finds_within_the_legs(hexapod):
    # A demand in every channel at once: the legs' accelerations, not the coordinates' box,
    # hold the optimum back. Oracle: SciPy's SLSQP on the same cost with the legs' exact
    # limits as nonlinear constraints.
    T, k = 8, 6
    rest = plant_output(np.zeros((T, k)), np.zeros((T, k)), np.zeros((T, k)), hexapod)
    reference = rest + np.array([0.6, 0.6, 0.6, 3.0, 3.0, 3.0])
    ocp = OptimalCueing(T, OptimalConfig(kkt_tolerance=1e-9), hexapod)
    ours = ocp.solve(reference)
    assert ours.converged
    g = hexapod.actuators

    def legs(u):
        U = u.reshape(T, k)
        x = ocp.states(np.zeros(2 * k), U)
        lengths, speeds, _ = hexapod.actuator_motion(x[1:, :k], x[1:, k:], 0 * U)
        _, _, accelerations = hexapod.actuator_motion(x[:-1, :k], x[:-1, k:], U)
        return np.concatenate(
            [
                (lengths - g.min_position).ravel(),
                (g.max_position - lengths).ravel(),
                (g.max_speed - np.abs(speeds)).ravel(),
                (g.max_acceleration - np.abs(accelerations)).ravel(),
            ]
        )

    u_max = np.tile(hexapod.qdd_max, T)
    theirs = scipy.optimize.minimize(
        lambda u: ocp.cost(np.zeros(2 * k), u.reshape(T, k), reference),
        np.zeros(k * T),
        method="SLSQP",
        bounds=list(zip(-u_max, u_max, strict=True)),
        constraints=[{"type": "ineq", "fun": legs}],
        options={"ftol": 1e-12, "maxiter": 3000},
    )
    assert theirs.success, theirs.message
    assert ours.cost == pytest.approx(theirs.fun, rel=1e-5)
    # the legs bind: some leg's acceleration is at its limit, less the QP's reserve
    assert np.min(legs(ours.U.ravel())) < 1e-4 * g.max_acceleration
    assert np.min(legs(ours.U.ravel())) >= -1e-9


@pytest.mark.slow
def test_a_flights_hexapod_bound_converges_inside_every_leg_limit(hexapod):
    from mca_drake.references.flights import FlightSpec, flight_reference
    from mca_drake.simulation.optimal_bound import run_optimal_bound

    reference = flight_reference(FlightSpec(vehicle="light", seed=700), 20.0)
    result = run_optimal_bound(reference=reference, robot=hexapod, progress=False)
    solver = result.summary["solver"]
    assert solver["converged"] and solver["cost"] <= min(solver["start_costs"].values())
    q, qd = result.states[:, :6], result.states[:, 6:]
    assert not any(limit_violations(q, qd, result.commands, hexapod).values())
