"""Symmetries of the training windows: the KR500's independence of the base joint's angle
(checked against Drake's MultibodyPlant; its left-right symmetry is checked with every
platform's in tests/test_platforms.py), the mirroring and base turning of a share of each
batch, and the checks that refuse a plant without them."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from drake_oracle import drake_plant_output

from mca_drake.conventions import MIRROR_CHANNEL_SIGNS
from mca_drake.learning.dpc_training import (
    DpcTrainingConfig,
    RolloutPlant,
    check_base_yaw_invariance,
    check_mirror_symmetry,
    dpc_objective,
    mirror_signs,
    mirror_some_windows,
    shift_base_yaw,
    stretch_some_targets,
)
from mca_drake.learning.policy_network import PolicyNetwork
from mca_drake.platforms.files import load_platform

KR500 = load_platform("kr500")


def test_mirrored_windows_are_a_random_share_flipped_whole(robot):
    torch.manual_seed(0)
    x0, y0 = torch.rand(4000, 12) + 0.5, torch.rand(4000, 6) + 0.5  # all positive
    targets = torch.rand(4000, 7, 6) + 0.5
    x, y, r = mirror_some_windows(x0, y0, targets, 0.3, robot)
    flipped = x[:, 0] < 0
    assert 0.27 < flipped.float().mean() < 0.33
    joints = torch.tensor(robot.mirror_joint_signs, dtype=torch.float32)
    channels = torch.tensor(MIRROR_CHANNEL_SIGNS)
    torch.testing.assert_close(x[flipped], x0[flipped] * torch.cat((joints, joints)))
    torch.testing.assert_close(y[flipped], y0[flipped] * channels)
    torch.testing.assert_close(r[flipped], targets[flipped] * channels)
    for new, old in ((x, x0), (y, y0), (r, targets)):
        torch.testing.assert_close(new[~flipped], old[~flipped])


def test_the_symmetry_check_passes_the_kr500_and_refuses_a_lopsided_plant():
    plant = RolloutPlant(DpcTrainingConfig(compile=False), KR500)
    check_mirror_symmetry(plant)

    class Lopsided(torch.nn.Module):
        """The KR500 with a constant lateral force added (a cabin mounted off-centre)."""

        robot = plant.robot

        def output(self, x, u):
            return plant.output(x, u) + torch.tensor([0.0, 0, 0, 0, 0.3, 0])

        def step(self, x, u):
            return plant.step(x, u)

    with pytest.raises(ValueError, match="left-right symmetric"):
        check_mirror_symmetry(Lopsided())
    with pytest.raises(ValueError, match="mirror_fraction"):
        DpcTrainingConfig(mirror_fraction=1.5).validate()


def test_the_training_objective_flies_the_mirrored_window(robot):
    """With every window mirrored, the training loss is the loss of the same batch mirrored
    by hand (x0, y0 and targets alike) and flown without mirroring: the objective mirrors
    the whole window, not part of it. The policy is not symmetric, so the two batches differ."""
    torch.manual_seed(3)
    T = 16
    batch = {"X": 0.3 * torch.randn(8, T, 12), "Y": torch.randn(8, T, 6), "R": torch.randn(8, T, 6)}
    _, x_signs, y_signs = mirror_signs(robot)
    by_hand = {"X": batch["X"] * x_signs, "Y": batch["Y"] * y_signs, "R": batch["R"] * y_signs}
    policy = PolicyNetwork(KR500).train()
    loss = {}
    for fraction, data in ((1.0, batch), (0.0, by_hand), (0.0, batch)):
        config = DpcTrainingConfig(
            mirror_fraction=fraction,
            yaw_shift_fraction=0.0,
            time_stretch_fraction=0.0,
            compile=False,
        )
        with torch.no_grad():
            loss[fraction, id(data)] = float(
                dpc_objective(config, RolloutPlant(config, KR500))(policy, data)
            )
    mirrored = loss[1.0, id(batch)]
    np.testing.assert_allclose(mirrored, loss[0.0, id(by_hand)], rtol=1e-5)
    assert abs(mirrored - loss[0.0, id(batch)]) > 1e-3 * abs(mirrored)


def test_the_base_joint_angle_changes_no_cue_in_drake(robot, drake_plant, rng):
    """Drake's MultibodyPlant (the oracle) gives the same head outputs for any angle of joint
    1 (its axis is vertical, along gravity), so a window started at another base angle is as
    real as the one flown; the rollout plant passes the check, a plant that sees the angle
    does not."""
    context = drake_plant.CreateDefaultContext()
    for _ in range(30):
        q = rng.uniform(robot.q_min, robot.q_max) * 0.9
        qd, qdd = rng.uniform(-1, 1, 6), rng.uniform(-1, 1, 6)
        y = drake_plant_output(drake_plant, context, q, qd, qdd)
        q[0] = rng.uniform(robot.q_min[0], robot.q_max[0])
        np.testing.assert_allclose(
            drake_plant_output(drake_plant, context, q, qd, qdd), y, atol=1e-9
        )
    plant = RolloutPlant(DpcTrainingConfig(compile=False), KR500)
    check_base_yaw_invariance(plant)

    class Tilted(torch.nn.Module):
        """The KR500 on a base tilted about x: gravity then leaks into f_y with joint 1."""

        robot = KR500

        def output(self, x, u):
            return plant.output(x, u) + 0.2 * torch.sin(x[:, :1]) * torch.tensor(
                [0.0, 0, 0, 0, 1, 0]
            )

        def step(self, x, u):
            return plant.step(x, u)

    with pytest.raises(ValueError, match="joint 1"):
        check_base_yaw_invariance(Tilted())
    with pytest.raises(ValueError, match="yaw_shift_fraction"):
        DpcTrainingConfig(yaw_shift_fraction=-0.1).validate()


def test_base_turned_windows_are_a_random_share_within_the_range(robot):
    torch.manual_seed(1)
    x0 = torch.rand(4000, 12) * 1e-3  # near neutral: a turned row is told by its joint 1
    q_min, q_max = torch.tensor(robot.q_min), torch.tensor(robot.q_max)
    x = shift_base_yaw(x0, 0.4, q_min, q_max)
    turned = (x[:, 0] - x0[:, 0]).abs() > 0
    assert 0.37 < turned.float().mean() < 0.43
    torch.testing.assert_close(x[:, 1:], x0[:, 1:])
    torch.testing.assert_close(x[~turned], x0[~turned])
    angles = x[turned, 0].double().numpy()
    bound = 0.9 * robot.q_max[0]  # joint 1's range is symmetric
    assert angles.min() >= -bound - 1e-6 and angles.max() <= bound + 1e-6
    # spread over the range, not near neutral: a uniform sample's quartiles
    np.testing.assert_allclose(
        np.quantile(angles, [0.25, 0.75]), [-bound / 2, bound / 2], atol=0.15
    )


@pytest.mark.parametrize("option", ["yaw_shift_fraction", "time_stretch_fraction"])
def test_the_training_objective_flies_the_turned_or_stretched_window(option):
    """With every window turned (or slowed down), the training loss differs from the flown
    batch's (the policy sees the angle, the washout term counts it; the targets change); in
    evaluation mode nothing changes."""
    torch.manual_seed(4)
    T = 16
    batch = {"X": 0.3 * torch.randn(8, T, 12), "Y": torch.randn(8, T, 6), "R": torch.randn(8, T, 6)}
    policy = PolicyNetwork(KR500)
    loss = {}
    for fraction in (0.0, 1.0):
        off = dict(yaw_shift_fraction=0.0, mirror_fraction=0.0, time_stretch_fraction=0.0)
        config = DpcTrainingConfig(**{**off, option: fraction}, compile=False)
        objective = dpc_objective(config, RolloutPlant(config, KR500))
        with torch.no_grad():
            loss[fraction] = float(objective(policy.train(), batch))
            if fraction:
                np.testing.assert_allclose(
                    float(objective(policy.eval(), batch)), loss[0.0], rtol=1e-6
                )
    assert abs(loss[1.0] - loss[0.0]) > 1e-3 * abs(loss[0.0])


def test_stretched_windows_are_the_window_slowed_down():
    """Each stretched row is its window at t / k for one k in [1, k_max] (numpy's linear
    interpolation as the oracle), the others are untouched, and the share is the fraction."""
    torch.manual_seed(5)
    B, T = 3000, 50
    t = np.arange(T)
    phase = np.random.default_rng(0).uniform(0, 6, (B, 1, 1))
    targets = torch.as_tensor(np.sin(0.2 * t[None, :, None] + phase) * np.ones((1, 1, 6)))
    stretched = stretch_some_targets(targets, 0.4, 3.0)
    changed = (stretched - targets).abs().amax(dim=(1, 2)) > 1e-9
    assert 0.37 < changed.float().mean() < 0.43
    torch.testing.assert_close(stretched[~changed], targets[~changed])
    factors = []
    for b in np.flatnonzero(changed.numpy())[:40]:
        row, flown = stretched[b, :, 0].numpy(), targets[b, :, 0].numpy()
        # the factor from the first step (r(1 / k)), then the whole row against the oracle
        k = min(
            np.linspace(1, 3, 20001),
            key=lambda k: abs(np.interp(1 / k, t, flown) - row[1]),
        )
        np.testing.assert_allclose(row, np.interp(t / k, t, flown), atol=2e-3)
        factors.append(k)
    assert 1.0 <= min(factors) and max(factors) <= 3.0
    with pytest.raises(ValueError, match="time_stretch_max"):
        DpcTrainingConfig(time_stretch_max=0.5).validate()
    with pytest.raises(ValueError, match="time_stretch_fraction"):
        DpcTrainingConfig(time_stretch_fraction=2.0).validate()
