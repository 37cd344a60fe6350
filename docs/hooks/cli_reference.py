"""MkDocs hook: the command-line reference page, generated from the `mca-drake` parser.

At build time it walks `mca_drake.app.cli.build_parser()` and its sub-parsers, recursively,
and adds `reference/cli.md` to the build: for every command its usage, its help and
description, and every argument with its flags, help text, choices and default. Only the
entry point `build_parser` and argparse's own structures are used (`parser._actions`,
`argparse._SubParsersAction`), so the page follows the parser wherever its commands live.
Nothing is written to docs/: the committed page there is a placeholder for readers of the
repository, replaced in the build.
"""

from __future__ import annotations

import argparse
import html
import importlib
import sys
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File

PAGE = "reference/cli.md"
# Usage lines are wrapped at this width, whatever the terminal that builds the site.
USAGE_WIDTH = 88

_MARKDOWN_SPECIALS = "\\`*_[]|"


def _cell(text: str) -> str:
    """`text` as plain text inside a Markdown table cell (one line, specials escaped)."""
    text = html.escape(" ".join(text.split()), quote=False)
    for char in _MARKDOWN_SPECIALS:
        text = text.replace(char, "\\" + char)
    return text


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """An argument's help as `--help` prints it (argparse's %-expansion, e.g. %(default)s)."""
    if not action.help:
        return ""
    params = dict(vars(action), prog=parser.prog)
    for name in list(params):
        if params[name] is argparse.SUPPRESS:
            del params[name]
        elif hasattr(params[name], "__name__"):
            params[name] = params[name].__name__
    if params.get("choices") is not None:
        params["choices"] = ", ".join(str(c) for c in params["choices"])
    try:
        return action.help % params
    except (KeyError, TypeError, ValueError) as error:
        flag = "/".join(action.option_strings) or action.dest
        raise PluginError(
            f"cli_reference hook: the help of {parser.prog} {flag} does not format "
            f"({error!r}); `{parser.prog} --help` fails the same way"
        ) from error


def _usage(parser: argparse.ArgumentParser) -> str:
    formatter = parser.formatter_class(prog=parser.prog, width=USAGE_WIDTH)
    formatter.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups)
    return formatter.format_help().strip()


def _flags(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """The argument as `--help` lists it: `--plant {analytical,multibody}`, `recording`."""
    invocation = parser._get_formatter()._format_action_invocation(action)
    return ", ".join(f"`{part}`" for part in invocation.split(", "))


def _default(action: argparse.Action) -> str:
    if isinstance(action, argparse._StoreTrueAction | argparse._StoreFalseAction):
        return "off" if not action.default else "on"
    if action.default is None or action.default is argparse.SUPPRESS or action.required:
        return ""
    return f"`{action.default}`"


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """(name, help, parser) of the parser's sub-commands, in the order they were added."""
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help or "" for choice in action._choices_actions}
            for name, sub in action.choices.items():
                found.append((name, helps.get(name, ""), sub))
    return found


def arguments_table(parser: argparse.ArgumentParser) -> list[str]:
    """The Markdown table lines of a parser's arguments: flags, help, choices, default."""
    rows = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
            continue
        choices = ""
        if action.choices is not None:
            choices = ", ".join(f"`{c}`" for c in action.choices)
        required = " (required)" if action.required and action.option_strings else ""
        rows.append(
            f"| {_flags(parser, action)}{required} | {_cell(_help(parser, action))} | {choices} "
            f"| {_default(action)} |"
        )
    if not rows:
        return []
    return ["| argument | help | choices | default |", "|---|---|---|---|", *rows, ""]


def _command_section(
    parser: argparse.ArgumentParser, path: list[str], summary: str, level: int
) -> list[str]:
    lines = [f"{'#' * level} {' '.join(path)}", ""]
    for text in dict.fromkeys(t for t in (summary, parser.description) if t):
        lines += [_cell(text), ""]
    lines += ["```text", _usage(parser), "```", ""]
    lines += arguments_table(parser)
    subcommands = _subcommands(parser)
    if subcommands:
        lines += ["Commands:", ""]
        lines += [
            f"- [`{' '.join([*path, name])}`](#{_anchor([*path, name])}): {_cell(help_text)}"
            for name, help_text, _ in subcommands
        ]
        lines.append("")
        for name, help_text, sub in subcommands:
            lines += _command_section(sub, [*path, name], help_text, min(level + 1, 6))
    return lines


def _anchor(path: list[str]) -> str:
    """The id Python-Markdown's toc gives the heading of command `path`."""
    return "-".join(path).lower()


def render_cli_reference(parser: argparse.ArgumentParser) -> str:
    """The Markdown of the command-line reference for `parser`."""
    lines = [
        "# Command line",
        "",
        "Generated from the parser of the `mca-drake` command when this site was built; "
        "`mca-drake COMMAND --help` prints the same. Flags that show no default leave the "
        "value to the typed configuration they fill (a scenario's or an MCA's dataclass), "
        "whose default the help text names.",
        "",
    ]
    lines += _command_section(parser, [parser.prog], "", 2)
    return "\n".join(lines).rstrip() + "\n"


def _load_parser(root: Path) -> argparse.ArgumentParser:
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    try:
        cli = importlib.import_module("mca_drake.app.cli")
    except Exception as error:
        raise PluginError(
            f"cli_reference hook: cannot import mca_drake.app.cli ({error}); build the site "
            "with the project's environment (.venv/bin/mkdocs)"
        ) from error
    return cli.build_parser()


def on_files(files, config):
    """Adds the generated `reference/cli.md` to the build."""
    # the committed page is a placeholder for readers of the repository: the build's replaces it
    placeholder = files.get_file_from_path(PAGE)
    if placeholder is not None:
        files.remove(placeholder)
    root = Path(config.config_file_path).resolve().parent
    content = render_cli_reference(_load_parser(root))
    files.append(File.generated(config, PAGE, content=content))
    return files
