"""Test-wide setup. pytest puts this directory on ``sys.path`` (rootdir conftest, no
package), so helpers shared by the unit and the end-to-end tests live here once
(``proc_helpers.py``)."""

import os
import tempfile

import pytest


@pytest.fixture(autouse=True, scope="session")
def _plan_cache_of_this_run():
    """Plans are cached in a directory of this test run, not the user's (the daemon and the
    emulator that end-to-end tests start inherit the variable)."""
    before = os.environ.get("MAVREG_PLAN_CACHE")
    with tempfile.TemporaryDirectory(prefix="mavreg-plans-") as d:
        os.environ["MAVREG_PLAN_CACHE"] = d
        yield d
    if before is None:
        os.environ.pop("MAVREG_PLAN_CACHE", None)
    else:
        os.environ["MAVREG_PLAN_CACHE"] = before
