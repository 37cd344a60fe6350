"""Command-line flags derived from the typed configs, so that each default has one home.

A config dataclass carries a comment on every field (its meaning, unit and why); a flag made
by `add_config_flags` takes its help text from the first sentence of that comment and shows
the default of the config instance it is given. Flags default to None: only the flags a user
gives override the config (`given_fields`).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import inspect
import math
import re
import typing
from collections.abc import Mapping, Sequence

from mca_drake.atomic_io import check_writable
from mca_drake.platforms.files import DEFAULT_PLATFORM
from mca_drake.references.reference import ReferenceScaling

ADDRESS_HELP = (
    "run the tasks on this Ray cluster ('auto', 'ray://host:10001'; default: RAY_ADDRESS, "
    "else a local Ray with --workers CPUs); its nodes need mca-drake installed"
)
_FIELD = re.compile(r"^(\s*)(\w+)\s*:")


@functools.cache
def field_comments(config_class: type) -> dict[str, str]:
    """{field: the comment lines just above it, joined} of a dataclass's source."""
    lines = inspect.getsource(config_class).splitlines()
    # the body starts after the `class` line (decorators come before it)
    lines = lines[next(i for i, line in enumerate(lines) if line.lstrip().startswith("class ")) :]
    body_indent = None
    comments: dict[str, str] = {}
    pending: list[str] = []
    previous = ""
    for line in lines[1:]:
        stripped = line.strip()
        indent = len(line) - len(line.lstrip())
        if not stripped:
            pending, previous = [], ""
            continue
        if body_indent is None and not stripped.startswith(('"""', "'''")):
            body_indent = indent
        if indent != body_indent:
            continue
        if stripped.startswith("#"):
            pending.append(stripped.lstrip("#").strip())
        elif match := _FIELD.match(line):
            # fields listed right under one comment share it ("host" and "port")
            comments[match.group(2)] = " ".join(pending) or previous
            previous, pending = comments[match.group(2)], []
        else:
            pending, previous = [], ""
    return comments


def first_sentence(text: str) -> str:
    """The first sentence of a comment (up to '. ' or the end), without its full stop."""
    head = re.split(r"(?<=[a-z0-9)\]])\. ", text, maxsplit=1)[0]
    return head.rstrip(".")


def _format_default(value: object) -> str:
    if isinstance(value, float):
        return "inf" if math.isinf(value) else f"{value:g}"
    if isinstance(value, tuple | list):
        return ",".join(_format_default(v) for v in value) or "none"
    if value in ("", None):
        return "none"
    return str(value)


def _list_of(item_type: type, container: type = tuple):
    def parse(text: str):
        try:
            return container(item_type(v.strip()) for v in text.split(",") if v.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"comma-separated {item_type.__name__} values, not '{text}'"
            ) from None

    parse.__name__ = f"list of {item_type.__name__}"
    return parse


def _flag_type(annotation: object):
    """The argparse `type` of a field's annotation (None for text)."""
    if annotation in (int, float):
        return annotation
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (tuple, list) and args and args[0] in (int, float, str):
        return _list_of(args[0], origin)
    return None


def add_config_flags(
    parser: argparse.ArgumentParser,
    config: object,
    fields: Sequence[str] | Mapping[str, str],
    *,
    help_suffix: Mapping[str, str] | None = None,
) -> None:
    """Adds one flag per config field; the flag's value lands in `args.<field>`.

    Args:
        parser: the command's parser.
        config: an instance of a config dataclass; its values are the defaults shown.
        fields: field names (flag `--field-name`), or {field: flag} where a flag keeps a
            name of its own (`{"initial_policy": "--init-policy"}`).
        help_suffix: {field: text} added to the help (e.g. what 0 means).

    Raises:
        KeyError: a field the config does not have.
    """
    flags = fields if isinstance(fields, Mapping) else {f: "" for f in fields}
    comments = field_comments(type(config))
    hints = typing.get_type_hints(type(config))
    names = {f.name for f in dataclasses.fields(config)}
    for field, flag in flags.items():
        if field not in names:
            raise KeyError(f"{type(config).__name__} has no field '{field}'")
        default = getattr(config, field)
        text = first_sentence(comments.get(field, "")) or field.replace("_", " ")
        if text[:2].istitle():  # "Seed of ..." -> "seed of ...", but "NMPC ..." stays
            text = text[0].lower() + text[1:]
        extra = (help_suffix or {}).get(field, "")
        help_text = f"{text} (default {_format_default(default)}{'; ' + extra if extra else ''})"
        flag = flag or "--" + field.replace("_", "-")
        parser.add_argument(
            flag,
            dest=field,
            metavar=flag.lstrip("-").replace("-", "_").upper(),
            type=_flag_type(hints[field]),
            help=help_text.replace("%", "%%"),
        )


def given_fields(args: argparse.Namespace, fields: Sequence[str] | Mapping[str, str]) -> dict:
    """{field: value} of the fields whose flag was given (flags default to None)."""
    return {f: getattr(args, f) for f in fields if getattr(args, f, None) is not None}


def check_outputs(*paths) -> None:
    """Refuses, before any work, output files that cannot be written (None: not asked)."""
    for path in paths:
        if path:
            check_writable(path)


def add_quiet(parser: argparse.ArgumentParser) -> None:
    """The `--quiet` flag every long-running command has."""
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def add_platform_flag(parser: argparse.ArgumentParser) -> None:
    """--platform NAME_OR_FILE: a packaged platform (`mca-drake platforms`) or a file."""
    parser.add_argument(
        "--platform",
        help="the motion platform: a packaged name (mca-drake platforms) or a platform file "
        f"(default {DEFAULT_PLATFORM})",
    )


def add_comfort_flag(parser: argparse.ArgumentParser) -> None:
    """--max-force-change M: the cabin comfort bound (`mca_drake.comfort`)."""
    parser.add_argument(
        "--max-force-change",
        type=float,
        help="the cabin comfort bound: the largest change of the cabin's specific force in "
        "one control period, m/s^2 (a head jerk of M/0.01 s); held for every MCA, the "
        "joint limits first; counted in the summary's comfort block (default: none)",
    )


def add_trajectory_flag(parser: argparse.ArgumentParser) -> None:
    """--trajectory FILE.csv: the run's time series, one row per control period."""
    parser.add_argument(
        "--trajectory",
        help="write the run's time series to this CSV, one row per control period: t, "
        "ref_<ch> and cue_<ch> per channel, each joint's q, qd and qdd, what the input "
        "plausibility guard did (live: and the supervisor's health) (docs: "
        "concepts/metrics.md)",
    )


# ReferenceScaling fields with a flag (--angular-scale, --force-scale); the limits take --set.
SCALING_FLAGS = ("angular_scale", "force_scale")


def add_scaling_flags(parser: argparse.ArgumentParser) -> None:
    """--angular-scale S and --force-scale S: the scaling the MCA cues at
    (`references.reference.ReferenceScaling`; the run is scored at the default)."""
    add_config_flags(
        parser,
        ReferenceScaling(),
        SCALING_FLAGS,
        help_suffix={f: "the run is scored at the default" for f in SCALING_FLAGS},
    )


def apply_scaling_flags(args: argparse.Namespace, scaling: ReferenceScaling) -> None:
    """Sets the fields of `scaling` whose flag was given."""
    for field, value in given_fields(args, SCALING_FLAGS).items():
        setattr(scaling, field, value)
