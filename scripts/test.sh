#!/usr/bin/env bash
# Set up .venv (if needed) with mavreg and its test dependencies, then run the default
# suite: unit, firmware_sim and end-to-end (sitl) tests; `-m slow` ones are left out.
#
# The unit tests are pure or sans-I/O (an injected clock, no real-time flight), so they run
# on two workers (pytest-xdist). The emulator and end-to-end tests start processes that talk
# over UDP; they run one at a time, so that no two flights share the machine's cores.
# With arguments, they are handed to one plain pytest run instead (e.g. `-k governor`).
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e '.[test,gcs]'
export PATH="$PWD/.venv/bin:$PATH"
PYTEST=(.venv/bin/python -m pytest -q -p no:cacheprovider)
if [ "$#" -gt 0 ]; then
    exec "${PYTEST[@]}" "$@"
fi
status=0
"${PYTEST[@]}" -n 2 tests/unit || status=$?
"${PYTEST[@]}" tests/firmware_sim tests/sitl || status=$?
exit "$status"
