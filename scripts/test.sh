#!/usr/bin/env bash
# Set up .venv with mavreg and its test dependencies (only when it is missing or
# pyproject.toml changed: scripts/venv.sh), then run the default suite: unit, firmware_sim
# and end-to-end (sitl) tests; `-m slow` ones are left out.
#
# The unit tests are pure or sans-I/O (an injected clock, no real-time flight), so they run
# on two workers (pytest-xdist). The emulator and end-to-end tests start processes that talk
# over UDP; those marked `lockstep` (paced by the vehicle's clock alone) run two files at a
# time, the others one at a time, so that no real-time flight shares the machine's cores.
# With arguments, they are handed to one plain pytest run instead (e.g. `-k governor`).
# Without, ruff and the import contracts (lint-imports) run first; a finding fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/venv.sh
ensure_venv '.[test,gcs]'
export PATH="$PWD/.venv/bin:$PATH"
PYTEST=(.venv/bin/python -m pytest -q -p no:cacheprovider)
DURATIONS=(--durations=15)   # the slowest tests, in every log: what the suite's time goes to
if [ "$#" -gt 0 ]; then
    exec "${PYTEST[@]}" "$@"
fi
# Lint and import contracts first (rules: pyproject.toml, docs/architecture.md "Layering and
# lint"); a finding fails the run.
.venv/bin/ruff check --quiet .
.venv/bin/lint-imports --no-cache > /dev/null || { .venv/bin/lint-imports --no-cache; exit 1; }
status=0
"${PYTEST[@]}" "${DURATIONS[@]}" -n 2 tests/unit || status=$?
# Flights paced by lockstep alone (marked `lockstep`) two files at a time: each is two processes
# taking turns, about one core, and is judged on the vehicle's time; then the rest one at a time.
"${PYTEST[@]}" "${DURATIONS[@]}" -n 2 --dist loadfile -m "lockstep and not slow" tests/firmware_sim tests/sitl \
    || status=$?
"${PYTEST[@]}" "${DURATIONS[@]}" -m "not lockstep and not slow" tests/firmware_sim tests/sitl || status=$?
exit "$status"
