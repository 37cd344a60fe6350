"""The torch training path on a machine without pydrake (a GPU box that only trains): the
`mca-drake` command offers the torch commands alone, and `train-policy` trains, with a
profile's objective too, without importing Drake."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from dataset_helpers import rest_segments
from hidden_drake import PYDRAKE_LOADED, run_without_drake

from mca_drake.app.cli.platforms import platform_records
from mca_drake.cueing.nmpc_config import NmpcConfig
from mca_drake.cueing.profiles import profile_config
from mca_drake.learning.configs import DpcTrainingConfig, TrainConfig
from mca_drake.learning.dpc_training import train_policy
from mca_drake.platforms.files import packaged_platforms

REPO = Path(__file__).resolve().parents[1]

# The torch commands, run in a fresh interpreter without pydrake.
WITHOUT_DRAKE = f"""
from mca_drake.app.cli import build_parser, main
commands = sorted(build_parser()._subparsers._group_actions[0].choices)
status = main(json.loads(sys.argv[1]))
print(json.dumps({{"commands": commands, "status": status, "pydrake_loaded": {PYDRAKE_LOADED}}}))
"""


def _run_without_drake(argv: list[str], cwd: Path) -> dict:
    return run_without_drake(WITHOUT_DRAKE, [json.dumps(argv)], cwd)


def _sine_dataset():
    """24 segments of 32 steps at rest at neutral, targets: slow sines in roll rate and
    surge around a level 1 g."""
    rng = np.random.default_rng(0)
    t = 0.01 * np.arange(32)
    zero = 0 * t
    targets = np.stack(
        [
            np.column_stack(
                [0.05 * np.sin(2 * t + p), zero, zero, np.sin(t + p), zero, 9.81 + zero]
            )
            for p in rng.uniform(0, 3, 24)
        ]
    )
    return rest_segments(targets)


def test_train_policy_runs_without_drake_on_a_profiles_objective(tmp_path):
    dataset = _sine_dataset().save(tmp_path / "data.npz")
    argv = ["train-policy", "--dataset", str(dataset), "--out-dir", str(tmp_path / "policy")]
    argv += ["--objective", "ground", "--horizons", "32", "--window-segments", "1"]
    argv += ["--max-epochs", "2", "--batch-size", "8", "--no-compile", "--device", "cpu"]
    result = _run_without_drake([*argv, "--quiet"], REPO)

    assert result["status"] == 0
    assert result["pydrake_loaded"] == []
    assert result["commands"] == [
        "export-policy",
        "platforms",
        "table2",
        "train-policy",
        "transfer-policy",
    ]
    policy = np.load(tmp_path / "policy" / "policy.npz")
    metadata = json.loads(str(policy["metadata_json"]))
    # The loss is the ground profile's NMPC objective, read without Drake's YAML loader.
    ground = profile_config(NmpcConfig, "ground")
    np.testing.assert_allclose(metadata["tracking_channel_weights"], ground.output_weights, 1e-6)
    assert metadata["dpc_config"]["input_weight"] == ground.input_weight
    assert metadata["dpc_config"]["washout_weight"] == ground.washout_weight


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_train_policy_trains_on_cuda(tmp_path):
    """On a GPU the policy, the data and the rollout plant (its limits, its clamp) all live
    on the device: two epochs, compiled as by default, end in a policy file."""
    dataset = _sine_dataset().save(tmp_path / "data.npz")
    config = DpcTrainingConfig(
        window_segments=1,
        train=TrainConfig(batch_size=8, max_epochs=2, horizons=(32,), device="cuda"),
    )
    _, path = train_policy(config, dataset, tmp_path / "policy", progress=False)
    assert np.all(np.isfinite(np.load(path)["W1"]))


PLATFORMS_WITHOUT_DRAKE = f"""
from mca_drake.app.cli.platforms import platform_records
from mca_drake.platforms.files import packaged_platforms
records = platform_records(list(packaged_platforms()))
print(json.dumps({{"records": records, "pydrake_loaded": {PYDRAKE_LOADED}}}))
"""


def test_the_platforms_read_without_drake_as_with_it():
    """The packaged platforms as `mca-drake platforms --json` gives them, read by the XML
    reader in an interpreter without pydrake, equal those read through Drake's parser."""
    result = run_without_drake(PLATFORMS_WITHOUT_DRAKE, [], REPO)
    assert result["pydrake_loaded"] == []
    assert result["records"] == platform_records(list(packaged_platforms()))
