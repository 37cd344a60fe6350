"""A DPC policy with a reference preview: its numpy and torch versions agree on the preview
inputs, its rollouts read the targets ahead, its file says its preview, the diagram feeds it
the future at its offsets, and live runs refuse it."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from dataset_helpers import rest_segments
from pydrake.systems.analysis import Simulator

from mca_drake.cueing.dpc import (
    DpcConfig,
    PolicyInference,
    load_policy_arrays,
    policy_preview_steps,
    preview_offsets,
)
from mca_drake.learning.configs import DpcTrainingConfig, TrainConfig
from mca_drake.learning.dpc_training import rollout_previews, train_policy
from mca_drake.learning.policy_network import PolicyNetwork, load_policy_network, save_policy
from mca_drake.platforms.files import load_platform
from mca_drake.references.reference import Reference
from mca_drake.segments import SegmentDataset
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.systems.dpc import DpcPolicy

KR500 = load_platform("kr500")

PREVIEW = 20


def test_numpy_and_torch_agree_with_a_preview_and_the_file_keeps_it(tmp_path):
    torch.manual_seed(0)
    policy = PolicyNetwork(KR500, hidden=16, preview_steps=PREVIEW).double()
    rng = np.random.default_rng(0)
    y, x, target, preview = (rng.normal(size=n) for n in (6, 12, 6, 24))
    u, x_hat = policy(*(torch.tensor(v)[None] for v in (y, x, target, preview)))
    path = tmp_path / "preview.npz"
    save_policy(path, policy, {"command": "test"})
    arrays, metadata = load_policy_arrays(path)
    assert policy_preview_steps(metadata) == PREVIEW and arrays["W1"].shape == (16, 48)
    got_u, got_x = PolicyInference(arrays)(y, x, target, preview)
    np.testing.assert_allclose(got_u, u[0].detach().numpy(), atol=1e-9)
    np.testing.assert_allclose(got_x, x_hat[0].detach().numpy(), atol=1e-9)
    assert load_policy_network(path, KR500).preview_steps == PREVIEW
    np.testing.assert_array_equal(preview_offsets(PREVIEW), [5, 10, 15, 20])


def test_rollouts_read_the_targets_ahead_holding_the_last():
    targets = torch.arange(2 * 30 * 6, dtype=torch.float64).reshape(2, 30, 6)
    previews = rollout_previews(targets, PREVIEW)
    assert previews.shape == (2, 30, 24) and rollout_previews(targets, 0) is None
    for t in (0, 7, 29):
        rows = [min(t + o, 29) for o in (5, 10, 15, 20)]
        expected = targets[:, rows].reshape(2, 24)
        torch.testing.assert_close(previews[:, t], expected)


def _dataset(n=24, horizon=40, seed=0) -> SegmentDataset:
    rng = np.random.default_rng(seed)
    t = 0.01 * np.arange(horizon)
    R = np.zeros((n, horizon, 6))
    R[..., 3] = np.sin(rng.uniform(0, 3, (n, 1)) + 2.0 * t[None])  # a surge to anticipate
    return rest_segments(R)


@pytest.fixture(scope="module")
def preview_policy(tmp_path_factory):
    folder = tmp_path_factory.mktemp("preview")
    data = _dataset().save(folder / "data.npz")
    config = DpcTrainingConfig.paper(
        targets="reference",
        compile=False,
        window_segments=1,
        preview_steps=PREVIEW,
        train=TrainConfig(
            learning_rate=1e-2, batch_size=8, max_epochs=2, horizons=(40,), device="cpu"
        ),
    )
    return train_policy(config, data, folder, progress=False)[1]


def test_the_diagram_feeds_a_trained_preview_policy_the_future(preview_policy, robot):
    """The trained file says its preview; in closed loop the source's preview reaches the
    policy, whose command is the network's for the reference at its offsets ahead."""
    assert policy_preview_steps(load_policy_arrays(preview_policy)[1]) == PREVIEW
    system = DpcPolicy(str(preview_policy), robot)
    assert system.preview_samples == PREVIEW + 1
    context = system.CreateDefaultContext()
    future = np.zeros((PREVIEW + 1, 6))
    future[:, 3] = np.linspace(0.0, 2.0, PREVIEW + 1)
    state = np.zeros(12)
    system.GetInputPort("state").FixValue(context, state)
    system.GetInputPort("inertial_output").FixValue(context, np.zeros(6))
    system.GetInputPort("reference").FixValue(context, future[0])
    system.GetInputPort("reference_preview").FixValue(context, future.reshape(-1))
    simulator = Simulator(system, context)  # the control step at t = 0, as in a diagram
    simulator.AdvanceTo(0.005)
    command = system.GetOutputPort("joint_acceleration").Eval(simulator.get_context())
    inference = PolicyInference(load_policy_arrays(preview_policy)[0])
    ahead = future[preview_offsets(PREVIEW)].reshape(-1)
    expected, _ = inference(np.zeros(6), state, future[0], ahead)
    assert np.max(np.abs(expected)) > 1e-3  # the check has something to check
    np.testing.assert_allclose(command, expected, atol=1e-12)  # at rest: inside the clamp
    t = np.arange(200) * 0.01
    y = np.zeros((t.size, 6))
    y[:, 3] = np.sin(2.0 * t)
    result = run_closed_loop(
        mca=DpcConfig(policy=str(preview_policy)),
        reference=Reference(y, 0.01, "surge"),
        progress=False,
        robot=KR500,
    )
    assert result.summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}


def test_live_runs_refuse_a_preview_policy(preview_policy):
    from mca_drake.app.scenarios import LiveScenario

    with pytest.raises(ValueError, match="no future"):
        LiveScenario(mca=DpcConfig(policy=str(preview_policy))).validate()
    with pytest.raises(ValueError, match="preview_steps"):
        DpcTrainingConfig(preview_steps=-1).validate()
