"""The torch plant against the numpy plant, a step-by-step loop and autograd checks."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import random_joint_states
from hypothesis import given, settings
from hypothesis import strategies as st

from mca_drake.learning.torch_plant import TorchPlant
from mca_drake.platforms import kinematics


@pytest.fixture(scope="module")
def plant64(robot):
    return TorchPlant(robot, dtype=torch.float64)


def test_output_equals_numpy_in_float64(plant64, robot, rng):
    q, qd, qdd = random_joint_states(rng, robot, 500)
    x = torch.tensor(np.concatenate([q, qd], axis=1))
    y_torch = plant64.output(x, torch.tensor(qdd)).numpy()
    np.testing.assert_allclose(y_torch, kinematics.plant_output(q, qd, qdd, robot), atol=1e-10)
    np.testing.assert_allclose(
        plant64.head_pose(torch.tensor(q)).numpy(), kinematics.head_pose(q, robot), atol=1e-12
    )


def test_rollout_equals_exact_double_integrator_loop(plant64, robot, rng):
    """Closed-form cumulative-sum rollout equals stepping x+ = x + h qd + h^2/2 u one by one."""
    B, T, h = 3, 120, plant64.dt
    q, qd, _ = random_joint_states(rng, robot, B)
    U = rng.uniform(-robot.qdd_max, robot.qdd_max, size=(B, T, 6))
    X, Y = plant64(torch.tensor(np.concatenate([q, qd], 1)), torch.tensor(U))
    assert X.shape == (B, T + 1, 12) and Y.shape == (B, T, 6)
    x = np.concatenate([q, qd], 1)
    for t in range(T):
        np.testing.assert_allclose(X[:, t].numpy(), x, atol=1e-12)
        np.testing.assert_allclose(
            Y[:, t].numpy(), kinematics.plant_output(x[:, :6], x[:, 6:], U[:, t], robot), atol=1e-10
        )
        x = np.concatenate(
            [x[:, :6] + h * x[:, 6:] + 0.5 * h * h * U[:, t], x[:, 6:] + h * U[:, t]], 1
        )
        np.testing.assert_allclose(
            plant64.step(torch.tensor(X[:, t].numpy()), torch.tensor(U[:, t])).numpy(),
            x,
            atol=1e-12,
        )
    np.testing.assert_allclose(X[:, T].numpy(), x, atol=1e-12)


def test_constant_acceleration_closed_form(plant64):
    """u constant: q(T) = q0 + qd0 T + u T^2 / 2 exactly (zero-order hold is exact)."""
    T_steps, u = 256, torch.linspace(-0.5, 0.5, 6, dtype=torch.float64)
    x0 = torch.cat([torch.full((6,), 0.1), torch.full((6,), -0.2)]).double()[None]
    X = plant64.rollout_states(x0, u.expand(1, T_steps, 6))
    t = T_steps * plant64.dt
    np.testing.assert_allclose(
        X[0, -1, :6].numpy(), (0.1 - 0.2 * t + u * t * t / 2).numpy(), atol=1e-12
    )
    np.testing.assert_allclose(X[0, -1, 6:].numpy(), (-0.2 + u * t).numpy(), atol=1e-12)


def test_gradients_match_numpy_jacobians(plant64, robot, rng):
    q, qd, qdd = random_joint_states(rng, robot, 4)
    x = torch.tensor(np.concatenate([q, qd], 1), requires_grad=True)
    u = torch.tensor(qdd, requires_grad=True)
    jac = kinematics.plant_output_jacobians(q, qd, qdd, robot)
    for k in range(6):
        gx, gu = torch.autograd.grad(plant64.output(x, u)[:, k].sum(), (x, u))
        np.testing.assert_allclose(gx[:, :6].numpy(), jac.dy_dq[:, k], atol=1e-10)
        np.testing.assert_allclose(gx[:, 6:].numpy(), jac.dy_dqd[:, k], atol=1e-10)
        np.testing.assert_allclose(gu.numpy(), jac.dy_dqdd[:, k], atol=1e-10)


def test_rollout_gradcheck(robot):
    plant = TorchPlant(robot, dtype=torch.float64)
    gen = torch.Generator().manual_seed(0)
    x0 = (0.3 * torch.randn(2, 12, generator=gen, dtype=torch.float64)).requires_grad_()
    U = (0.5 * torch.randn(2, 5, 6, generator=gen, dtype=torch.float64)).requires_grad_()
    assert torch.autograd.gradcheck(lambda a, b: plant(a, b)[1], (x0, U))


def test_float32_is_close_to_float64(robot, rng):
    plant32 = TorchPlant(robot, dtype=torch.float32)
    q, qd, qdd = random_joint_states(rng, robot, 100)
    x = torch.tensor(np.concatenate([q, qd], 1), dtype=torch.float32)
    y = plant32.output(x, torch.tensor(qdd, dtype=torch.float32))
    assert y.dtype == torch.float32
    np.testing.assert_allclose(y.numpy(), kinematics.plant_output(q, qd, qdd, robot), atol=5e-5)


@settings(max_examples=25, deadline=None)
@given(batch=st.integers(1, 5), horizon=st.integers(1, 40))
def test_rollout_shapes(plant64, batch, horizon):
    X, Y = plant64(
        torch.zeros(batch, 12, dtype=torch.float64),
        torch.zeros(batch, horizon, 6, dtype=torch.float64),
    )
    assert X.shape == (batch, horizon + 1, 12)
    assert Y.shape == (batch, horizon, 6)
    # at rest in the neutral pose nothing is felt (y = 0)
    assert torch.allclose(Y, torch.zeros_like(Y), atol=1e-12)


@pytest.mark.parametrize(
    ("x0", "U", "match"),
    [
        (torch.zeros(2, 11), torch.zeros(2, 3, 6), r"x0 must have shape \(\.\.\., 12\)"),
        (torch.zeros(2, 12), torch.zeros(2, 3, 5), r"U must have shape \(\.\.\., 6\)"),
        (torch.zeros(2, 12), torch.zeros(3, 3, 6), r"U must have shape \(\*batch, T, 6\)"),
        (torch.full((2, 12), float("nan")), torch.zeros(2, 3, 6), "x0 has non-finite"),
        (np.zeros((2, 12)), torch.zeros(2, 3, 6), "must be a torch.Tensor"),
    ],
)
def test_bad_input_is_reported(plant64, x0, U, match):
    if isinstance(x0, torch.Tensor):
        x0 = x0.double()
    with pytest.raises(ValueError, match=match):
        plant64(x0, U.double())
