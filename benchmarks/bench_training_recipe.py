"""The shipped flight policies' training recipe, run and timed: the `train-policy` steps of
the training guide ("Recipe: the shipped policy") on this machine (step 1, then from it the
default's second step and the light aircraft's first, then from that step the
transports' first step and from it their policy, the default policy, and from it the light
aircraft's policy), each curriculum step's epochs, best epoch and wall time, and the whole
recipe's wall time against its target (30 minutes on 2 CPU cores for the first four steps;
the three steps that learn pilots of drawn styles on top).

python benchmarks/bench_training_recipe.py [--dataset datasets/mixed_t37/dataset.npz]
    [--styles-dataset datasets/mixed_tr/dataset.npz]
    [--default-styles-dataset datasets/mixed_all/dataset.npz] [--out-dir results/recipe]
    [--json benchmarks/results/training_recipe.json]

Each step trains in its own folder under --out-dir (`step1`, `step2`, `light`,
`transport`, `transport_styles`, `default_styles`, `light_styles`): `transport_styles` on
--styles-dataset, the flight dataset joined with the wide-body's flights by pilots of
drawn styles, `default_styles` and `light_styles` on --default-styles-dataset, joined with
the flights of every training aircraft by pilots of drawn styles. A folder that holds the step's
policy.npz is read, not trained again (its recorded times stand); one with only a
checkpoint is resumed (`train-policy --resume`), so a killed run continues. The figures
are the trainer's own wall times (dataset loading and the policy export excluded) and, for
the steps run now, the whole process's. Time it with nothing else running.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import time
from pathlib import Path

from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing.dpc import load_policy_arrays

# The recipe's target on 2 CPU cores, s.
TARGET_WALL_S = 30 * 60

# The flags every step shares: the augmentations.
COMMON_FLAGS = (
    "--perturbed-fraction 0.0 --patience 100 "
    "--terminal-weight-horizon 256 --mirror-fraction 0.5 --yaw-shift-fraction 0.5 "
    "--time-stretch-fraction 0.5 --seed 1"
).split()
# The two-step curriculum of every step but the last, which fine-tunes at the long one.
CURRICULUM = ("--horizons", "256,1024")

# Step 1 learns the tuned NMPC's objective from random weights on windows starting near
# neutral; step 2 fine-tunes step 1's policy with the PI's correlation term and the
# washouts (decision 0015), on windows starting up to 1 rad from it (decision 0017) and on
# every training window again from step 1's own closed-loop state (decision 0018), each
# window's tracking weighted by what the NMPC achieved on it (decision 0019). The light
# aircraft's first step is the same fine-tuning on their training flights alone, from near
# neutral (decision 0016). The transports' first step fine-tunes step 2 on the wide-body's
# flights alone (decision 0020); their policy fine-tunes that at the long horizon on the
# wide-body's flights by the scripted pilot and by pilots of drawn styles, ending on the
# mean of its last 60 epochs (decision 0038), with the longitudinal and lateral forces
# weighed twice the tuned NMPC's (decision 0040), heave's correlation halved (decision
# 0042) and joints 2-6 pulled towards the NMPC's posture instead of washed out (decision
# 0043). The default policy is step 2 fine-tuned the same way on every training aircraft's
# flights by the scripted pilot and by pilots of drawn styles (decision 0039); the light
# aircraft's policy is the default fine-tuned the same way on the light aircraft's flights
# alone (decision 0040).
FINE_TUNING_FLAGS = (
    "--correlation-weight",
    "1",
    "--washout-weight",
    "0.3",
    "--base-washout-weight",
    "1",
    "--own-start-fraction",
    "1.0",
)
STEP2_FLAGS = ("--init-policy", "{step1}/policy.npz", *FINE_TUNING_FLAGS)


def with_value(flags: tuple[str, ...], flag: str, value: str) -> tuple[str, ...]:
    """`flags` (flag, value pairs) with `flag`'s value replaced by `value`."""
    at = flags.index(flag) + 1
    return (*flags[:at], value, *flags[at + 1 :])


# The steps that learn pilots of drawn styles: step 2's loss at the long horizon, 160 epochs
# at a learning rate of 0.002 ending on the mean of the last 60 (decisions 0038, 0039).
STYLES_FLAGS = (
    "--horizons",
    "1024",
    "--max-start-position",
    "1.0",
    *FINE_TUNING_FLAGS,
    "--achievable-cost-floor",
    "0.003",
    "--max-epochs",
    "160",
    "--average-epochs",
    "60",
    "--learning-rate",
    "0.002",
)
# The transports' channel weights (w_x, w_y, w_z, f_x, f_y, a_z): the tuned NMPC's, four
# digits, with f_x and f_y twice theirs. A wide-body's forces are slow and sustained;
# with the tuned weights the policy trades their RMSE, which the PI counts in m/s^2, for the
# correlation of rotation rates below the canals' thresholds (decision 0040).
TRANSPORT_CHANNEL_WEIGHTS = "11.01,3.497,232.6,13.6,15.78,0.2642"
# The transports' correlation weights per channel (w_x, w_y, w_z, f_x, f_y, a_z): heave's
# halved. Inside a 10 s window a wide-body's slow heave looks like a cue to follow; chasing
# it buys no heave correlation over the flight and tilts the forces (decision 0042).
TRANSPORT_CORRELATION_CHANNELS = "1,1,1,1,1,0.5"
# The transports' pull of joints 2-6 towards the NMPC's posture, rad^-2, in place of their
# washout (which the NMPC's posture carries): from poses of its own the policy renders a
# wide-body's outputs over a window at the cost of its sustained forces (decision 0043).
TRANSPORT_POSTURE_WEIGHT = "1"
STEPS = (
    ("step1", (*CURRICULUM, "--max-start-position", "0.6", "--max-epochs", "300")),
    (
        "step2",
        (
            *CURRICULUM,
            "--max-start-position",
            "1.0",
            *STEP2_FLAGS,
            "--achievable-cost-floor",
            "0.003",
            "--max-epochs",
            "40",
        ),
    ),
    (
        "light",
        (
            *CURRICULUM,
            "--max-start-position",
            "0.6",
            *STEP2_FLAGS,
            "--max-epochs",
            "60",
            "--vehicles",
            "light,DHC6",
        ),
    ),
    (
        "transport",
        (
            *CURRICULUM,
            "--max-start-position",
            "1.0",
            "--init-policy",
            "{step2}/policy.npz",
            *FINE_TUNING_FLAGS,
            "--achievable-cost-floor",
            "0.003",
            "--max-epochs",
            "40",
            "--learning-rate",
            "0.01",
            "--vehicles",
            "787-8",
        ),
    ),
    (
        "transport_styles",
        (
            "--init-policy",
            "{transport}/policy.npz",
            *with_value(STYLES_FLAGS, "--washout-weight", "0"),
            "--vehicles",
            "787-8",
            "--channel-weights",
            TRANSPORT_CHANNEL_WEIGHTS,
            "--correlation-channels",
            TRANSPORT_CORRELATION_CHANNELS,
            "--posture-weight",
            TRANSPORT_POSTURE_WEIGHT,
        ),
    ),
    ("default_styles", ("--init-policy", "{step2}/policy.npz", *STYLES_FLAGS)),
    (
        "light_styles",
        ("--init-policy", "{default_styles}/policy.npz", *STYLES_FLAGS, "--vehicles", "light,DHC6"),
    ),
)
# The steps trained on a dataset with the drawn-style pilots' flights, and the command-line
# option (attribute of the parsed arguments) that names it.
STYLES_STEPS = {
    "transport_styles": "styles_dataset",
    "default_styles": "default_styles_dataset",
    "light_styles": "default_styles_dataset",
}
# The steps the 30-minute target covers (all but the three that learn drawn-style pilots).
TARGET_STEPS = ("step1", "step2", "light", "transport")
# The shipped policy file each step after the first gives (`mca_drake.resources`).
SHIPPED = {
    "light_styles": "light_policy",
    "transport_styles": "transport_policy",
    "default_styles": "default_policy",
}
# The steps a shipped policy fine-tunes further, kept in tests/data (the selection compares
# them, `bench_selection.py`).
KEPT = {
    "step2": "default_step2.npz",
    "light": "light_step1.npz",
    "transport": "transport_step1.npz",
}


def step_command(name: str, extra: tuple[str, ...], dataset: str, out_dir: Path) -> list[str]:
    """The `mca-drake train-policy` argument list of recipe step `name` writing into
    out_dir/name; "{step1}", "{step2}", "{transport}" and "{default_styles}" in `extra` name
    those steps' folders."""
    folders = {name: out_dir / name for name in ("step1", "step2", "transport", "default_styles")}
    flags = [f.format(**folders) for f in extra]
    return [
        "train-policy",
        "--dataset",
        dataset,
        "--out-dir",
        str(out_dir / name),
        *COMMON_FLAGS,
        *flags,
    ]


def run_step(command: list[str], folder: Path) -> float | None:
    """Trains one step unless its policy file exists (None: read, not run); the process's
    wall time, s. Raises SystemExit if training fails."""
    if (folder / "policy.npz").is_file():
        return None
    resume = ["--resume"] if (folder / "policy.pt").is_file() else []
    # this interpreter's mca-drake, whether or not its environment is activated
    cli = [sys.executable, "-m", "mca_drake.app.cli"]
    start = time.perf_counter()
    done = subprocess.run([*cli, *command, *resume, "--quiet"], check=False)
    if done.returncode != 0:
        raise SystemExit(f"train-policy failed ({done.returncode}): {shlex.join(command)}")
    return time.perf_counter() - start


def step_figures(folder: Path, command: list[str], process_wall_s: float | None) -> dict:
    """A finished step's command, curriculum steps (horizon, epochs, best epoch, wall s) and
    trainer wall time, read from its policy file's metadata."""
    _, metadata = load_policy_arrays(folder / "policy.npz")
    return {
        "stages": [
            {k: s[k] for k in ("horizon", "epochs", "best_epoch", "wall_s")}
            for s in metadata["stages"]
        ],
        "training_wall_s": metadata["training_wall_s"],
        "process_wall_s": process_wall_s,
        "command": "mca-drake " + shlex.join(command),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dataset", default="datasets/mixed_t37/dataset.npz")
    parser.add_argument("--styles-dataset", default="datasets/mixed_tr/dataset.npz")
    parser.add_argument("--default-styles-dataset", default="datasets/mixed_all/dataset.npz")
    parser.add_argument("--out-dir", default="results/recipe", help="the steps' folders")
    parser.add_argument("--json", default=default_result_path("training_recipe.json"))
    args = parser.parse_args()
    for dataset in (args.dataset, args.styles_dataset, args.default_styles_dataset):
        if not Path(dataset).is_file():
            raise SystemExit(
                f"dataset {dataset} not found: the training guide's recipe makes it "
                "(mca-drake dataset closed-loop, then dataset join)"
            )
    calibration = print_calibration()
    out_dir = Path(args.out_dir)
    steps = {}
    for name, extra in STEPS:
        dataset = getattr(args, STYLES_STEPS[name]) if name in STYLES_STEPS else args.dataset
        command = step_command(name, extra, dataset, out_dir)
        print(f"{name}: mca-drake {shlex.join(command)}", flush=True)
        steps[name] = step_figures(out_dir / name, command, run_step(command, out_dir / name))
        for stage in steps[name]["stages"]:
            print(
                f"  n_p {stage['horizon']}: {stage['epochs']} epochs (best {stage['best_epoch']}),"
                f" {stage['wall_s']:.0f} s"
            )
        print(f"  trainer wall time {steps[name]['training_wall_s']:.0f} s", flush=True)
    total = sum(s["training_wall_s"] for s in steps.values())
    target = sum(steps[name]["training_wall_s"] for name in TARGET_STEPS)
    met = "met" if target <= TARGET_WALL_S else "not met"
    print(
        f"recipe: {total:.0f} s ({total / 60:.1f} min); its first four steps "
        f"{target:.0f} s ({target / 60:.1f} min), target {TARGET_WALL_S / 60:.0f} min: {met}"
    )
    atomic_write_json(
        args.json,
        {
            "provenance": result_header(calibration),
            "dataset": args.dataset,
            "styles_dataset": args.styles_dataset,
            "default_styles_dataset": args.default_styles_dataset,
            "steps": steps,
            "training_wall_s_total": total,
            "target_steps": list(TARGET_STEPS),
            "training_wall_s_target_steps": target,
            "target_wall_s": TARGET_WALL_S,
        },
    )
    print(f"written to {args.json}")


if __name__ == "__main__":
    sys.exit(main())
