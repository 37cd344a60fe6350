"""`mca-drake train-policy`, `export-policy` and `table2`: the torch commands.

torch is imported inside the commands only, so that the other commands start fast; the
flags come from the torch-free configs (`mca_drake.learning.configs`). Nothing here needs
Drake at import, so these commands run where pydrake is not installed.
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import sys
from pathlib import Path

from mca_drake.app.cli.flags import (
    ADDRESS_HELP,
    add_config_flags,
    add_quiet,
    check_outputs,
    given_fields,
)
from mca_drake.cueing.nmpc_config import NmpcConfig
from mca_drake.cueing.profiles import load_platform_settings, profile_config
from mca_drake.learning.configs import DpcTrainingConfig
from mca_drake.platforms.excitation import ExcitationConfig, generate_excitation_dataset
from mca_drake.platforms.files import packaged_name
from mca_drake.resources import PROFILES
from mca_drake.segments import DEFAULT_DATASET

# DpcTrainingConfig fields with a flag, by flag name where it differs from the field's.
POLICY_FLAGS = {
    "targets": "",
    "tracking_signals": "",
    "perception_model": "",
    "preview_steps": "",
    "preview_predictor": "",
    "plant": "",
    "learned_output_weights": "",
    "window_segments": "",
    "vehicles": "",
    "initial_policy": "--init-policy",
    "washout_weight": "",
    "base_washout_weight": "",
    "input_weight": "",
    "max_start_position_rad": "--max-start-position",
    "perturbed_fraction": "",
    "own_start_fraction": "",
    "initial_state_noise": "",
    "mirror_fraction": "",
    "yaw_shift_fraction": "",
    "time_stretch_fraction": "",
    "time_stretch_max": "",
    "correlation_weight": "",
    "correlation_channel_weights": "--correlation-channels",
    "posture_weight": "",
    "achievable_cost_floor": "",
    "terminal_weight_horizon": "",
    "hidden": "",
    "seed": "",
    "platform": "",
}
# TrainConfig fields (the policy's optimisation) with a flag.
POLICY_TRAIN_FLAGS = {
    "horizons": "",
    "max_epochs": "",
    "early_stopping_patience": "--patience",
    "learning_rate": "",
    "batch_size": "",
    "device": "",
    "average_epochs": "",
}


def add_parsers(commands) -> None:
    """Adds `train-policy`, `export-policy`, `transfer-policy` and `table2` to the parsers
    `commands`."""
    _add_train_policy(commands)
    export = commands.add_parser(
        "export-policy", help="best weights so far of a training checkpoint as a policy file"
    )
    export.add_argument("checkpoint", help="policy.pt of a train-policy run")
    export.add_argument("--out", default="policy.npz", help="the policy file to write")
    export.set_defaults(func=run_export_policy)
    transfer = commands.add_parser(
        "transfer-policy",
        help="a policy file for another platform whose joints include the policy's: the "
        "shared joints keep their weights (turned where a joint moves the cabin the other "
        "way), the others start at zero",
    )
    transfer.add_argument("policy", help="the policy file (its platform's joints by name)")
    transfer.add_argument(
        "--platform", required=True, help="the platform: a packaged name or a platform file"
    )
    transfer.add_argument("--out", default="policy.npz", help="the policy file to write")
    transfer.set_defaults(func=run_transfer_policy)
    _add_table2(commands)


def _add_train_policy(commands) -> None:
    defaults = DpcTrainingConfig()
    parser = commands.add_parser(
        "train-policy",
        help="train the DPC policy on a closed-loop dataset (unset flags: the defaults of "
        "mca_drake.learning.dpc_training.DpcTrainingConfig: the shipped NMPC's objective)",
    )
    parser.add_argument(
        "--objective",
        choices=("tuned", "paper", *PROFILES),
        default="tuned",
        help="loss weights: tuned (the shipped NMPC's weights on --platform, tracking the "
        "references; default), paper (equation 9, tracking the NMPC-achieved outputs), or a "
        "profile's "
        f"NMPC objective ({', '.join(PROFILES)}: that profile's weights, tracking the references)",
    )
    parser.add_argument("--dataset", default=DEFAULT_DATASET, help="closed-loop dataset.npz")
    parser.add_argument("--out-dir", default="results/policy", help="the run's folder")
    add_config_flags(parser, defaults, POLICY_FLAGS)
    add_config_flags(parser, defaults.train, POLICY_TRAIN_FLAGS)
    parser.add_argument(
        "--channel-weights",
        help="tracking weights per output channel: six numbers (default the objective's), "
        "uniform, or normalized (1 / target variance)",
    )
    parser.add_argument("--no-compile", action="store_true", help="eager torch (slower)")
    parser.add_argument("--resume", action="store_true", help="continue a killed run")
    add_quiet(parser)
    parser.set_defaults(func=run_train_policy)


def channel_weights(text: str) -> str | tuple[float, ...]:
    """--channel-weights: 'uniform', 'normalized' or six comma-separated numbers."""
    if text in ("uniform", "normalized"):
        return text
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise SystemExit(
            f"--channel-weights: 'uniform', 'normalized' or six numbers, not '{text}'"
        ) from None


def objective_config(objective: str, platform: str = "") -> DpcTrainingConfig:
    """--objective: the training config whose loss is "tuned" (the NMPC tuned for the
    packaged `platform` where it ships settings, `cueing.profiles.load_platform_settings`;
    else the defaults, tuned on the KR500), "paper", or a profile's NMPC objective
    (`mca_drake.cueing.profiles`)."""
    if objective == "tuned":
        tuned = load_platform_settings(packaged_name(platform)) if platform else None
        return DpcTrainingConfig() if tuned is None else DpcTrainingConfig.matching(tuned.nmpc)
    if objective == "paper":
        return DpcTrainingConfig.paper()
    return DpcTrainingConfig.matching(profile_config(NmpcConfig, objective))


def command_line(argv: list[str] | None = None) -> str:
    """The training command as a user types it ("mca-drake train-policy ..."), for the policy
    file's metadata: from the `mca-drake` script or `python -m mca_drake.app.cli` (how
    `benchmarks/bench_training_recipe.py` runs it); "" when called from Python."""
    argv = sys.argv if argv is None else argv
    program = Path(argv[0])
    if program.name == "mca-drake" or program.parts[-3:] == ("app", "cli", "__main__.py"):
        return shlex.join(["mca-drake", *argv[1:]])
    return ""


def run_train_policy(args: argparse.Namespace) -> int:
    """Trains the policy the flags describe; writes policy.npz in --out-dir."""
    # torch: loaded by the training commands only, so the others start fast
    from mca_drake.learning.dpc_training import train_policy

    base = objective_config(args.objective, args.platform or "")
    config = dataclasses.replace(base, **given_fields(args, POLICY_FLAGS))
    if args.no_compile:
        config.compile = False
    if args.channel_weights is not None:
        config.tracking_channel_weights = channel_weights(args.channel_weights)
    config.train = dataclasses.replace(config.train, **given_fields(args, POLICY_TRAIN_FLAGS))
    _, path = train_policy(
        config,
        args.dataset,
        args.out_dir,
        resume=args.resume,
        progress=not args.quiet,
        command=command_line(),
    )
    print(f"policy written to {path}")
    return 0


def run_export_policy(args: argparse.Namespace) -> int:
    """Writes the checkpoint's best weights as a policy file."""
    check_outputs(args.out)
    # torch: loaded by the training commands only, so the others start fast
    from mca_drake.learning.dpc_training import export_checkpoint_policy

    print(f"policy written to {export_checkpoint_policy(args.checkpoint, args.out)}")
    return 0


def run_transfer_policy(args: argparse.Namespace) -> int:
    """Writes the policy moved onto --platform's joints
    (`mca_drake.learning.policy_network.transfer_policy_network`)."""
    check_outputs(args.out)
    # torch: loaded by the training commands only, so the others start fast
    from mca_drake.learning.dpc_training import initial_policy_provenance
    from mca_drake.learning.policy_network import save_policy, transfer_policy_network
    from mca_drake.platforms.files import load_platform

    robot = load_platform(args.platform)
    policy = transfer_policy_network(args.policy, robot)
    provenance = initial_policy_provenance(args.policy)
    save_policy(
        args.out,
        policy,
        {
            "model": "dpc-policy",
            "command": command_line(),
            # the platform whose joints the policy commands (`cueing.dpc.check_policy_platform`)
            "platform": robot.summary(),
            "transferred_from": provenance,
            "training_wall_s": 0.0,
            "training_wall_s_total": provenance.get("training_wall_s_total", 0.0),
        },
    )
    print(f"policy for platform '{robot.name}' written to {args.out}")
    return 0


def _add_table2(commands) -> None:
    parser = commands.add_parser(
        "table2", help="train and score every plant-model candidate (the paper's Table II)"
    )
    parser.add_argument("--quick", action="store_true", help="a few minutes: small data, epochs")
    parser.add_argument("--closed-loop-dataset", help=f"default {DEFAULT_DATASET}")
    parser.add_argument("--open-loop-dataset", help="default datasets/open_loop.npz")
    parser.add_argument("--out-dir", default="results/table2", help="the study's folder")
    parser.add_argument("--resume", action="store_true", help="continue a killed run")
    parser.add_argument(
        "--workers", type=int, help="candidates at once, on a local Ray (default 1: here)"
    )
    parser.add_argument("--address", help=ADDRESS_HELP)
    parser.add_argument("--device", help="auto (CUDA if present), cpu, cuda")
    parser.add_argument("--max-epochs", type=int, help="override epochs per curriculum step")
    parser.add_argument(
        "--only", help="comma-separated candidates, e.g. state_node1,output_mixed (default all)"
    )
    add_quiet(parser)
    parser.set_defaults(func=run_table2)


def _quick_closed_loop_dataset(folder: Path, progress: bool) -> Path:
    # Imported here: closed-loop datasets need Drake, training does not.
    from mca_drake.studies.closed_loop_dataset import (
        ClosedLoopDatasetConfig,
        generate_closed_loop_dataset,
    )

    config = ClosedLoopDatasetConfig(flight_seeds=(100,), flight_duration_s=60.0, horizon=32)
    return generate_closed_loop_dataset(config, folder / "closed_loop", progress=progress)


def _quick_open_loop_dataset(folder: Path) -> Path:
    path = folder / "open_loop_quick.npz"
    if not path.is_file():
        config = ExcitationConfig(repetitions=3, duration_s=4.0, horizon=32)
        generate_excitation_dataset(config, progress=False).save(path)
    return path


def _table2_config(args: argparse.Namespace, out: Path):
    """The study's config: the quick one, or the paper-size one on datasets that exist."""
    # torch: loaded by the training commands only, so the others start fast
    from mca_drake.studies.table2 import Table2Config, quick_config

    closed, open_loop = args.closed_loop_dataset, args.open_loop_dataset
    if args.quick:
        closed = closed or str(_quick_closed_loop_dataset(out / "data", not args.quiet))
        open_loop = open_loop or str(_quick_open_loop_dataset(out / "data"))
        return quick_config(closed, open_loop)
    defaults = Table2Config()
    config = Table2Config(
        closed_loop_dataset=closed or defaults.closed_loop_dataset,
        open_loop_dataset=open_loop or defaults.open_loop_dataset,
    )
    for path, command in (
        (config.closed_loop_dataset, "mca-drake dataset closed-loop"),
        (config.open_loop_dataset, "mca-drake dataset open-loop --out datasets/open_loop.npz"),
    ):
        if not Path(path).is_file():
            raise FileNotFoundError(f"dataset {path} not found; make it with `{command}`")
    return config


def run_table2(args: argparse.Namespace) -> int:
    """Trains and scores the plant-model candidates; prints Table II."""
    # torch: loaded by the training commands only, so the others start fast
    from mca_drake.studies.table2 import run_table2 as run_study

    out = Path(args.out_dir)
    config = _table2_config(args, out)
    config.train = dataclasses.replace(config.train, **given_fields(args, ("device", "max_epochs")))
    if args.only:
        wanted = set(args.only.split(","))
        config.state_models = tuple(n for n in config.state_models if f"state_{n}" in wanted)
        config.output_models = tuple(n for n in config.output_models if f"output_{n}" in wanted)
    report = run_study(
        config,
        out,
        resume=args.resume,
        progress=not args.quiet,
        workers=args.workers if args.workers is not None else 1,
        address=args.address,
    )
    print((out / "table2.md").read_text())
    print(f"written to {out / 'table2.md'} and table2.json ({report['wall_s'] / 60:.1f} min)")
    return 0
