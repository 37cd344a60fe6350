"""MkDocs hook: the decision records, listed in the navigation and on their index page.

Every file docs/decisions/NNNN-title.md is a record. The hook puts them all, in number order,
into the navigation's "Decisions" section after its index page, and replaces the marker
`<!-- decision-records -->` of docs/decisions/index.md with a list of links, each titled by
the record's first heading. A record added later needs no edit anywhere else.
"""

from __future__ import annotations

import re
from pathlib import Path

from mkdocs.exceptions import PluginError

SECTION = "Decisions"
FOLDER = "decisions"
INDEX = f"{FOLDER}/index.md"
MARKER = "<!-- decision-records -->"
_RECORD = re.compile(r"^\d{4}-[a-z0-9-]+\.md$")


def _records(docs_dir: Path) -> list[Path]:
    return sorted(p for p in (docs_dir / FOLDER).glob("*.md") if _RECORD.match(p.name))


def _title(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    raise PluginError(f"decisions hook: {path} has no '# ' title line")


def on_config(config):
    """Lists every record in the navigation's Decisions section, after its index."""
    docs_dir = Path(config.docs_dir)
    for item in config.nav or []:
        if isinstance(item, dict) and SECTION in item:
            item[SECTION] = [INDEX] + [f"{FOLDER}/{p.name}" for p in _records(docs_dir)]
            return config
    raise PluginError(f"decisions hook: mkdocs.yml's nav has no '{SECTION}' section")


def on_page_markdown(markdown, page, config, files):
    """Fills the index page's list of records."""
    if page.file.src_uri != INDEX:
        return markdown
    if MARKER not in markdown:
        raise PluginError(f"decisions hook: docs/{INDEX} lacks the marker {MARKER}")
    records = _records(Path(config.docs_dir))
    listing = "\n".join(f"- [{_title(p)}]({p.name})" for p in records) or "No records yet."
    return markdown.replace(MARKER, listing)
