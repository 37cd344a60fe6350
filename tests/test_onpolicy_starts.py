"""On-policy starts: where each segment lies in its flight, the policy's own flights, and the
share of each training batch that starts from them (`mca_drake.learning.onpolicy`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from mca_drake.cueing.dpc import load_policy_arrays
from mca_drake.learning.dpc import (
    DpcTrainingConfig,
    RolloutPlant,
    closed_loop_rollout,
    dpc_objective,
    rollout_cell,
    train_policy,
)
from mca_drake.learning.onpolicy import (
    FlightRuns,
    FlightStarts,
    locate_flight_runs,
    start_some_on_policy,
)
from mca_drake.learning.policy import PolicyNetwork, load_policy_network
from mca_drake.learning.trainer import TrainConfig
from mca_drake.segments import SOURCE_COLUMNS, SegmentDataset


def _flights(rows, n_p, rng, split=None):
    """A dataset of segments (flight seed, start step) whose reference R encodes the flight
    and the time step (R = 1000 flight + step in every channel), with random X and Y."""
    steps = np.array([s for _, s in rows])[:, None] + np.arange(n_p)[None, :]
    flights = np.array([f for f, _ in rows])[:, None]
    R = np.repeat((1000 * flights + steps)[..., None], 6, axis=2).astype(np.float32)
    J = len(rows)
    arrays = {
        "R": R,
        "X": 0.1 * rng.standard_normal((J, n_p, 12)).astype(np.float32),
        "Y": rng.standard_normal((J, n_p, 6)).astype(np.float32),
        "U": np.zeros((J, n_p, 6), np.float32),
        **{k: np.zeros((J, n_p, 4, 4), np.float32) for k in ("F", "dF", "ddF")},
    }
    split = np.zeros(J, np.int64) if split is None else split
    source = np.array([(f, s, p) for (f, s), p in zip(rows, split, strict=True)])
    meta = {"source_columns": list(SOURCE_COLUMNS), "split_names": ["train", "validation", "test"]}
    return SegmentDataset(arrays, source, meta)


def test_segments_are_placed_in_their_flight_runs(rng):
    n_p = 4
    # flight 7: one run of four segments; flight 9: two runs (the segment at step 8 is
    # missing); listed out of order, as a joined dataset may hold them
    rows = [(9, 12), (7, 4), (9, 0), (7, 12), (9, 16), (7, 0), (9, 4), (7, 8)]
    data = _flights(rows, n_p, rng)
    located, runs = locate_flight_runs(data, "R")
    assert runs.targets.shape == (3, 16, 6)
    np.testing.assert_array_equal(runs.lengths, [16, 8, 8])
    # each run is its flight's reference in time, from its first step (R encodes them)
    for n, (flight, first) in enumerate(((7, 0), (9, 0), (9, 12))):
        flown = runs.targets[n, : runs.lengths[n], 0]
        np.testing.assert_array_equal(flown, 1000 * flight + first + np.arange(runs.lengths[n]))
        np.testing.assert_array_equal(runs.targets[n, runs.lengths[n] :, 0], flown[-1])
        row = rows.index((flight, first))
        np.testing.assert_array_equal(runs.x0[n], data.arrays["X"][row, 0])
        np.testing.assert_array_equal(runs.y0[n], data.arrays["Y"][row, 0])
    # every sample's RUN and STEP point at its own reference value in its run
    run = located.arrays["RUN"].astype(int)
    step = located.arrays["STEP"].astype(int)
    np.testing.assert_array_equal(runs.targets[run, step], data.arrays["R"])
    for name in ("X", "Y", "R"):
        np.testing.assert_array_equal(located.arrays[name], data.arrays[name])


def test_two_flights_with_one_seed_are_refused(rng):
    data = _flights([(5, 0), (5, 4), (5, 0)], 4, rng)
    with pytest.raises(ValueError, match="one flight per seed"):
        locate_flight_runs(data, "R")


def test_own_flights_follow_the_cell_step_by_step():
    """Closed form: a cell that adds the target to the state and outputs twice the state
    gives x_s = x_0 + sum of the first s targets and, as last output, 2 x_(s-1)."""
    targets = torch.arange(2 * 5 * 6, dtype=torch.float32).reshape(2, 5, 6).numpy()
    x0 = np.ones((2, 12), np.float32)
    y0 = -np.ones((2, 6), np.float32)
    starts = FlightStarts(FlightRuns(targets, np.array([5, 5]), x0, y0), refresh_batches=3)

    def cell(y, x, target):
        return None, None, 2 * x[:, :6], x + target.repeat(1, 2)

    assert starts.due()
    starts.refresh(cell)
    sums = np.concatenate([np.zeros((2, 1, 6)), np.cumsum(targets, axis=1)[:, :-1]], axis=1)
    np.testing.assert_allclose(starts.x.numpy(), x0[:, None] + np.tile(sums, 2))
    np.testing.assert_allclose(starts.y[:, 0].numpy(), y0)
    np.testing.assert_allclose(starts.y[:, 1:].numpy(), 2 * starts.x[:, :-1, :6].numpy())
    x, y = starts.starts(torch.tensor([1.0, 0.0]), torch.tensor([3.0, 2.0]))
    torch.testing.assert_close(x, starts.x[[1, 0], [3, 2]])
    torch.testing.assert_close(y, starts.y[[1, 0], [3, 2]])
    for _ in range(3):
        assert not starts.due()
        starts.count_batch()
    assert starts.due()
    with pytest.raises(ValueError, match="refresh_batches"):
        FlightStarts(starts.runs, refresh_batches=0)


def test_own_flights_reach_what_the_training_rollout_reaches():
    """The states kept are those of the closed-loop rollout the DPC loss uses (policy, clamp
    and the analytical plant), flown from the run's start for the same number of steps."""
    torch.manual_seed(1)
    config = DpcTrainingConfig(compile=False)
    policy, plant = PolicyNetwork(), RolloutPlant(config)
    targets = 2.0 * torch.randn(3, 60, 6)
    x0 = 0.2 * torch.randn(3, 12)
    y0 = torch.randn(3, 6)
    runs = FlightRuns(targets.numpy(), np.array([60] * 3), x0.numpy(), y0.numpy())
    starts = FlightStarts(runs, refresh_batches=1)
    starts.refresh(rollout_cell(policy, plant))
    with torch.no_grad():
        rollout = closed_loop_rollout(policy, plant, x0, y0, targets[:, :37])
    torch.testing.assert_close(starts.x[:, 37], rollout.X[:, -1])
    torch.testing.assert_close(starts.y[:, 37], rollout.Y[:, -1])


def test_a_random_share_of_the_batch_starts_on_policy():
    torch.manual_seed(2)
    x0, y0 = torch.zeros(4000, 12), torch.zeros(4000, 6)
    own_x, own_y = torch.ones(4000, 12), torch.ones(4000, 6)
    x, y = start_some_on_policy(x0, y0, own_x, own_y, 0.3)
    moved = x[:, 0] == 1
    assert 0.27 < moved.float().mean() < 0.33
    assert bool((x[moved] == 1).all() and (y[moved] == 1).all())
    assert bool((x[~moved] == 0).all() and (y[~moved] == 0).all())


def test_the_objective_starts_from_own_states_only_when_training_the_longest_step(rng):
    """With every window on policy, the training loss at the longest n_c is the loss of the
    batch whose first state and output are the policy's own (computed with the option off);
    in evaluation mode and at a shorter n_c the batch is flown as it is."""
    n_p = 8
    data = _flights([(3, 0), (3, 8), (3, 16), (4, 0), (4, 8)], n_p, rng)
    data.arrays["R"] = 0.5 * rng.standard_normal(data.arrays["R"].shape).astype(np.float32)
    located, runs = locate_flight_runs(data, "R")
    batch = {k: torch.as_tensor(located.arrays[k]) for k in ("X", "Y", "R", "RUN", "STEP")}
    train = TrainConfig(horizons=(4, n_p))
    on = DpcTrainingConfig(onpolicy_fraction=1.0, mirror_fraction=0.0, compile=False, train=train)
    off = dataclasses.replace(on, onpolicy_fraction=0.0)
    plant = RolloutPlant(on)
    torch.manual_seed(0)
    policy = PolicyNetwork()
    starts = FlightStarts(runs, refresh_batches=5)
    with torch.no_grad():
        loss_on = float(dpc_objective(on, plant, None, starts)(policy.train(), batch))
        own = dict(batch)
        own["X"], own["Y"] = batch["X"].clone(), batch["Y"].clone()
        own["X"][:, 0], own["Y"][:, 0] = starts.starts(batch["RUN"][:, 0], batch["STEP"][:, 0])
        assert not torch.allclose(own["X"][:, 0], batch["X"][:, 0])  # the starts moved
        np.testing.assert_allclose(loss_on, float(dpc_objective(off, plant)(policy, own)), 1e-6)
        as_flown = float(dpc_objective(off, plant)(policy, batch))
        assert abs(loss_on - as_flown) > 1e-4 * as_flown
        objective = dpc_objective(on, plant, None, starts)
        np.testing.assert_allclose(float(objective(policy.eval(), batch)), as_flown, 1e-6)
        short = {k: v[:, :4] for k, v in batch.items()}
        np.testing.assert_allclose(
            float(objective(policy.train(), short)),
            float(dpc_objective(off, plant)(policy, short)),
            1e-6,
        )
    with pytest.raises(ValueError, match="own_starts"):
        dpc_objective(on, plant)
    with pytest.raises(ValueError, match="onpolicy_fraction"):
        DpcTrainingConfig(onpolicy_fraction=1.5).validate()
    with pytest.raises(ValueError, match="onpolicy_refresh_batches"):
        DpcTrainingConfig(onpolicy_refresh_batches=0).validate()


def test_a_policy_trains_with_on_policy_starts(tmp_path, rng):
    """train_policy end to end on two small flights: the run finishes, and the policy file
    loads and records the option."""
    n_p, rows = 16, [(f, 16 * k) for f in (1, 2) for k in range(8)]
    data = _flights(rows, n_p, rng, split=np.array([0, 0, 0, 0, 1, 1, 1, 1] * 2))
    data.arrays["R"] = np.sin(data.arrays["R"] / 20.0).astype(np.float32)
    data.arrays["X"] *= 0.0
    path = data.save(tmp_path / "data.npz")
    config = DpcTrainingConfig(
        onpolicy_fraction=0.5,
        onpolicy_refresh_batches=2,
        window_segments=2,
        compile=False,
        train=TrainConfig(batch_size=2, max_epochs=2, horizons=(16, 32), device="cpu"),
    )
    _, policy_path = train_policy(config, path, tmp_path / "out", progress=False)
    policy = load_policy_network(policy_path)
    assert policy.hidden == config.hidden
    _, meta = load_policy_arrays(policy_path)
    assert meta["dpc_config"]["onpolicy_fraction"] == 0.5
