"""The `mca-drake` command: one module per command, each parsing its flags and calling one
library function; flags that set a typed config's field are derived from that config
(`flags.add_config_flags`), so every default has one home.

    simulate       simulate.py      the main job: a closed loop with a readable result table
    run            run.py           any scenario, from a YAML file or a packaged name
    flight, drive, plot-recording   recordings.py
    dataset        dataset.py       open-loop, closed-loop, join
    evaluate       evaluate.py      one recording, or the evaluation suite
    tune           tune.py          Ray Tune + Optuna over an MCA's config
    live           live.py          real-time cueing of UDP telemetry (and a robot over RSI)
    platforms      platforms.py     the packaged motion platforms, or one platform file
    train-policy, export-policy, table2   training.py (torch)
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from mca_drake import __version__
from mca_drake.app.cli import platforms, training
from mca_drake.resources import drake_installed

# The torch commands need no Drake: on a machine without pydrake (a GPU box for training
# searches) `mca-drake` offers them alone and says why the others are missing.
HAS_DRAKE = drake_installed()
if HAS_DRAKE:
    from mca_drake.app.cli import (
        dataset,
        evaluate,
        live,
        optimal,
        recordings,
        run,
        simulate,
        tune,
    )


def build_parser() -> argparse.ArgumentParser:
    """The ``mca-drake`` argument parser: one sub-command per job (see ``--help``)."""
    description = "Motion cueing for motion simulators (serial robots, rails), on Drake."
    if not HAS_DRAKE:
        description += " pydrake is not installed: only the torch commands are offered."
    parser = argparse.ArgumentParser(prog="mca-drake", description=description)
    parser.add_argument("--version", action="version", version=f"mca-drake {__version__}")
    parser.add_argument(
        "--debug", action="store_true", help="show the traceback of an error (for reports)"
    )
    commands = parser.add_subparsers(dest="command", required=True)
    if HAS_DRAKE:
        simulate.add_parser(commands)
        run.add_parser(commands)
        recordings.add_parsers(commands)
        dataset.add_parser(commands)
        evaluate.add_parser(commands)
        optimal.add_parser(commands)
        tune.add_parser(commands)
        live.add_parser(commands)
    platforms.add_parser(commands)
    training.add_parsers(commands)
    return parser


# The longest error line printed: a message quoting a huge input is cut, with its length said.
MAX_ERROR_CHARS = 600


def error_line(err: BaseException) -> str:
    """`err` as one printable line: whitespace collapsed, control characters (a NUL byte
    from a damaged file) escaped, cut to MAX_ERROR_CHARS."""
    text = " ".join(str(err).split()) or type(err).__name__
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    if len(text) > MAX_ERROR_CHARS:
        text = f"{text[:MAX_ERROR_CHARS]}... ({len(text)} characters)"
    return text


# Errors a user can act on from the message alone (bad input, a missing or unwritable file,
# a run that cannot go on); anything else is a bug, reported with a pointer to --debug.
_USER_ERRORS = (ValueError, OSError, RuntimeError)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `mca-drake` console script.

    Every error ends as one line on stderr and exit status 2 (130 when interrupted), never a
    traceback; `--debug` shows the traceback instead.
    """
    args = build_parser().parse_args(argv)
    np.set_printoptions(precision=4, suppress=True)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("mca-drake: interrupted (finished result files are kept)", file=sys.stderr)
        return 130
    except Exception as err:
        if args.debug:
            raise
        message = error_line(err)
        if not isinstance(err, _USER_ERRORS):
            message = (
                f"{type(err).__name__}: {message} (unexpected: rerun with --debug for the "
                "traceback and report it)"
            )
        print(f"mca-drake: error: {message}", file=sys.stderr)
        return 2
