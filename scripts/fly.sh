#!/usr/bin/env bash
# Set up .venv (only when it is missing or pyproject.toml changed: scripts/venv.sh) and fly
# the paper's barrel roll on the bundled emulator.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/venv.sh
ensure_venv '.'
export PATH="$PWD/.venv/bin:$PATH"
exec .venv/bin/mavreg fly params/maneuvers/barrel_roll.yaml "$@"
