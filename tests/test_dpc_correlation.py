"""The DPC loss's correlation term (`pooled_correlation`, `correlation_weight`)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from dpc_batches import KR500, batch_rollout, objective_value, random_batch

from mca_drake.learning.dpc_training import DpcTrainingConfig, dpc_loss_terms, pooled_correlation
from mca_drake.learning.policy_network import PolicyNetwork
from mca_drake.metrics import pearson_cc


def _windows(seed: int, shape=(5, 40, 6)) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    return (torch.randn(*shape, generator=g, dtype=torch.float64) for _ in range(2))


def test_pooled_correlation_is_pearsons_over_the_windows_each_centred():
    """Against the metrics' Pearson CC (numpy) of the windows, each centred on its own mean,
    joined end to end: the flight-level CC's formula over the batch."""
    outputs, targets = _windows(0)
    outputs = outputs + 0.8 * targets  # correlated, by a different amount per channel
    outputs[..., 2] *= 0.01
    centred = [(w - w.mean(axis=1, keepdims=True)) for w in (outputs.numpy(), targets.numpy())]
    joined = [c.reshape(-1, 6) for c in centred]
    np.testing.assert_allclose(
        pooled_correlation(outputs, targets).numpy(), pearson_cc(joined[1], joined[0]), atol=1e-9
    )


def test_a_scaled_copy_with_its_own_offsets_correlates_fully():
    """Closed form: outputs = s targets + a per-window offset score 1 per channel for s > 0
    and -1 for s < 0, whatever the scale (the PI's CC ignores it too)."""
    _, targets = _windows(1)
    offsets = torch.randn(5, 1, 6, dtype=torch.float64)
    for scale, expected in ((0.05, 1.0), (3.0, 1.0), (-0.5, -1.0)):
        cc = pooled_correlation(scale * targets + offsets, targets)
        np.testing.assert_allclose(cc.numpy(), expected, atol=1e-9)


def test_still_channels_score_as_the_pi_scores_them_and_keep_finite_gradients():
    """A target still in every window counts as rendered (1); an output still where its
    target moves scores 0, and its gradient is finite (the variance floor); elsewhere the
    gradient matches finite differences."""
    outputs, targets = _windows(2, shape=(3, 12, 6))
    targets[..., 1] = 0.7  # a still target channel
    outputs[..., 4] = 0.0  # a still output channel
    outputs.requires_grad_(True)
    cc = pooled_correlation(outputs, targets)
    assert cc[1].item() == 1.0 and cc[4].item() == 0.0
    cc.sum().backward()
    assert torch.isfinite(outputs.grad).all()
    moving = torch.randn(3, 12, 6, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda o: pooled_correlation(o, targets), (moving,))


def test_the_objective_adds_the_weighted_correlation_term():
    """With correlation_weight w the objective is the tuned one plus w sum_k (1 - CC_k) of
    the same rollout; 0 leaves it as it was (and computes no term); a negative weight or
    NaN is refused."""
    batch = random_batch(5)
    policy = PolicyNetwork(KR500).eval()
    loss = {w: objective_value(policy, batch, correlation_weight=w) for w in (0.0, 0.5)}
    rollout = batch_rollout(policy, batch)
    with torch.no_grad():
        terms = dpc_loss_terms(rollout, batch["R"], policy, correlation=True)
    assert "correlation" not in dpc_loss_terms(rollout, batch["R"], policy)
    expected = float((1.0 - pooled_correlation(rollout.Y, batch["R"])).sum())
    assert float(terms["correlation"]) == pytest.approx(expected)
    assert 0.0 < expected < 12.0
    assert loss[0.5] - loss[0.0] == pytest.approx(0.5 * expected, rel=1e-4)
    for bad in (-0.1, float("nan")):
        with pytest.raises(ValueError, match="correlation_weight"):
            DpcTrainingConfig(correlation_weight=bad).validate()


def test_the_correlation_term_weighs_each_channel_by_its_weight():
    """With correlation_channel_weights c the term is sum_k c_k (1 - CC_k) of the same
    rollout (Pearson's CC from numpy as the oracle); a zero weight drops its channel; six
    finite weights >= 0 are required."""
    batch = random_batch(6)
    policy = PolicyNetwork(KR500).eval()
    weights = (1.0, 0.5, 2.0, 1.0, 3.0, 0.0)
    loss = {
        name: objective_value(
            policy, batch, correlation_weight=0.5, correlation_channel_weights=channels
        )
        for name, channels in (("uniform", (1.0,) * 6), ("weighted", weights))
    }
    rollout = batch_rollout(policy, batch)
    outputs, targets = rollout.Y.numpy(), batch["R"].numpy()
    centred = lambda a: (a - a.mean(axis=1, keepdims=True)).reshape(-1, 6)  # noqa: E731
    cc = np.array(
        [np.corrcoef(centred(outputs)[:, k], centred(targets)[:, k])[0, 1] for k in range(6)]
    )
    misses = 1.0 - cc
    expected = 0.5 * (np.dot(weights, misses) - misses.sum())
    assert loss["weighted"] - loss["uniform"] == pytest.approx(expected, rel=1e-3, abs=1e-6)
    for bad in ((1.0,) * 5, (1.0,) * 5 + (-1.0,), (1.0,) * 5 + (float("nan"),)):
        with pytest.raises(ValueError, match="correlation_channel_weights"):
            DpcTrainingConfig(correlation_channel_weights=bad).validate()
