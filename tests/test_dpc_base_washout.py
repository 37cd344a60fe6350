"""The DPC loss's washout of the base joint alone (`base_washout_weight`)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from dpc_batches import KR500, batch_rollout, objective_value

from mca_drake.learning.dpc_training import DpcTrainingConfig
from mca_drake.learning.policy_network import PolicyNetwork


def test_the_objective_adds_the_base_joints_squared_angle():
    """With base_washout_weight w the objective is the default one plus w times the mean of
    q_1^2 over the rollouts' steps (computed here in numpy from the same rollout), so that
    only the base joint is pulled home harder."""
    torch.manual_seed(3)
    T = 16
    x = torch.zeros(8, T, 12)
    x[:, :, :6] = 0.4 * torch.randn(8, 1, 6)  # starts away from neutral, base joint too
    batch = {"X": x, "Y": torch.randn(8, T, 6), "R": torch.randn(8, T, 6)}
    policy = PolicyNetwork(KR500).eval()
    loss = {w: objective_value(policy, batch, base_washout_weight=w) for w in (0.0, 2.0)}
    rollout = batch_rollout(policy, batch)
    q1 = rollout.X[:, :-1, 0].numpy().astype(float)  # the states the steps act from
    expected = float(np.mean(q1**2))
    assert expected > 1e-3
    assert loss[2.0] - loss[0.0] == pytest.approx(2.0 * expected, rel=1e-4)


@pytest.mark.parametrize("bad", [-0.5, float("nan"), float("inf")])
def test_a_negative_or_non_finite_base_washout_weight_is_refused(bad):
    with pytest.raises(ValueError, match="base_washout_weight"):
        DpcTrainingConfig(base_washout_weight=bad).validate()
