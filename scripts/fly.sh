#!/usr/bin/env bash
# Set up .venv (only when it is missing or pyproject.toml changed: scripts/venv.sh) and fly
# the paper's barrel roll on the bundled emulator (after an install, `mavreg warm-up` first).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/venv.sh
ensure_venv '.'
export PATH="$PWD/.venv/bin:$PATH"
# a fresh install: compile the controller's kernels and plan the barrel roll now, saying so,
# so that this and every later flight starts in seconds (docs/cli.md, "First run")
if [ "$MAVREG_INSTALLED_NOW" = 1 ]; then
    .venv/bin/mavreg warm-up params/maneuvers/barrel_roll.yaml
fi
exec .venv/bin/mavreg fly params/maneuvers/barrel_roll.yaml "$@"
