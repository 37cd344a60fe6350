"""The README's front page: its Python example runs as printed, and its length stays that
of a front page."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def _section(title: str) -> str:
    text = README.read_text()
    start = text.index(f"## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end > 0 else None]


def test_the_readme_is_a_front_page():
    assert len(README.read_text().splitlines()) <= 150
    assert "session" not in README.read_text().lower()


def test_the_readme_example_runs_and_prints_the_pi_of_each_mca(tmp_path):
    (code,) = re.findall(r"```python\n(.*?)```", _section("A short example"), flags=re.S)
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True
    )
    lines = [line.split() for line in result.stdout.splitlines()]
    assert [line[0] for line in lines] == ["dpc", "nmpc-rti"]
    for _, pi, pi_zero_motion in lines:
        # each MCA cues better than not moving at all (PI lower than zero motion's)
        assert float(pi) < float(pi_zero_motion)
