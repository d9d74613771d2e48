#!/usr/bin/env bash
# Set up .venv (if needed) with mavreg and its test dependencies, then run the default
# suite: unit, firmware_sim and end-to-end (sitl) tests; `-m slow` ones are left out.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e '.[test]'
export PATH="$PWD/.venv/bin:$PATH"
exec .venv/bin/python -m pytest -q -p no:cacheprovider "$@"
