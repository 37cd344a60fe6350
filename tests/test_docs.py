"""The documentation against the code: generated tables cover what the code knows, every
page is reachable from the front pages, every command line in the docs parses, and the
examples run and print what the docs show.

Oracles: the code's own registries (scenario dataclasses, MCA names, protocols, packaged
platforms, scenarios and notebooks), mkdocs.yml's navigation, the `mca-drake` parser, and
the outputs the docs print beside their examples."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from mca_drake.app import cli
from mca_drake.app.scenarios import Scenario
from mca_drake.cueing import MCA_NAMES
from mca_drake.live.decoders import PROTOCOLS
from mca_drake.platforms.files import packaged_platforms
from mca_drake.references.vehicle_signals import SIGNALS
from mca_drake.resources import packaged_scenarios

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
PAGES = sorted(DOCS.rglob("*.md"))


def _hook():
    spec = importlib.util.spec_from_file_location(
        "generated_tables", DOCS / "hooks" / "generated_tables.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


HOOK = _hook()


def _markers() -> dict[tuple[str, ...], list[Path]]:
    found: dict[tuple[str, ...], list[Path]] = {}
    for page in PAGES:
        for match in HOOK.MARKER.finditer(page.read_text()):
            key = (match.group(1), *match.group(2).split())
            found.setdefault(key, []).append(page)
    return found


MARKERS = _markers()


def test_every_marker_renders_a_table():
    assert MARKERS, "no generated tables in the docs"
    for (kind, *arguments), pages in MARKERS.items():
        table = HOOK.render(kind, tuple(arguments))
        assert table.count("\n|") >= 2, (kind, arguments, pages)


@pytest.mark.parametrize(
    ("marker", "page", "names"),
    [
        (("scenario-files",), "guides/scenarios.md", [f"`{n}.yaml`" for n in packaged_scenarios()]),
        (("mca-names",), "concepts/mcas.md", [f"`{n}`" for n in MCA_NAMES]),
        (("protocols",), "guides/live.md", [f"`{p}`" for p in PROTOCOLS]),
        (("platforms",), "concepts/platforms.md", [f"`{p}`" for p in packaged_platforms()]),
        (("signals",), "concepts/plant-output.md", [f"`{name}`" for name in SIGNALS]),
        (
            ("notebooks",),
            "getting-started.md",
            [f"`notebooks/{p.name}`" for p in (REPO / "notebooks").glob("*.ipynb")],
        ),
        (
            ("scenario-types",),
            "guides/scenarios.md",
            [f"`!{cls.__name__}`" for cls in Scenario.__args__],
        ),
    ],
)
def test_a_list_the_code_knows_is_on_its_page_whole(marker, page, names):
    assert DOCS / page in MARKERS.get(marker, []), f"{page} lost its {marker} table"
    table = HOOK.render(marker[0], marker[1:])
    assert names and all(name in table for name in names), [n for n in names if n not in table]


def test_every_scenario_field_is_documented():
    """Each scenario's table of fields is on the scenarios page, with every field."""
    for cls in [*Scenario.__args__, "SuiteCase", "FlightSpec", "DriveSpec", "ReferenceScaling"]:
        name = cls if isinstance(cls, str) else cls.__name__
        assert DOCS / "guides/scenarios.md" in MARKERS.get(("fields", name), []), name
        table = HOOK.render("fields", (name,))
        fields = dataclasses.fields(HOOK.config_class(name))
        missing = [f.name for f in fields if f"| `{f.name}` |" not in table]
        assert not missing, (name, missing)


def test_a_flag_table_holds_every_flag_of_its_command():
    parser = cli.build_parser()
    for (kind, *command), _ in MARKERS.items():
        if kind != "flags":
            continue
        table = HOOK.render(kind, tuple(command))
        sub = parser
        for name in command:
            sub = next(a for a in sub._actions if hasattr(a, "choices") and a.choices).choices[name]
        for action in sub._actions:
            for flag in action.option_strings:
                if flag.startswith("--") and flag != "--help":
                    assert f"`{flag}" in table, (command, flag)


def _nav_pages(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    if isinstance(node, list):
        return [p for item in node for p in _nav_pages(item)]
    return [p for value in node.values() for p in _nav_pages(value)]


def test_the_front_pages_link_every_page_of_the_site():
    config = yaml.load((REPO / "mkdocs.yml").read_text(), Loader=yaml.BaseLoader)
    pages = [
        p
        for p in _nav_pages(config["nav"])
        if not p.startswith(("reference/api/", "decisions/")) and p != "index.md"
    ]
    index, readme = (DOCS / "index.md").read_text(), (REPO / "README.md").read_text()
    assert [p for p in pages if f"]({p}" not in index] == []
    assert [p for p in pages if f"](docs/{p}" not in readme and p != "changelog.md"] == []


def test_links_to_generated_pages_resolve_in_the_repository():
    """A relative link of a page to another .md file names a file that exists (generated
    pages keep a placeholder in the repository)."""
    broken = []
    for page in [*PAGES, REPO / "README.md"]:
        for target in re.findall(r"\]\(([^)#\s]+\.md)(?:#[^)]*)?\)", page.read_text()):
            if "://" not in target and not (page.parent / target).resolve().is_file():
                broken.append((page.relative_to(REPO), target))
    assert broken == []


def _blocks(language: str):
    for page in [*PAGES, REPO / "README.md"]:
        text = page.read_text()
        for match in re.finditer(rf"```{language}\n(.*?)```", text, flags=re.S):
            yield page, match.group(1)


def _command_lines(block: str):
    """The `mca-drake ...` command lines of a shell block (continuations joined)."""
    for line in block.replace("\\\n", " ").splitlines():
        line = line.split(" #")[0].strip()
        if line.startswith("$ "):
            line = line[2:]
        for part in re.split(r"\s*(?:&&|;|\|)\s*", line):
            part = part.strip().removesuffix("&").strip()  # a command sent to the background
            if part.startswith(("mca-drake ", ".venv/bin/mca-drake ")):
                yield part


def test_every_command_line_in_the_docs_parses():
    parser = cli.build_parser()
    checked, refused = 0, []
    for page, block in [*_blocks("bash"), *_blocks("text")]:
        for line in _command_lines(block):
            if "$(" in line or "..." in line:  # a shell substitution or an elided part
                continue
            words = shlex.split(line)[1:]
            try:
                parser.parse_args(words)
            except SystemExit:
                refused.append((page.relative_to(REPO), line))
            checked += 1
    assert checked > 50 and refused == []


# Python examples that cannot run in a test, and why.
NOT_RUN = {
    "guides/driving.md": "waits for a racing game's packets on a UDP port",
    "guides/rsi.md": "drives a KUKA controller at a real address",
    "guides/perceived-motion.md#0": "reads the runs of an earlier comparison (results/compare)",
    "guides/perceived-motion.md#1": "reads the runs of an earlier suite (results/evaluation)",
    "guides/perceived-motion.md#2": "two 60 s NMPC runs (the same calls run in the notebook)",
    "concepts/optimal-bound.md": "a 60 s bound takes minutes (test_optimal solves short ones)",
    "README.md": "tests/test_readme.py runs it",
}
# Shrinks for the test run: simulated seconds of the examples' flights.
SHRINK = [
    (
        'FlightSpec(vehicle="light", seed=1000), 60.0)',
        'FlightSpec(vehicle="light", seed=1000), 3.0)',
    ),
    ("duration_s=120.0", "duration_s=10.0"),
]


def _python_examples():
    counts: dict[Path, int] = {}
    for page, code in _blocks("python"):
        index = counts.get(page, 0)
        counts[page] = index + 1
        name = str(page.relative_to(DOCS if page.is_relative_to(DOCS) else REPO))
        if name in NOT_RUN or f"{name}#{index}" in NOT_RUN:
            continue
        yield pytest.param(code, id=f"{name}#{index}")


def _expected_outputs(code: str) -> list[str]:
    """The outputs a block shows: the `# ` comment lines right after a print, joined."""
    expected, lines = [], code.splitlines()
    for i, line in enumerate(lines):
        if line.startswith("print(") and i + 1 < len(lines) and lines[i + 1].startswith("# "):
            shown = []
            for following in lines[i + 1 :]:
                if not following.startswith("#"):
                    break
                shown.append(following.lstrip("#").strip())
            expected.append(" ".join(shown))
    return expected


@pytest.mark.parametrize("code", list(_python_examples()))
def test_a_python_example_runs_and_prints_what_the_docs_show(code, tmp_path):
    for old, new in SHRINK:
        code = code.replace(old, new)
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600
    )
    assert result.returncode == 0, result.stderr[-2000:]
    printed = " ".join(result.stdout.split())
    for shown in _expected_outputs(code):
        assert " ".join(shown.split()) in printed, (shown, result.stdout)


def _shown_runs():
    for page, block in _blocks("text"):
        lines = block.splitlines()
        if lines and lines[0].startswith("$ mca-drake"):
            yield pytest.param(lines, id=str(page.relative_to(DOCS)))


@pytest.mark.parametrize("lines", list(_shown_runs()))
def test_a_shown_command_prints_what_the_docs_show(lines, tmp_path):
    """A `$ mca-drake ...` block: the command's output (stdout and stderr), line by line up
    to an elision ("..."), is the block's."""
    command = shlex.split(lines[0][2:])
    command[0] = str(Path(sys.executable).with_name("mca-drake"))
    command = [str(REPO / w) if w.startswith("diagrams/") else w for w in command]
    result = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    shown = [line for line in lines[1:] if line.strip()]
    if "..." in shown:
        shown = shown[: shown.index("...")]
    output = [
        line.replace(str(REPO) + "/", "")
        for line in (result.stdout + result.stderr).splitlines()
        if line.strip()
    ]
    assert output[: len(shown)] == shown
