#!/usr/bin/env bash
# Set up, check lint and format, then run the default test suite (no `slow` tests).
# Extra arguments go to pytest (e.g. `-m slow`). Exits non-zero if no test ran.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check .
.venv/bin/ruff format --check .
set +e
.venv/bin/python -m pytest -m "not slow" "$@"
status=$?
set -e
if [ "$status" -eq 5 ]; then
  echo "error: pytest collected no tests" >&2
  exit 1
fi
exit "$status"
