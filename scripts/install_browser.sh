#!/usr/bin/env bash
# Installs Debian's Chromium for the Meshcat rendering test (tests/test_meshcat.py), when
# it is missing and apt-get can be used; prints what it did. Never fails the caller: the
# test itself reports a missing browser (and fails under MCA_DRAKE_REQUIRE_CHROMIUM=1).
set -uo pipefail
if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then
  echo "chromium: $(command -v chromium || command -v chromium-browser)"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then SUDO="sudo -n"; else
    echo "chromium: missing, and no root to install it (apt-get install chromium)"; exit 0
  fi
fi
if ! command -v apt-get >/dev/null 2>&1; then
  echo "chromium: missing, and no apt-get here"; exit 0
fi
export DEBIAN_FRONTEND=noninteractive
($SUDO apt-get install -y -q chromium >/dev/null 2>&1 ||
  ($SUDO apt-get update -q >/dev/null 2>&1 && $SUDO apt-get install -y -q chromium >/dev/null 2>&1)) &&
  echo "chromium: installed $(command -v chromium)" || echo "chromium: apt-get install failed"
exit 0
