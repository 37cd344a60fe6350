"""Open-loop excitation dataset (Algorithm 1) at a small size, and the segment file format."""

from __future__ import annotations

import numpy as np
import pytest

from mca_drake.platforms import kinematics
from mca_drake.platforms.excitation import (
    SIGNALS,
    ExcitationConfig,
    excitation_profiles,
    first_violation,
    generate_excitation_dataset,
    rollout_states,
)
from mca_drake.segments import SegmentDataset

SMALL = ExcitationConfig(repetitions=4, horizon=64, initial_state_fraction=0.5, seed=3)


@pytest.fixture(scope="module")
def dataset():
    return generate_excitation_dataset(SMALL, progress=False)


def test_every_kept_segment_is_inside_all_limits(dataset, robot):
    assert len(dataset) > 20
    q, qd, u = dataset.X[..., :6], dataset.X[..., 6:], dataset.U
    assert np.all(q >= robot.q_min - 1e-6) and np.all(q <= robot.q_max + 1e-6)
    assert np.all(np.abs(qd) <= robot.qd_max + 1e-6)
    assert np.all(np.abs(u) <= robot.qdd_max + 1e-6)


def test_segment_shapes(dataset):
    J = len(dataset)
    n_p = SMALL.horizon
    assert dataset.U.shape == (J, n_p, 6) and dataset.Y.shape == (J, n_p, 6)
    assert dataset.X.shape == (J, n_p, 12)
    assert dataset.F.shape == dataset.dF.shape == dataset.ddF.shape == (J, n_p, 4, 4)
    assert dataset.source.shape == (J, 5)
    assert set(np.unique(dataset.source[:, 0])) <= set(range(len(SIGNALS)))


def test_segments_are_plant_trajectories(dataset, robot):
    """Within a segment x_(t+1) = exact step(x_t, u_t); Y and F are the plant's (float32)."""
    X, U, h = dataset.X.astype(float), dataset.U.astype(float), SMALL.time_step
    q, qd = X[..., :6], X[..., 6:]
    np.testing.assert_allclose(qd[:, 1:], qd[:, :-1] + h * U[:, :-1], atol=1e-5)
    np.testing.assert_allclose(
        q[:, 1:], q[:, :-1] + h * qd[:, :-1] + 0.5 * h * h * U[:, :-1], atol=1e-5
    )
    k = slice(0, 5)
    np.testing.assert_allclose(
        dataset.Y[k], kinematics.plant_output(q[k], qd[k], U[k], robot), atol=1e-4
    )
    F, _, ddF = kinematics.head_pose_derivatives(q[k], qd[k], U[k], robot)
    np.testing.assert_allclose(dataset.F[k], F, atol=1e-5)
    np.testing.assert_allclose(dataset.ddF[k], ddF, atol=1e-4)


def test_profiles_drive_only_joints_i_to_j_within_limits(robot):
    rng = np.random.default_rng(0)
    for signal in SIGNALS:
        U = excitation_profiles(signal, 1, 3, 5, 500, 0.01, rng, robot)
        assert U.shape == (5, 500, 6)
        assert np.all(U[:, :, [0, 4, 5]] == 0.0)
        assert np.all(np.abs(U) <= robot.qdd_max + 1e-12)
        assert np.all(np.std(U[:, :, 1:4], axis=1) > 0), signal


def test_trim_at_first_violation(robot):
    """A constant acceleration on joint 1 from rest: the trim index is the first step at
    which q_1 (t^2 u / 2) or qd_1 (t u) leaves its limits, computed in closed form."""
    u, h = 1.0, 0.01
    U = np.zeros((1, 3000, 6))
    U[..., 0] = u
    X = rollout_states(np.zeros((1, 12)), U, h)
    k = first_violation(X, robot)[0]
    qd_hit = np.ceil(robot.qd_max[0] / (u * h) + 1e-9)  # qd_k = k h u exceeds qd_max
    q_hit = np.ceil(np.sqrt(2 * robot.q_max[0] / u) / h)  # q_k ~ (k h)^2 u / 2
    assert k == pytest.approx(min(qd_hit, q_hit), abs=1)
    assert np.all(np.abs(X[0, :k, 6]) <= robot.qd_max[0])


def test_seeded_generation_is_reproducible(dataset):
    again = generate_excitation_dataset(SMALL, progress=False)
    np.testing.assert_array_equal(again.U, dataset.U)
    np.testing.assert_array_equal(again.source, dataset.source)


def test_save_load_round_trip_and_split(dataset, tmp_path):
    path = dataset.save(tmp_path / "open_loop.npz")
    back = SegmentDataset.load(path)
    for name in dataset.arrays:
        np.testing.assert_array_equal(back.arrays[name], dataset.arrays[name])
    assert back.metadata["config"]["horizon"] == SMALL.horizon
    assert "numpy" in back.metadata["versions"]
    train, val, test = back.split(seed=1)
    assert len(train) + len(val) + len(test) == len(back)
    assert abs(len(train) - 0.7 * len(back)) <= 1


def test_bad_config_and_file(tmp_path):
    with pytest.raises(ValueError, match="unknown signals"):
        generate_excitation_dataset(ExcitationConfig(signals=("chirp",)), progress=False)
    with pytest.raises(ValueError, match="shorter than one segment"):
        generate_excitation_dataset(ExcitationConfig(duration_s=1.0), progress=False)
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a segment dataset"):
        SegmentDataset.load(bad)
