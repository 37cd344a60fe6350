"""Flags derived from the typed configs: help from the field's comment, the default from the
config (one home), and a given flag overrides exactly its field."""

from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys

import pytest

from mca_drake.app import cli
from mca_drake.app.cli.flags import add_config_flags, field_comments, given_fields
from mca_drake.app.cli.training import POLICY_FLAGS, POLICY_TRAIN_FLAGS, command_line


@dataclasses.dataclass
class _Toy:
    """A config written as the project writes them."""

    # Simulated time, s. The second sentence is not part of the help.
    duration_s: float = 2.5
    # Address and port, shared by both fields.
    host: str = "127.0.0.1"
    port: int = 5500

    # Rollout lengths, steps.
    horizons: tuple[int, ...] = (32, 64)

    def validate(self) -> None:
        # a comment inside a method belongs to no field
        value: int = 3
        del value


def test_field_comments_reads_the_comment_above_each_field():
    comments = field_comments(_Toy)
    assert comments["duration_s"].startswith("Simulated time, s.")
    assert comments["port"] == comments["host"] == "Address and port, shared by both fields."
    assert comments["horizons"] == "Rollout lengths, steps."
    assert "value" not in comments


def _toy_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser()
    add_config_flags(parser, _Toy(), {"duration_s": "--duration", "port": "", "horizons": ""})
    return parser


def test_a_derived_flag_shows_the_comment_and_the_config_default():
    text = _toy_parser().format_help()
    assert "simulated time, s (default 2.5)" in " ".join(text.split())
    assert "(default 32,64)" in text and "second sentence" not in text


def test_given_flags_override_only_their_fields():
    args = _toy_parser().parse_args(["--duration", "4", "--horizons", "8,16"])
    given = given_fields(args, ("duration_s", "port", "horizons"))
    assert given == {"duration_s": 4.0, "horizons": (8, 16)}
    assert dataclasses.replace(_Toy(), **given) == _Toy(duration_s=4.0, horizons=(8, 16))


def test_a_bad_list_value_is_a_usage_error(capsys):
    with pytest.raises(SystemExit):
        _toy_parser().parse_args(["--horizons", "8,x"])
    assert "comma-separated int values" in capsys.readouterr().err


def test_an_unknown_field_is_refused():
    with pytest.raises(KeyError, match="no field 'nope'"):
        add_config_flags(argparse.ArgumentParser(), _Toy(), ["nope"])


def _subcommand(name: str) -> argparse.ArgumentParser:
    parser = cli.build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return commands.choices[name]


def test_train_policy_flags_fill_the_training_config():
    """Every train-policy flag derived from DpcTrainingConfig / TrainConfig shows that
    config's default, and a given flag lands in its field."""
    from mca_drake.learning.configs import DpcTrainingConfig

    defaults = DpcTrainingConfig()
    parser = _subcommand("train-policy")
    actions = {a.dest: a for a in parser._actions}
    for field in [*POLICY_FLAGS, *POLICY_TRAIN_FLAGS]:
        owner = defaults if field in POLICY_FLAGS else defaults.train
        value = getattr(owner, field)
        if isinstance(value, tuple):
            shown = ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
        elif isinstance(value, float):
            shown = f"{value:g}"
        else:
            shown = str(value) if value != "" else "none"
        assert actions[field].default is None, field  # unset flags leave the config alone
        assert f"(default {shown}" in actions[field].help, field
    args = parser.parse_args(["--mirror-fraction", "0.25", "--patience", "7", "--horizons", "9"])
    assert args.mirror_fraction == 0.25 and args.early_stopping_patience == 7
    assert args.horizons == (9,)


def test_the_command_line_starts_without_torch():
    """Every command's flags, the training ones included, are built without loading torch:
    only a training command's run loads it."""
    code = (
        "import sys\n"
        "from mca_drake.app.cli import build_parser\n"
        "build_parser().parse_args(['train-policy', '--horizons', '256'])\n"
        "print('torch' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_the_recorded_training_command_names_mca_drake_however_it_was_started():
    """The command a policy file records: the same from the installed script and from
    `python -m mca_drake.app.cli` (the recipe benchmark's way), an argument with a space
    quoted so that it pastes back; nothing when training was called from Python."""
    args = ["train-policy", "--out-dir", "my runs/a", "--seed", "1"]
    expected = "mca-drake train-policy --out-dir 'my runs/a' --seed 1"
    assert command_line(["/venv/bin/mca-drake", *args]) == expected
    assert command_line(["/src/mca_drake/app/cli/__main__.py", *args]) == expected
    assert command_line(["/usr/lib/python3/site-packages/pytest/__main__.py", *args]) == ""
    assert command_line(["-c"]) == ""
