"""The DPC loss's posture term (`posture_weight`): the pull of joints 2..n towards where the
dataset's MCA held them, carried with its windows through mirroring, slowing down and the
policy's own starts."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from dataset_helpers import segments_of
from dpc_batches import KR500, batch_rollout, objective_value, random_batch

import mca_drake.learning.dpc_training as dpc_training
from mca_drake.learning.dpc_training import (
    MCA_POSTURE,
    DpcTrainingConfig,
    dpc_loss_terms,
    mirror_some_windows,
    stretch_some_targets,
)
from mca_drake.learning.policy_network import PolicyNetwork
from mca_drake.learning.trainer import TrainConfig


def _distance(states: np.ndarray, postures: np.ndarray) -> float:
    """Mean over windows and steps of sum over joints 2..6 of (q - q_mca)^2 (numpy)."""
    return float(((states[:, :-1, 1:6] - postures[..., 1:6]) ** 2).sum(-1).mean())


def test_the_posture_term_is_the_squared_distance_beyond_the_first_joint():
    """The term is the numpy distance of the rollout's joints 2..6 from the MCA's at the
    same steps; the first joint's does not count; the objective adds it times its weight;
    a negative weight or NaN is refused."""
    batch = random_batch(7)
    batch[MCA_POSTURE] = 0.4 * torch.randn(8, 16, 6)
    policy = PolicyNetwork(KR500).eval()
    rollout = batch_rollout(policy, batch)
    expected = _distance(rollout.X.numpy(), batch[MCA_POSTURE].numpy())
    with torch.no_grad():
        term = dpc_loss_terms(rollout, batch["R"], policy, postures=batch[MCA_POSTURE])
        turned = batch[MCA_POSTURE].clone()
        turned[..., 0] += 1.0
        term_turned = dpc_loss_terms(rollout, batch["R"], policy, postures=turned)
    assert float(term["posture"]) == pytest.approx(expected, rel=1e-5)
    assert float(term_turned["posture"]) == pytest.approx(expected, rel=1e-5)
    assert "posture" not in dpc_loss_terms(rollout, batch["R"], policy)
    loss = {w: objective_value(policy, batch, posture_weight=w) for w in (0.0, 0.7)}
    assert loss[0.7] - loss[0.0] == pytest.approx(0.7 * expected, rel=1e-4)
    for bad in (-0.1, float("nan")):
        with pytest.raises(ValueError, match="posture_weight"):
            DpcTrainingConfig(posture_weight=bad).validate()
    del batch[MCA_POSTURE]  # a batch without the MCA's posture cannot price it
    with pytest.raises(ValueError, match="joint positions"):
        objective_value(policy, batch, posture_weight=0.7)


def test_mirrored_windows_mirror_the_mca_posture_with_them(robot):
    """The same draws as without postures (nothing else changes); a mirrored window's
    postures take the platform's joint signs, the others stay as they were."""
    x0, y0 = torch.rand(500, 12) + 0.5, torch.rand(500, 6) + 0.5
    targets, postures = torch.rand(500, 5, 6) + 0.5, torch.rand(500, 5, 6) + 0.5
    torch.manual_seed(3)
    plain = mirror_some_windows(x0, y0, targets, 0.4, robot)
    torch.manual_seed(3)
    *mirrored, q = mirror_some_windows(x0, y0, targets, 0.4, robot, postures=postures)
    for a, b in zip(plain, mirrored, strict=True):
        torch.testing.assert_close(a, b)
    flipped = plain[0][:, 0] < 0
    assert 0 < int(flipped.sum()) < 500
    signs = torch.tensor(robot.mirror_joint_signs, dtype=torch.float32)
    torch.testing.assert_close(q[flipped], postures[flipped] * signs)
    torch.testing.assert_close(q[~flipped], postures[~flipped])


def test_slowed_windows_slow_the_mca_posture_with_their_targets():
    """With every window slowed down, the term compares the rollout over the slowed targets
    with the MCA's posture slowed by the same factor: with postures equal to the targets,
    the slowed targets (the same draws) stand in for both."""
    batch = random_batch(8)
    batch[MCA_POSTURE] = 0.5 * batch["R"].clone()
    policy = PolicyNetwork(KR500).train()  # windows are slowed down in training only
    stretch = dict(time_stretch_fraction=1.0, time_stretch_max=3.0)
    torch.manual_seed(11)
    without = objective_value(policy, batch, **stretch)
    torch.manual_seed(11)
    with_term = objective_value(policy, batch, posture_weight=0.5, **stretch)
    torch.manual_seed(11)
    slowed = stretch_some_targets(batch["R"], 1.0, 3.0)
    assert not torch.allclose(slowed, batch["R"])
    rollout = batch_rollout(policy, batch, targets=slowed)
    expected = _distance(rollout.X.numpy(), 0.5 * slowed.numpy())
    assert with_term - without == pytest.approx(0.5 * expected, rel=1e-4)


def test_own_start_windows_keep_the_mca_posture(tmp_path, monkeypatch):
    """Training with a posture weight hands the trainer every window with the MCA's joint
    positions of its own steps, also the windows started from the policy's own states
    (whose states are the policy's)."""
    rng = np.random.default_rng(5)
    n = 12
    source = np.stack([np.zeros(n), 8 * np.arange(n), np.zeros(n)], 1).astype(np.int64)
    source[9:, 2] = 1  # validation
    states = np.concatenate((rng.uniform(-0.3, 0.3, (n, 8, 6)), np.zeros((n, 8, 6))), -1)
    data = segments_of({"R": 0.3 * rng.normal(size=(n, 8, 6)), "X": states}, source)
    path = data.save(tmp_path / "data.npz")
    seen = {}

    class CapturedError(Exception):
        """Stops training once the trainer holds its windows."""

    class Trainer:
        def __init__(self, *args, arrays, **kwargs):
            seen["arrays"] = arrays

        def fit(self, train, validation, **kwargs):
            seen["train"] = train
            raise CapturedError

    monkeypatch.setattr(dpc_training, "CurriculumTrainer", Trainer)
    config = DpcTrainingConfig(
        compile=False,
        window_segments=1,
        own_start_fraction=1.0,
        max_start_position_rad=float("inf"),
        posture_weight=0.3,
        train=TrainConfig(batch_size=4, max_epochs=1, horizons=(8,), device="cpu"),
    )
    with pytest.raises(CapturedError):
        dpc_training.train_policy(config, path, tmp_path / "run", progress=False)
    train = seen["train"]
    assert MCA_POSTURE in seen["arrays"]
    assert len(train) == 18  # nine windows, then the same nine from the policy's own states
    for row, (flight, step, _) in enumerate(train.source):
        mca = states[(source[:, 0] == flight) & (source[:, 1] == step)][0]
        np.testing.assert_allclose(train.arrays[MCA_POSTURE][row], mca[:, :6], rtol=1e-6)
    own_rows = train.arrays["X"][9:, 1:, :6]
    assert not np.allclose(own_rows, train.arrays[MCA_POSTURE][9:, 1:])
