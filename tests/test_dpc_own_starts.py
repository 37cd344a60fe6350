"""Training windows from the policy's own closed-loop states (`own_start_fraction`):
`own_closed_loop_states` flies each run of a flight's consecutive segments in one closed
loop, and `with_own_starts` adds a share of those windows to the training set."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from dataset_helpers import segments_of

from mca_drake.learning.dpc_training import (
    DpcTrainingConfig,
    RolloutPlant,
    closed_loop_rollout,
    own_closed_loop_states,
    train_policy,
    with_own_starts,
)
from mca_drake.learning.policy_network import PolicyNetwork
from mca_drake.learning.trainer import TrainConfig
from mca_drake.platforms.files import load_platform
from mca_drake.segments import SegmentDataset

KR500 = load_platform("kr500")

N_P = 8


def _flights() -> SegmentDataset:
    """Flight 7: three consecutive segments, then a gap, then one more; flight 9: two. Rows
    shuffled, so that alignment cannot come from the order. The NMPC's states are random
    poses (the policy's own will differ)."""
    rng = np.random.default_rng(0)
    rows = [(7, 0), (7, N_P), (7, 2 * N_P), (7, 5 * N_P), (9, 0), (9, N_P)]
    order = rng.permutation(len(rows))
    source = np.array([(rows[i][0], rows[i][1], 0) for i in order], dtype=np.int64)
    n = len(rows)
    arrays = {
        "R": rng.normal(0.0, 1.0, (n, N_P, 6)),
        "X": np.concatenate(
            (rng.uniform(-0.3, 0.3, (n, N_P, 6)), rng.uniform(-0.1, 0.1, (n, N_P, 6))), -1
        ),
        "Y": rng.normal(0.0, 1.0, (n, N_P, 6)),
    }
    return segments_of(arrays, source)


def _row(data: SegmentDataset, flight: int, step: int) -> int:
    return int(np.flatnonzero((data.source[:, 0] == flight) & (data.source[:, 1] == step))[0])


@pytest.fixture(scope="module")
def own():
    torch.manual_seed(2)
    policy = PolicyNetwork(KR500)
    plant = RolloutPlant(DpcTrainingConfig(compile=False), KR500)
    data = _flights()
    return policy, plant, data, own_closed_loop_states(policy, plant, data)


def _fly(policy, plant, x0, y0, targets):
    """The closed loop over `targets` (T, 6) alone, from x0 (12) and y0 (6)."""
    t = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)[None]  # noqa: E731
    with torch.no_grad():
        roll = closed_loop_rollout(policy, plant, t(x0), t(y0), t(targets))
    return roll.X[0, :-1].numpy(), roll.Y[0].numpy()


def test_each_run_starts_where_the_nmpc_started_it(own):
    _, _, data, states = own
    for flight, step in ((7, 0), (7, 5 * N_P), (9, 0)):  # first segments of the three runs
        row = _row(data, flight, step)
        np.testing.assert_array_equal(states["X"][row, 0], data.arrays["X"][row, 0])
        assert not np.allclose(states["X"][row, 1:], data.arrays["X"][row, 1:])


def test_a_run_is_one_closed_loop_across_its_segments(own):
    """The rollout is Markov in (state, last output): the loop flown over one segment's
    targets alone, from the own state at its start and the own output just before it,
    reproduces that segment's own states and outputs; the run's first segment, flown from
    the NMPC's state and output, reproduces the run's start."""
    policy, plant, data, states = own
    first = _row(data, 7, 0)
    X, Y = _fly(
        policy,
        plant,
        data.arrays["X"][first, 0],
        data.arrays["Y"][first, 0],
        data.arrays["R"][first],
    )
    np.testing.assert_allclose(states["X"][first], X, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(states["Y"][first], Y, rtol=1e-5, atol=1e-6)
    for before, step in ((0, N_P), (N_P, 2 * N_P)):
        row, previous = _row(data, 7, step), _row(data, 7, before)
        X, Y = _fly(
            policy, plant, states["X"][row, 0], states["Y"][previous, -1], data.arrays["R"][row]
        )
        np.testing.assert_allclose(states["X"][row], X, rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(states["Y"][row], Y, rtol=1e-5, atol=1e-5)


def test_a_shorter_run_is_flown_as_if_alone(own):
    """Flight 9's run (two segments) flies in a batch with a three-segment run: holding its
    last target beyond its end changes nothing in its own steps."""
    policy, plant, data, states = own
    rows = [_row(data, 9, 0), _row(data, 9, N_P)]
    X, Y = _fly(
        policy,
        plant,
        data.arrays["X"][rows[0], 0],
        data.arrays["Y"][rows[0], 0],
        data.arrays["R"][rows].reshape(-1, 6),
    )
    np.testing.assert_allclose(states["X"][rows].reshape(-1, 12), X, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(states["Y"][rows].reshape(-1, 6), Y, rtol=1e-5, atol=1e-6)


def test_own_windows_are_added_in_their_share_and_none_for_zero():
    rng = np.random.default_rng(1)

    def windows(value: float, n: int) -> SegmentDataset:
        arrays = {"X": np.full((n, 4, 12), value), "R": rng.normal(size=(n, 4, 6))}
        source = np.stack([np.arange(n), np.zeros(n), np.zeros(n)], 1).astype(np.int64)
        return segments_of(arrays, source)

    base, own_windows = windows(0.0, 10), windows(1.0, 20)
    joined = with_own_starts(base, own_windows, 0.25, seed=3)
    assert len(joined) == 15
    np.testing.assert_array_equal(joined.arrays["X"][:10], base.arrays["X"])
    assert (joined.arrays["X"][10:] == 1.0).all()
    added = joined.source[10:, 0]
    assert len(set(added)) == 5 and set(added) <= set(range(20))
    assert with_own_starts(base, own_windows, 0.0, seed=3) is base


def test_training_with_own_starts_runs_and_records_its_share(tmp_path):
    rng = np.random.default_rng(4)
    n = 20
    split = (np.arange(n) >= 14).astype(np.int64)
    source = np.stack([np.zeros(n), 16 * np.arange(n), split], 1).astype(np.int64)
    data = segments_of({"R": 0.3 * rng.normal(size=(n, 16, 6))}, source)
    path = data.save(tmp_path / "data.npz")
    config = DpcTrainingConfig(
        compile=False,
        window_segments=1,
        own_start_fraction=0.5,
        train=TrainConfig(batch_size=8, max_epochs=1, horizons=(16,), device="cpu"),
    )
    _, policy_path = train_policy(config, path, tmp_path / "run", progress=False)
    meta = json_meta(policy_path)
    assert meta["dpc_config"]["own_start_fraction"] == 0.5
    # the own closed loops count in the run's training time
    assert 0 < meta["own_states_wall_s"] < meta["training_wall_s"]


def json_meta(policy_path):
    from mca_drake.cueing.dpc import load_policy_arrays

    return load_policy_arrays(policy_path)[1]


@pytest.mark.parametrize("fraction", [-0.1, 1.5, float("nan")])
def test_a_bad_own_start_fraction_is_refused(fraction):
    with pytest.raises(ValueError, match="own_start_fraction"):
        DpcTrainingConfig(own_start_fraction=fraction).validate()
