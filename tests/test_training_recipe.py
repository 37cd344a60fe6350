"""The training guide's recipe for the shipped policy and the benchmark that runs and times
it (`benchmarks/bench_training_recipe.py`) give the same `train-policy` steps, and the
shipped policy file records the loss weights and epochs of its last step."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest
from benchmark_scripts import load_benchmark

from mca_drake.cueing.dpc import load_policy_arrays, shipped_policy_path
from mca_drake.cueing.nmpc_config import NmpcConfig
from mca_drake.learning.configs import DpcTrainingConfig

REPO = Path(__file__).resolve().parents[1]
GUIDE = REPO / "docs" / "guides" / "training.md"


def _guide_train_commands() -> list[list[str]]:
    """The `mca-drake train-policy` commands of the guide's "Recipe: the shipped policy"
    section, continuation lines joined, as argument lists after `mca-drake`."""
    text = GUIDE.read_text()
    section = text.split("## Recipe: the shipped policy", 1)[1].split("\n## ", 1)[0]
    block = section.split("```bash", 1)[1].split("```", 1)[0].replace("\\\n", " ")
    return [
        shlex.split(line)[1:]
        for line in block.splitlines()
        if line.startswith("mca-drake train-policy")
    ]


def _flags(arguments: list[str]) -> dict[str, str]:
    """--flag value pairs of an argument list (a flag given twice: its last value, as the
    command line reads it); the folders (--out-dir, --init-policy) left out, since the
    guide and the benchmark write to their own."""
    pairs = dict(zip(arguments[1::2], arguments[2::2], strict=True))
    assert arguments[0] == "train-policy" and all(k.startswith("--") for k in pairs), arguments
    return {k: v for k, v in pairs.items() if k not in ("--out-dir", "--init-policy")}


def test_guide_and_benchmark_train_the_same_steps():
    bench = load_benchmark("bench_training_recipe")
    guide = _guide_train_commands()
    assert len(guide) == len(bench.STEPS) == 7
    datasets = {
        "transport_styles": "mixed_tr",
        "default_styles": "mixed_all",
        "light_styles": "mixed_all",
    }
    assert set(datasets) == set(bench.STYLES_STEPS)
    for (name, extra), command in zip(bench.STEPS, guide, strict=True):
        dataset = datasets.get(name, "mixed_t37")
        ours = bench.step_command(name, extra, f"datasets/{dataset}/dataset.npz", Path("r"))
        assert _flags(ours) == _flags(command), name
    # Steps 2 and the light aircraft's first start from step 1's result in both; the
    # transports' first step and the default's last from step 2's, the transports' last from
    # their first, the light aircraft's last from the default's.
    outs = [command[command.index("--out-dir") + 1] for command in guide]
    origins = (0, 0, 1, 3, 1, 5)
    for later, step, origin in zip(guide[1:], bench.STEPS[1:], origins, strict=True):
        assert later[later.index("--init-policy") + 1] == f"{outs[origin]}/policy.npz"
        ours = bench.step_command(*step, "d.npz", Path("r"))
        origin_name = bench.STEPS[origin][0]
        assert ours[ours.index("--init-policy") + 1] == str(Path("r") / origin_name / "policy.npz")


@pytest.mark.parametrize(
    "step",
    ["step2", "light", "transport", "transport_styles", "default_styles", "light_styles"],
)
def test_each_shipped_or_kept_flight_policy_was_trained_with_its_recipe_step(step):
    """The shipped policies and the earlier steps kept in tests/data (which the selection
    compares them with) record the flags of their recipe step."""
    bench = load_benchmark("bench_training_recipe")
    assert set(bench.SHIPPED).isdisjoint(bench.KEPT)
    if step in bench.SHIPPED:
        path = shipped_policy_path(bench.SHIPPED[step])
    else:
        path = REPO / "tests" / "data" / bench.KEPT[step]
    _, metadata = load_policy_arrays(path)
    flags = _flags(bench.step_command(step, dict(bench.STEPS)[step], "d.npz", Path("r")))
    config = metadata["dpc_config"]
    assert config["correlation_weight"] == pytest.approx(float(flags["--correlation-weight"]))
    assert config["washout_weight"] == pytest.approx(float(flags["--washout-weight"]))
    assert config["base_washout_weight"] == pytest.approx(float(flags["--base-washout-weight"]))
    assert config["train"]["max_epochs"] == int(flags["--max-epochs"])
    rate = float(flags.get("--learning-rate", DpcTrainingConfig().train.learning_rate))
    assert config["train"]["learning_rate"] == pytest.approx(rate)
    assert config["seed"] == int(flags["--seed"])
    assert config["max_start_position_rad"] == pytest.approx(float(flags["--max-start-position"]))
    assert config["own_start_fraction"] == pytest.approx(float(flags["--own-start-fraction"]))
    # the light aircraft's first step is older than the field: it trained without the weighting
    floor = float(flags.get("--achievable-cost-floor", 0.0))
    assert config.get("achievable_cost_floor", 0.0) == pytest.approx(floor)
    assert config["initial_policy"], "every shipped flight policy is fine-tuned"
    # step 2 and the default policy train on every flight (no --vehicles)
    wanted = flags["--vehicles"].split(",") if "--vehicles" in flags else []
    assert config.get("vehicles", []) == wanted
    averaged = int(flags.get("--average-epochs", 0))
    assert config["train"].get("average_epochs", 0) == averaged
    assert [s["horizon"] for s in metadata["stages"]] == [
        int(h) for h in flags["--horizons"].split(",")
    ]
    weights = metadata["tracking_channel_weights"]
    if "--channel-weights" in flags:
        wanted_weights = [float(w) for w in flags["--channel-weights"].split(",")]
    else:
        wanted_weights = list(NmpcConfig().output_weights)
    assert weights == pytest.approx(wanted_weights, rel=1e-6)
    correlation = flags.get("--correlation-channels", "1,1,1,1,1,1")
    wanted_correlation = [float(w) for w in correlation.split(",")]
    assert config.get("correlation_channel_weights", [1.0] * 6) == pytest.approx(wanted_correlation)
    posture = float(flags.get("--posture-weight", 0.0))
    assert config.get("posture_weight", 0.0) == pytest.approx(posture)


def test_transport_channel_weights_are_the_nmpc_weights_with_forces_twice():
    """The transports' last step weighs f_x and f_y twice the tuned NMPC's weights and
    every other channel as the NMPC does (its flag writes them to four digits)."""
    bench = load_benchmark("bench_training_recipe")
    ours = [float(w) for w in bench.TRANSPORT_CHANNEL_WEIGHTS.split(",")]
    scale = [1, 1, 1, 2, 2, 1]
    nmpc = [s * w for s, w in zip(scale, NmpcConfig().output_weights, strict=True)]
    assert ours == pytest.approx(nmpc, rel=1e-3)
