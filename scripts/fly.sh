#!/usr/bin/env bash
# Set up .venv (if needed) and fly the paper's barrel roll on the bundled emulator.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e .
export PATH="$PWD/.venv/bin:$PATH"
exec .venv/bin/mavreg fly params/maneuvers/barrel_roll.yaml "$@"
