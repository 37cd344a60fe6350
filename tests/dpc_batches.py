"""Random training batches and the DPC objective flown on them, for the loss-term tests."""

from __future__ import annotations

import torch

from mca_drake.learning.dpc_training import (
    DpcTrainingConfig,
    RolloutPlant,
    closed_loop_rollout,
    dpc_objective,
)
from mca_drake.learning.policy_network import PolicyNetwork
from mca_drake.platforms.files import load_platform

KR500 = load_platform("kr500")
# The objective's tests fly each batch as it is (no mirrored, turned or stretched windows).
NO_AUGMENTATION = dict(mirror_fraction=0.0, yaw_shift_fraction=0.0, time_stretch_fraction=0.0)


def random_batch(seed: int, T: int = 16) -> dict[str, torch.Tensor]:
    """Eight random windows of T steps (torch's global generator seeded with `seed`, which
    the policy built next also draws from)."""
    torch.manual_seed(seed)
    return {"X": 0.3 * torch.randn(8, T, 12), "Y": torch.randn(8, T, 6), "R": torch.randn(8, T, 6)}


def objective_value(policy: PolicyNetwork, batch: dict, **settings) -> float:
    """The DPC objective of `batch` with these DpcTrainingConfig settings (no augmentation
    unless the settings ask for it)."""
    config = DpcTrainingConfig(**{**NO_AUGMENTATION, **settings}, compile=False)
    with torch.no_grad():
        return float(dpc_objective(config, RolloutPlant(config, KR500))(policy, batch))


def batch_rollout(policy: PolicyNetwork, batch: dict, targets: torch.Tensor | None = None):
    """The closed-loop rollout the objective flies on `batch` (over `targets` where given,
    else the batch's references)."""
    config = DpcTrainingConfig(**NO_AUGMENTATION, compile=False)
    targets = batch["R"] if targets is None else targets
    with torch.no_grad():
        return closed_loop_rollout(
            policy, RolloutPlant(config, KR500), batch["X"][:, 0], batch["Y"][:, 0], targets
        )
