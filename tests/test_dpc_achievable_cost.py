"""Training windows weighted by what the dataset's own MCA achieved on them
(`achievable_cost_floor`): `achievable_cost_weights` against hand-computed costs, and the
objective's tracking term scaled window by window."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from dataset_helpers import segments_of
from loss_helpers import loss_weights_only

from mca_drake.learning.dpc_training import (
    RECORDED_ERRORS,
    DpcTrainingConfig,
    RolloutPlant,
    achievable_cost_weights,
    dpc_objective,
    recorded_squared_errors,
    train_policy,
)
from mca_drake.learning.policy_network import PolicyNetwork
from mca_drake.learning.trainer import TrainConfig
from mca_drake.platforms.files import load_platform
from mca_drake.segments import SegmentDataset

KR500 = load_platform("kr500")

N_P = 4


def _recorded() -> SegmentDataset:
    """Flight 3's two segments and flight 5's two, targets zero, the recorded outputs off by
    constants: (3, 0) exact; (3, 4) w_x off by 1 (cost c_0); (5, 0) f_y off by 2 (cost 4 c_4)
    and a_z by 5 (not counted); (5, 4) f_x off by 1 for half the steps (cost c_3 / 2)."""
    Y = np.zeros((4, N_P, 6))
    Y[1, :, 0] = 1.0
    Y[2, :, 4] = 2.0
    Y[2, :, 5] = 5.0
    Y[3, :2, 3] = 1.0
    source = [(3, 0, 0), (3, N_P, 0), (5, 0, 1), (5, N_P, 0)]
    return segments_of({"R": np.zeros((4, N_P, 6)), "Y": Y}, source)


def _with_errors(data: SegmentDataset) -> SegmentDataset:
    data.arrays[RECORDED_ERRORS] = recorded_squared_errors(data, "R")
    return data


def test_each_window_weighs_by_the_inverse_of_its_recorded_cost():
    data = _with_errors(_recorded())
    c = np.array([2.0, 1.0, 1.0, 3.0, 0.5, 7.0])
    floor = 0.25
    costs = np.array([0.0, 2.0, 4 * 0.5, 3.0 / 2])  # by the docstring of _recorded
    train = data.subset(np.array([0, 1, 3]))
    validation = data.subset(np.array([2]))
    parts = {"train": train, "validation": validation}
    achievable_cost_weights(parts, c, floor)
    inverse = 1.0 / (costs + floor)
    mean = inverse[[0, 1, 3]].mean()
    np.testing.assert_allclose(train.arrays["S"][:, 0, 0], inverse[[0, 1, 3]] / mean, rtol=1e-6)
    np.testing.assert_allclose(validation.arrays["S"][:, 0, 0], inverse[[2]] / mean, rtol=1e-6)
    # constant over each window's steps, one column that scales every channel alike
    assert train.arrays["S"].shape == (3, N_P, 1)
    assert np.ptp(train.arrays["S"], axis=1).max() == 0.0
    assert train.arrays["S"].mean() == pytest.approx(1.0)


def test_long_windows_average_their_segments_and_own_starts_keep_the_recorded_errors():
    data = _with_errors(_recorded())
    floor = 0.1
    # each flight as one window of its two segments, as `long_windows` joins them
    parts = {
        name: segments_of(
            {
                "R": np.zeros((1, 2 * N_P, 6)),
                RECORDED_ERRORS: data.arrays[RECORDED_ERRORS][rows].reshape(1, 2 * N_P, 5),
            },
            [(flight, 0, 0)],
        )
        for name, flight, rows in (("train", 3, [0, 1]), ("validation", 5, [2, 3]))
    }
    # the train window's outputs replaced by another closed loop's (an own-start window)
    parts["train"].arrays["Y"][:] = 9.0
    achievable_cost_weights(parts, None, floor)
    flight3, flight5 = (0.0 + 1.0) / 2, (4.0 + 0.5) / 2  # uniform channel weights
    expected = (1 / (flight5 + floor)) / (1 / (flight3 + floor))
    assert parts["train"].arrays["S"][0, 0, 0] == pytest.approx(1.0)
    assert parts["validation"].arrays["S"][0, 0, 0] == pytest.approx(expected, rel=1e-6)


def test_windows_without_recorded_errors_and_a_bad_floor_are_refused():
    data = _recorded()
    with pytest.raises(ValueError, match="recorded errors"):
        achievable_cost_weights({"train": data}, None, 0.1)
    _with_errors(data)
    for floor in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="floor"):
            achievable_cost_weights({"train": data}, None, floor)
    with pytest.raises(ValueError, match="achievable_cost_floor"):
        DpcTrainingConfig(achievable_cost_floor=-0.1).validate()


def test_the_weights_scale_each_windows_tracking_term():
    """With every other loss weight zero, the objective is the mean tracking error, each
    window multiplied by its S: S = 1 changes nothing, S = (3, 0) counts the first alone."""
    torch.manual_seed(0)
    config = DpcTrainingConfig(
        compile=False,
        **loss_weights_only(tracking_weight=1.0),
        mirror_fraction=0.0,
        yaw_shift_fraction=0.0,
        time_stretch_fraction=0.0,
    )
    policy = PolicyNetwork(KR500, hidden=8).eval()
    objective = dpc_objective(config, RolloutPlant(config, KR500))
    batch = {
        "R": torch.randn(2, 6, 6) * 0.3,
        "X": torch.zeros(2, 6, 12),
        "Y": torch.zeros(2, 6, 6),
    }
    plain = objective(policy, batch)
    ones = objective(policy, batch | {"S": torch.ones(2, 6, 1)})
    first = objective(
        policy, batch | {"S": torch.tensor([3.0, 0.0])[:, None, None].expand(2, 6, 1)}
    )
    alone = objective(policy, {k: v[:1] for k, v in batch.items()})
    assert ones.item() == pytest.approx(plain.item(), rel=1e-6)
    # the mean over two windows of 3 x the first window's error = 1.5 x its own mean
    assert first.item() == pytest.approx(1.5 * alone.item(), rel=1e-5)


def test_training_with_achievable_cost_weights_and_own_starts_records_its_floor(tmp_path):
    rng = np.random.default_rng(4)
    n = 12
    split = (np.arange(n) >= 9).astype(np.int64)
    source = np.stack([np.arange(n) // 3, 16 * (np.arange(n) % 3), split], 1)
    R = 0.3 * rng.normal(size=(n, 16, 6))
    data = segments_of({"R": R, "Y": R + 0.1 * rng.normal(size=R.shape)}, source)
    path = data.save(tmp_path / "data.npz")
    config = DpcTrainingConfig(
        compile=False,
        window_segments=1,
        achievable_cost_floor=0.01,
        own_start_fraction=0.5,  # own-start windows carry the recorded errors too
        train=TrainConfig(batch_size=4, max_epochs=1, horizons=(16,), device="cpu"),
    )
    _, policy_path = train_policy(config, path, tmp_path / "run", progress=False)
    from mca_drake.cueing.dpc import load_policy_arrays

    assert load_policy_arrays(policy_path)[1]["dpc_config"]["achievable_cost_floor"] == 0.01
