"""MkDocs hook: tables the code knows, generated into the pages that show them.

A page asks for a table with a marker line, `<!-- generated: KIND ARGUMENTS -->`, which the
build replaces with the table (the marker is an HTML comment, so the page read in the
repository shows nothing in its place). Kinds:

    flags COMMAND [SUBCOMMAND]  the flags of `mca-drake COMMAND` (its --help, as a table)
    scenario-files              the packaged scenario files and the job of each
    scenario-types              each scenario tag and its fields
    fields CLASS                one config dataclass's fields: default and meaning (a class
                                `mca_drake.app.scenarios` names: a scenario, FlightSpec,
                                DriveSpec, ReferenceScaling, StationConfig, ...)
    mca-names                   the MCA names `--mca` takes and the config each stands for
    protocols                   the live telemetry protocols and their vehicle kind
    platforms                   the packaged motion platforms
    notebooks                   the notebooks and what each shows

`render(kind, arguments)` gives one table's Markdown (the tests read it); an unknown kind
or class fails the build.
"""

from __future__ import annotations

import dataclasses
import html
import importlib
import importlib.util
import json
import re
import sys
from pathlib import Path

from mkdocs.exceptions import PluginError

ROOT = Path(__file__).resolve().parents[2]
MARKER = re.compile(r"^<!-- generated: ([a-z-]+)((?: [\w.-]+)*) -->$", re.MULTILINE)
_MARKDOWN_SPECIALS = "\\`*_[]|"


def _code():
    """The modules the tables read, imported from this checkout."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    return importlib.import_module("mca_drake")


def _cell(text: str) -> str:
    """`text` as plain text in a table cell (one line, Markdown specials escaped)."""
    text = html.escape(" ".join(str(text).split()), quote=False)
    for char in _MARKDOWN_SPECIALS:
        text = text.replace(char, "\\" + char)
    return text


def _prose(text: str) -> str:
    """Prose in a table cell: `code` spans kept as code, the rest as plain text."""
    parts = " ".join(str(text).split()).split("`")
    if len(parts) % 2 == 0:  # an unpaired backtick: all plain text
        return _cell(text)
    return "".join(_cell(p) if i % 2 == 0 else _code_cell(p) for i, p in enumerate(parts))


def _code_cell(text: str) -> str:
    """`text` as inline code in a table cell (pipes escaped, as tables need)."""
    return "`" + str(text).replace("|", "\\|") + "`"


def _table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def _cli_reference():
    """The sibling hook that renders the command-line reference (its argument tables)."""
    spec = importlib.util.spec_from_file_location(
        "mca_drake_docs_cli_reference", Path(__file__).with_name("cli_reference.py")
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def flags_table(*command: str) -> str:
    """The arguments of `mca-drake COMMAND [SUBCOMMAND]`."""
    _code()
    cli = importlib.import_module("mca_drake.app.cli")
    reference = _cli_reference()
    parser = cli.build_parser()
    for name in command:
        found = {n: sub for n, _, sub in reference._subcommands(parser)}
        if name not in found:
            raise PluginError(f"generated flags: no command {' '.join(command)!r}")
        parser = found[name]
    return "\n".join(reference.arguments_table(parser)).rstrip()


def _default_text(field: dataclasses.Field) -> str:
    if field.default is not dataclasses.MISSING:
        value = field.default
    elif field.default_factory is not dataclasses.MISSING:
        value = field.default_factory()
    else:
        return "(required)"
    if dataclasses.is_dataclass(value):
        return f"`!{type(value).__name__}` defaults"
    if isinstance(value, list) and value and dataclasses.is_dataclass(value[0]):
        return f"{len(value)} entries"
    if isinstance(value, str):
        return _code_cell(json.dumps(value))
    if value is None:
        return "`null`"
    if isinstance(value, bool):
        return _code_cell(str(value).lower())
    if isinstance(value, tuple):
        value = list(value)
    if not isinstance(value, int | float | list):
        return f"`{type(value).__name__}` defaults"  # a config of Drake's own
    return _code_cell(value)


def config_class(name: str) -> type:
    """A config dataclass that `mca_drake.app.scenarios` names (imported there)."""
    _code()
    scenarios = importlib.import_module("mca_drake.app.scenarios")
    cls = getattr(scenarios, name, None)
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise PluginError(f"generated fields: {name!r} is no dataclass of the scenarios")
    return cls


def fields_table(name: str) -> str:
    """One dataclass's fields: name, default, meaning (the comment above each field)."""
    cls = config_class(name)
    flags = importlib.import_module("mca_drake.app.cli.flags")
    comments = flags.field_comments(cls)
    rows = [
        (_code_cell(f.name), _default_text(f), _prose(comments.get(f.name, "")))
        for f in dataclasses.fields(cls)
    ]
    return _table(("field", "default", "meaning"), rows)


def scenario_types_table() -> str:
    """Each scenario's tag, what it runs and its fields."""
    _code()
    scenarios = importlib.import_module("mca_drake.app.scenarios")
    rows = []
    for cls in scenarios.Scenario.__args__:
        doc = (cls.__doc__ or "").strip().split("\n\n")[0]
        fields = ", ".join(_code_cell(f.name) for f in dataclasses.fields(cls))
        rows.append((_code_cell(f"!{cls.__name__}"), _prose(doc), fields))
    return _table(("tag", "job", "fields"), rows)


def _header_comment(path: Path) -> tuple[str, str]:
    """(the job a scenario file's header comment describes, its scenario tag)."""
    job, tag = [], ""
    for line in path.read_text().splitlines():
        if line.startswith("scenario:"):
            tag = line.split("!", 1)[1].split()[0] if "!" in line else ""
            break
        text = line.lstrip("#").strip()
        if text.startswith("Run:") or (job and not text) or line.startswith("#      "):
            continue
        job.append(text)
    return " ".join(job), tag


def scenario_files_table() -> str:
    """The packaged scenario files: name, tag and job (their header comments)."""
    _code()
    resources = importlib.import_module("mca_drake.resources")
    rows = []
    for name, path in sorted(resources.packaged_scenarios().items()):
        job, tag = _header_comment(path)
        rows.append((_code_cell(f"{name}.yaml"), _code_cell(f"!{tag}"), _prose(job)))
    return _table(("file", "scenario", "job"), rows)


def _summary(text: str) -> str:
    """A docstring's first paragraph, on one line."""
    return " ".join((text or "").strip().split("\n\n")[0].split())


def mca_names_table() -> str:
    """The MCA names (`--mca`, a scenario's `mca: NAME`) and the config each stands for."""
    _code()
    cueing = importlib.import_module("mca_drake.cueing")
    resources = importlib.import_module("mca_drake.resources")
    rows = []
    names = list(cueing.MCA_NAMES)
    names += [f"{n}-{p}" for p in resources.PROFILES for n in ("dpc", "nmpc-rti", "washout")]
    for name in names:
        config = cueing.mca_config_from_name(name)
        differs = {
            f.name: getattr(config, f.name)
            for f in dataclasses.fields(config)
            if f.name in ("mode", "objective", "profile", "preview_steps", "predictor")
            and getattr(config, f.name)
        }
        spelt = ", ".join(f"{k}: {v}" for k, v in differs.items())
        tag = f"!{type(config).__name__}" + (f" {{{spelt}}}" if spelt else "")
        rows.append((_code_cell(name), _code_cell(tag), _prose(_summary(type(config).__doc__))))
    return _table(("name", "config", "what it is"), rows)


def protocols_table() -> str:
    """The live telemetry protocols (`--protocol`), their decoder and vehicle kind."""
    _code()
    decoders = importlib.import_module("mca_drake.live.decoders")
    rows = []
    for protocol in decoders.PROTOCOLS:
        decoder = decoders.make_decoder(protocol, xplane_version=12)
        kind = getattr(decoder, "vehicle", "") or "not named: recognized from the motion"
        rows.append(
            (
                _code_cell(protocol),
                _prose(_summary(type(decoder).__doc__)),
                _cell(kind),
            )
        )
    return _table(("protocol", "what it reads", "vehicle kind"), rows)


def _file_comment(path: Path) -> str:
    """The first sentence of a file's header comment (the lines before its first other)."""
    lines = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("#").strip())
    text = " ".join(" ".join(lines).split())
    return re.split(r"(?<=[a-z0-9)])\. (?=[A-Z])", text, maxsplit=1)[0].rstrip(".")


def platforms_table() -> str:
    """The packaged motion platforms (`--platform NAME`): kind, coordinates, what it is
    (the platform file's header comment)."""
    _code()
    files = importlib.import_module("mca_drake.platforms.files")
    records = importlib.import_module("mca_drake.app.cli.platforms").platform_records
    paths = files.packaged_platforms()
    rows = []
    for record in records(list(paths)):
        joints = ", ".join(j["name"] for j in record["joints"])
        rows.append(
            (
                _code_cell(record["name"]),
                _cell(record["kind"]),
                _cell(joints),
                _cell(_file_comment(Path(paths[record["name"]]))),
            )
        )
    return _table(("name", "kind", "coordinates", "what it is"), rows)


def notebooks_table() -> str:
    """The notebooks in notebooks/ and the title of each (its first heading)."""
    rows = []
    for path in sorted((ROOT / "notebooks").glob("*.ipynb")):
        cells = json.loads(path.read_text())["cells"]
        title = ""
        for cell in cells:
            if cell["cell_type"] == "markdown":
                lines = "".join(cell["source"]).strip().splitlines()
                title = lines[0].lstrip("# ").strip() if lines else ""
                break
        rows.append((_code_cell(f"notebooks/{path.name}"), _cell(title)))
    return _table(("notebook", "what it shows"), rows)


def signals_table() -> str:
    """The optional control and state columns of a recording, their SI unit and meaning."""
    _code()
    signals = importlib.import_module("mca_drake.references.vehicle_signals")
    rows = []
    for name, (unit, meaning) in signals.SIGNALS.items():
        others = [u for u in signals.SIGNAL_UNITS[unit] if u and u != unit]
        units = unit if unit != "1" else "(none)"
        if others:
            units += f" (or {', '.join(others)})"
        rows.append((_code_cell(name), _cell(units), _cell(meaning)))
    return _table(("column", "unit", "what it is"), rows)


RENDERERS = {
    "flags": flags_table,
    "scenario-files": scenario_files_table,
    "scenario-types": scenario_types_table,
    "fields": fields_table,
    "mca-names": mca_names_table,
    "protocols": protocols_table,
    "platforms": platforms_table,
    "notebooks": notebooks_table,
    "signals": signals_table,
}


def render(kind: str, arguments: tuple[str, ...] = ()) -> str:
    """The Markdown of one generated table."""
    if kind not in RENDERERS:
        raise PluginError(f"generated: unknown kind {kind!r}; valid: {', '.join(RENDERERS)}")
    return RENDERERS[kind](*arguments)


def expand(markdown: str) -> str:
    """`markdown` with every marker replaced by its table."""
    return MARKER.sub(lambda m: render(m.group(1), tuple(m.group(2).split())), markdown)


def on_page_markdown(markdown, page, config, files):
    """Replaces the page's markers with their tables."""
    return expand(markdown)
