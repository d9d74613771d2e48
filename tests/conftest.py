"""Test-wide setup and the shared fixtures.

``pyproject.toml`` puts the repository root on ``sys.path`` (``pythonpath``), so shared helpers
are imported as ``tests.helpers.<module>`` (``tests/helpers/``); no test imports another test
module or a helper by its bare name.

Fixtures (session-scoped, from :mod:`harness.params`; shared objects, read-only):
``vehicle`` (the MK-Quadro), ``paper_controller``, ``design_controller``,
``realistic_controller`` and ``barrel_roll_plan`` (the barrel roll with ``paper_lqr.yaml``).
"""

import os
import tempfile

import pytest

from harness import params


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


@pytest.fixture(scope="session")
def vehicle():
    """The MK-Quadro (``params/vehicles/mk_quadro.yaml``), loaded."""
    return params.vehicle()


@pytest.fixture(scope="session")
def paper_controller():
    """``params/controller/paper_lqr.yaml``: the paper's design, loaded."""
    return params.controller("paper_lqr")


@pytest.fixture(scope="session")
def design_controller():
    """``params/controller/design.yaml``: the paper's weights on the SO(3) error, loaded."""
    return params.controller("design")


@pytest.fixture(scope="session")
def realistic_controller():
    """``params/controller/realistic.yaml``: lag-aware, predicting, observing; loaded."""
    return params.controller("realistic")


@pytest.fixture(scope="session")
def barrel_roll_plan(_plan_cache_of_this_run):
    """The barrel roll planned with ``paper_lqr.yaml`` for the MK-Quadro (planned once)."""
    return params.barrel_roll_plan("paper_lqr")
