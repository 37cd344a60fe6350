#!/usr/bin/env bash
# Creates .venv (if missing) and installs mca-drake in editable mode with its dev and docs tools.
# torch is pinned by constraints.txt to the CPU build (an unpinned torch pulls CUDA wheels).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PYTHON" -m venv .venv
fi
.venv/bin/python -m pip install --quiet --disable-pip-version-check -c constraints.txt -e ".[dev,docs]"
