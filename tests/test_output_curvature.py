"""The converged NMPC's output Hessians (`mca_drake.cueing.output_curvature`).

Oracles: second differences of the plant output itself (not of the Jacobians the module
differences), a dense assembly written out from the condensing matrices, and the
minimal-change property of the Powell-symmetric-Broyden update on a quadratic.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mca_drake.cueing import NmpcConfig
from mca_drake.cueing.nmpc import MotionCueingOcp
from mca_drake.cueing.output_curvature import (
    NodeCondensing,
    finite_difference_hessians,
    node_jacobians,
    psb_update,
    structure,
)
from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform
from mca_drake.platforms.kinematics import plant_output, plant_output_jacobians


@pytest.fixture(scope="module")
def robot():
    return load_platform(DEFAULT_PLATFORM)


def random_nodes(n: int, seed: int):
    rng = np.random.default_rng(seed)
    return (
        0.4 * rng.standard_normal((n, 6)),
        rng.standard_normal((n, 6)),
        rng.standard_normal((n, 6)),
    )


def second_differences(robot, q, qd, u, h=1e-4) -> np.ndarray:
    """d^2 y / dv^2 (6, 18, 18) at one node by central second differences of y."""
    v0 = np.concatenate([q, qd, u])

    def y(v):
        return plant_output(v[:6], v[6:12], v[12:], robot)

    out = np.zeros((6, 18, 18))
    eye = np.eye(18) * h
    for i in range(18):
        for j in range(i, 18):
            value = (
                y(v0 + eye[i] + eye[j])
                - y(v0 + eye[i] - eye[j])
                - y(v0 - eye[i] + eye[j])
                + y(v0 - eye[i] - eye[j])
            ) / (4 * h * h)
            out[:, i, j] = out[:, j, i] = value
    return out


def test_finite_difference_hessians_match_second_differences_of_the_output(robot):
    q, qd, u = random_nodes(3, seed=1)
    jac = node_jacobians(plant_output_jacobians(q, qd, u, robot))
    M = finite_difference_hessians(q, qd, u, robot, jac)
    assert M.shape == (3, 6, 18, 18)
    for k in range(3):
        oracle = second_differences(robot, q[k], qd[k], u[k])
        scale = np.abs(oracle).max()
        assert np.abs(M[k] - oracle).max() <= 1e-4 * scale, np.abs(M[k] - oracle).max()
        # the blocks structure(6) declares zero are zero in the oracle too
        assert np.abs(oracle * (1 - structure(6))).max() <= 1e-6 * scale


def test_assembly_and_gradient_equal_the_dense_sums_over_nodes(robot):
    ocp = MotionCueingOcp(NmpcConfig(mode="converged", nodes=5, horizon_steps=12), robot)
    N = ocp.N
    condensing = NodeCondensing(ocp.Sq, ocp.Sqd, 6)
    rng = np.random.default_rng(2)
    B = rng.standard_normal((N, 18, 18))
    B = B + np.swapaxes(B, 1, 2)
    dense = np.zeros((6 * N, 6 * N))
    for k in range(N):
        G = np.zeros((18, 6 * N))
        G[:6] = np.kron(ocp.Sq[k], np.eye(6))
        G[6:12] = np.kron(ocp.Sqd[k], np.eye(6))
        G[12:, 6 * k : 6 * k + 6] = np.eye(6)
        dense += G.T @ B[k] @ G
    assert np.allclose(condensing.assemble(B), dense, atol=1e-12)
    node_gradients = rng.standard_normal((N, 18))
    G = np.zeros((N, 18, 6 * N))
    for k in range(N):
        G[k, :6] = np.kron(ocp.Sq[k], np.eye(6))
        G[k, 6:12] = np.kron(ocp.Sqd[k], np.eye(6))
        G[k, 12:, 6 * k : 6 * k + 6] = np.eye(6)
    expected_gradient = np.einsum("kia,ki->a", G, node_gradients)
    assert np.allclose(condensing.gradient(node_gradients), expected_gradient, atol=1e-12)
    step = rng.standard_normal((N, 6))
    q, qd = ocp.states(np.zeros(12), step)
    expected = np.concatenate([q[:N], qd[:N], step], axis=1)
    assert np.allclose(condensing.node_steps(step), expected, atol=1e-12)


def test_psb_update_is_exact_along_the_step_and_never_moves_away_from_the_hessian():
    """On a quadratic with Hessian T (of structure(6)'s pattern), the change of the gradient
    along s is T s; the update makes M s = T s where the step is free of masked directions
    and, being two projections onto sets that hold T, never increases |M - T|_F."""
    rng = np.random.default_rng(3)
    T = rng.standard_normal((2, 6, 18, 18))
    T = (T + np.swapaxes(T, -1, -2)) * structure(6)
    M = np.zeros_like(T)
    previous = np.linalg.norm(M - T)
    for _ in range(30):
        s = rng.standard_normal((2, 18))
        change = np.einsum("kaij,kj->kai", T, s)
        M = psb_update(M, s, change)
        error = np.linalg.norm(M - T)
        assert error <= previous + 1e-12
        previous = error
    assert previous < 0.5 * np.linalg.norm(T)
    # secant condition, on the outputs whose pattern is full in (q, qd) (the forces), for a
    # step in q and qd only (the mask then keeps it)
    M = np.zeros_like(T)
    s = np.concatenate([rng.standard_normal((2, 12)), np.zeros((2, 6))], axis=1)
    change = np.einsum("kaij,kj->kai", T, s)
    after = np.einsum("kaij,kj->kai", psb_update(M, s, change), s)
    assert np.allclose(after[:, 3:, :12], change[:, 3:, :12], atol=1e-10)


def test_tiny_steps_leave_the_estimates_alone():
    M = np.ones((1, 6, 18, 18)) * structure(6)
    s = np.full((1, 18), 1e-9)
    assert np.array_equal(psb_update(M, s, np.ones((1, 6, 18))), M)


# The solver's mechanisms are tested at the paper's weights, where a 3 g surge step is a
# large-residual problem: at the shipped weights (tuned) the solve ends after two iterations
# on the step tolerance, its plan at the input bounds, which would test nothing here.
def _paper_converged(robot) -> MotionCueingOcp:
    config = dataclasses.replace(NmpcConfig.paper(), mode="converged", nodes=6, horizon_steps=24)
    return MotionCueingOcp(config, robot)


def test_converged_solve_carries_its_hessians_and_refuses_ones_that_do_not_fit(robot):
    ocp = _paper_converged(robot)
    x0, refs = np.zeros(12), np.array([0.0, 0.0, 0.0, 14.715, 0.0, 0.0])
    first = ocp.solve(x0, refs)
    assert first.output_hessians.shape == (ocp.N, 6, 18, 18)
    shifted = ocp.shift_output_hessians(first.output_hessians)
    again = ocp.solve(x0, refs, U_guess=ocp.shift(first.U), output_hessians=shifted)
    assert again.stop == "kkt"
    bad = np.full((ocp.N, 6, 18, 18), np.nan)
    fallback = ocp.solve(x0, refs, output_hessians=bad)  # finite differences instead
    assert fallback.success and np.all(np.isfinite(fallback.output_hessians))
    assert ocp.solve(x0, refs, mode="rti").output_hessians is None


def test_a_curvature_model_that_overpromises_is_measured_afresh(robot, monkeypatch):
    """Carried Hessians of the wrong sign make the Newton model promise more than a full
    step gains: the solve re-measures them (finite differences at the new point, counted
    here) and still ends at the KKT point the good estimates reach. (Where the check pays,
    on 3 g steps with drifted estimates, is measured in benchmarks/bench_nmpc.py.)"""
    from mca_drake.cueing import nmpc_sqp as nmpc

    ocp = _paper_converged(robot)
    x0, refs = np.zeros(12), np.array([0.5, 0.3, 0.0, 14.715, 5.0, 9.81])
    good = ocp.solve(x0, refs)
    measured = []

    def counted(*args):
        measured.append(1)
        return finite_difference_hessians(*args)

    monkeypatch.setattr(nmpc, "finite_difference_hessians", counted)
    wrong = -0.5 * good.output_hessians
    fixed = ocp.solve(x0, refs, output_hessians=wrong)
    assert measured and fixed.stop == "kkt"
    assert fixed.cost == pytest.approx(good.cost, rel=1e-7)
    np.testing.assert_allclose(fixed.U, good.U, atol=1e-3)
    monkeypatch.setattr(nmpc, "CURVATURE_REFRESH_RATIO", -np.inf)  # never re-measure
    measured.clear()
    ocp.solve(x0, refs, output_hessians=wrong)
    assert not measured
