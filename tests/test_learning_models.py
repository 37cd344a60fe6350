"""Plant-model candidates: shapes, exactness against independent oracles, adjoint gradients."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from mca_drake.learning import make_output_model, make_state_model
from mca_drake.learning.ode_adjoint import odeint_step, rk4_step
from mca_drake.learning.output_models import OUTPUT_MODELS, output_from_pose_derivatives
from mca_drake.learning.state_models import STATE_MODELS
from mca_drake.platforms.kinematics import head_pose_derivatives, plant_output
from tests.conftest import random_joint_states

DT = 0.01


@settings(max_examples=15, deadline=None)
@given(
    name=st.sampled_from(sorted(STATE_MODELS)),
    batch=st.integers(1, 4),
    horizon=st.integers(1, 6),
)
def test_state_model_shapes(name, batch, horizon):
    torch.manual_seed(0)
    model = make_state_model(name)
    x0, U = torch.randn(batch, 12), torch.randn(batch, horizon, 6)
    X = model(x0, U)
    assert X.shape == (batch, horizon + 1, 12)
    assert torch.equal(X[:, 0], x0)
    assert torch.all(torch.isfinite(X))


@settings(max_examples=15, deadline=None)
@given(
    name=st.sampled_from(sorted(OUTPUT_MODELS)),
    batch=st.integers(1, 4),
    horizon=st.integers(1, 6),
)
def test_output_model_shapes(name, batch, horizon):
    torch.manual_seed(0)
    model = make_output_model(name)
    X, U, y_prev = (
        torch.randn(batch, horizon, 12),
        torch.randn(batch, horizon, 6),
        torch.randn(batch, 6),
    )
    Y = model(X, U, y_prev)
    assert Y.shape == (batch, horizon, 6)
    assert torch.all(torch.isfinite(Y))


def test_unknown_names_and_bad_shapes_are_clear_errors():
    with pytest.raises(ValueError, match="unknown state model 'rnn'; valid: nssm"):
        make_state_model("rnn")
    with pytest.raises(ValueError, match="unknown output model"):
        make_output_model("gru")
    with pytest.raises(ValueError, match=r"U must have shape \(B, T, 6\)"):
        make_state_model("node2")(torch.zeros(2, 12), torch.zeros(2, 5, 4))
    with pytest.raises(ValueError, match="x0 must have shape"):
        make_state_model("nssm")(torch.zeros(12), torch.zeros(1, 5, 6))
    with pytest.raises(ValueError, match="needs y_prev"):
        make_output_model("latent")(torch.zeros(1, 3, 12), torch.zeros(1, 3, 6))


def _forward_euler_numpy(x0, U, dt):
    """Independent oracle: forward Euler on dq/dt = qd, dqd/dt = u, one step at a time."""
    X = [x0]
    for t in range(U.shape[1]):
        q, qd = X[-1][:, :6], X[-1][:, 6:]
        X.append(np.concatenate([q + dt * qd, qd + dt * U[:, t]], axis=1))
    return np.stack(X, axis=1)


def test_node2_is_forward_euler_to_machine_precision(rng):
    x0, U = rng.normal(size=(5, 12)), rng.normal(size=(5, 300, 6))
    X = make_state_model("node2").double()(torch.tensor(x0), torch.tensor(U)).numpy()
    np.testing.assert_allclose(X, _forward_euler_numpy(x0, U, DT), rtol=0, atol=1e-12)


def test_exact_state_is_the_zero_order_hold_integrator(rng):
    """Against the closed form of constant acceleration over each period, stepped in numpy;
    and NODE 2 differs from it by exactly dt^2/2 times the sum of past inputs in q."""
    x0, U = rng.normal(size=(4, 12)), rng.normal(size=(4, 200, 6))
    X = [x0]
    for t in range(U.shape[1]):
        q, qd = X[-1][:, :6], X[-1][:, 6:]
        X.append(np.concatenate([q + DT * qd + 0.5 * DT**2 * U[:, t], qd + DT * U[:, t]], 1))
    oracle = np.stack(X, axis=1)
    exact = make_state_model("exact").double()(torch.tensor(x0), torch.tensor(U)).numpy()
    np.testing.assert_allclose(exact, oracle, rtol=0, atol=1e-12)
    node2 = make_state_model("node2").double()(torch.tensor(x0), torch.tensor(U)).numpy()
    drift = 0.5 * DT**2 * np.concatenate([np.zeros((4, 1, 6)), np.cumsum(U, axis=1)], axis=1)
    np.testing.assert_allclose(exact[..., :6] - node2[..., :6], drift, rtol=0, atol=1e-12)


def test_exact_output_equals_numpy_plant(rng, robot):
    q, qd, qdd = random_joint_states(rng, robot, 64)
    X = torch.tensor(np.concatenate([q, qd], 1).reshape(8, 8, 12))
    U = torch.tensor(qdd.reshape(8, 8, 6))
    model = make_output_model("exact", dtype=torch.float64)
    Y = model(X, U).numpy().reshape(64, 6)
    np.testing.assert_allclose(Y, plant_output(q, qd, qdd, robot), rtol=0, atol=1e-9)


def test_output_from_pose_derivatives_matches_plant_output(rng, robot):
    """The exact part of the mixed analytical model: y from (F, dF, ddF) of the numpy
    kinematics equals y from the recursive numpy plant output."""
    q, qd, qdd = random_joint_states(rng, robot, 100)
    F, dF, ddF = (torch.tensor(a) for a in head_pose_derivatives(q, qd, qdd, robot))
    y = output_from_pose_derivatives(F, dF, ddF).numpy()
    np.testing.assert_allclose(y, plant_output(q, qd, qdd, robot), rtol=0, atol=1e-9)


def test_mixed_model_uses_exact_forward_kinematics(rng, robot):
    q, qd, qdd = random_joint_states(rng, robot, 6)
    model = make_output_model("mixed", dtype=torch.float64)
    X = torch.tensor(np.concatenate([q, qd], 1))[None]
    F, dF, ddF = model.pose_derivatives(X, torch.tensor(qdd)[None])
    F_ref = head_pose_derivatives(q, qd, qdd, robot)[0]
    np.testing.assert_allclose(F[0].detach().numpy(), F_ref, rtol=0, atol=1e-12)
    assert torch.all(dF[..., 3, :] == 0) and torch.all(ddF[..., 3, :] == 0)


def test_latent_model_equals_naive_recursion():
    torch.manual_seed(1)
    model = make_output_model("latent").double()
    X, U, y = (
        torch.randn(3, 7, 12).double(),
        torch.randn(3, 7, 6).double(),
        torch.randn(3, 6).double(),
    )
    Y = model(X, U, y)
    expected = []
    for t in range(7):
        y = model.f4(model.f3(torch.cat([y, X[:, t], U[:, t]], dim=-1)))
        expected.append(y)
    torch.testing.assert_close(Y, torch.stack(expected, 1), rtol=0, atol=1e-12)


def test_adjoint_step_forward_and_gradients():
    """The adjoint gradients agree with backpropagation through the RK4 stages (the
    discrete gradient) to the integration error, and the forward pass is exactly RK4."""
    torch.manual_seed(2)
    model = make_state_model("node1").double()
    f = model.derivative
    x, u = torch.randn(4, 12).double(), torch.randn(4, 6).double()

    def grads(adjoint: bool):
        xr, ur = x.clone().requires_grad_(True), u.clone().requires_grad_(True)
        f.zero_grad()
        out = xr
        for _ in range(20):
            out = odeint_step(f, out, ur, DT, adjoint=adjoint)
        loss = (out**2).sum() + out[:, 0].sum()
        loss.backward()
        return out.detach(), xr.grad, ur.grad, [p.grad.clone() for p in f.parameters()]

    out_a, gx_a, gu_a, gp_a = grads(True)
    out_d, gx_d, gu_d, gp_d = grads(False)
    torch.testing.assert_close(out_a, out_d, rtol=0, atol=1e-14)
    expected = x
    with torch.no_grad():
        for _ in range(20):
            expected = rk4_step(f, expected, u, DT)
    torch.testing.assert_close(out_a, expected, rtol=0, atol=1e-14)
    for a, d in [(gx_a, gx_d), (gu_a, gu_d), *zip(gp_a, gp_d, strict=True)]:
        scale = d.abs().max()
        assert (a - d).abs().max() <= 1e-6 * scale, (a - d).abs().max() / scale


def test_adjoint_gradient_matches_finite_differences():
    torch.manual_seed(3)
    f = make_state_model("node1").double().derivative
    x, u = torch.randn(2, 12).double(), torch.randn(2, 6).double()
    p = next(f.parameters())
    out = odeint_step(f, x, u, DT)
    (out.sum()).backward()
    analytic = p.grad[0, 0].item()
    eps = 1e-6
    with torch.no_grad():
        p[0, 0] += eps
        plus = rk4_step(f, x, u, DT).sum().item()
        p[0, 0] -= 2 * eps
        minus = rk4_step(f, x, u, DT).sum().item()
        p[0, 0] += eps
    assert analytic == pytest.approx((plus - minus) / (2 * eps), rel=1e-6, abs=1e-9)
