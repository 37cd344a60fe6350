#!/usr/bin/env bash
# Builds the wheel, installs it (not editable) into a fresh virtual environment and runs, from
# an empty folder, the main job (`mca-drake simulate --duration 2`) and a packaged scenario
# (`mca-drake run plant_demo`): the package must run without its source checkout.
# Prints the wheel's size and its non-Python files. WHEEL_ENV names the environment's folder.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
PYTHON=${PYTHON:-python3}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
ENV=${WHEEL_ENV:-$WORK/venv}
"$PYTHON" -m pip wheel --quiet --disable-pip-version-check --no-deps . -w "$WORK/dist"
WHEEL=$(ls "$WORK"/dist/mca_drake-*.whl)
echo "wheel: $(basename "$WHEEL"), $(du -k "$WHEEL" | cut -f1) KiB"
"$PYTHON" -m zipfile -l "$WHEEL" | grep -v -E '\.py |dist-info' || true
rm -rf "$ENV"
"$PYTHON" -m venv "$ENV"
"$ENV/bin/python" -m pip install --quiet --disable-pip-version-check -c constraints.txt "$WHEEL"
mkdir "$WORK/empty"
cd "$WORK/empty"
start=$(date +%s)
"$ENV/bin/mca-drake" simulate --duration 2 --quiet
echo "main job (2 s simulated) from the installed wheel: $(($(date +%s) - start)) s"
"$ENV/bin/mca-drake" run plant_demo --set '{duration_s: 1}' --quiet
test -f results/closed_loop/summary.json
echo "wheel check: the installed package ran the main job and a packaged scenario"
