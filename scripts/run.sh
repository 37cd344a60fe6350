#!/usr/bin/env bash
# The main job: set up, then run the default closed-loop motion-cueing simulation.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/mca-drake simulate "$@"
