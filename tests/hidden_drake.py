"""The preamble of a script run in a fresh interpreter in which pydrake cannot be found:
`find_spec` answers None for it and importing it fails, as where it is not installed."""

import json
import subprocess
import sys

HIDE_PYDRAKE = """
import importlib.util, json, sys
_find_spec = importlib.util.find_spec
def find_spec(name, *args, **kwargs):
    if name == "pydrake" or name.startswith("pydrake."):
        return None
    return _find_spec(name, *args, **kwargs)
importlib.util.find_spec = find_spec
sys.modules["pydrake"] = None
"""

# The script's last line: which pydrake modules it loaded after all (none, where it works).
PYDRAKE_LOADED = "sorted(m for m in sys.modules if m.startswith('pydrake.') and sys.modules[m])"


def run_without_drake(script: str, args: list[str], cwd) -> dict:
    """Runs HIDE_PYDRAKE + `script` with `args` in a fresh interpreter in `cwd`; the JSON
    object its last printed line holds."""
    done = subprocess.run(
        [sys.executable, "-c", HIDE_PYDRAKE + script, *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])
