#!/usr/bin/env bash
# Builds the documentation site (mkdocs.yml) into site/, warnings as errors: the CLI and API
# references and the results page are generated from the code and benchmarks/results/.
# Extra arguments go to mkdocs (e.g. `-d /tmp/site`). Expects .venv from scripts/setup.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
# (NO_MKDOCS_2_WARNING: the theme's banner about its successor is not a warning of this site)
NO_MKDOCS_2_WARNING=1 exec .venv/bin/mkdocs build --strict "$@"
