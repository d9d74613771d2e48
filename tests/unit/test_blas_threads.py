"""Planning runs BLAS on one thread (:mod:`mavreg.blas`), and its gains are the same bits."""
from __future__ import annotations

import numpy as np
import pytest

threadpoolctl = pytest.importorskip("threadpoolctl")

from mavreg.config.paths import maneuver_file
from mavreg.blas import one_blas_thread  # noqa: E402


def _blas_threads() -> set[int]:
    return {i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"}


def test_one_thread_inside_and_as_before_after():
    np.ones((4, 4)) @ np.ones((4, 4))             # numpy's BLAS loaded
    before = _blas_threads()
    with one_blas_thread():
        assert _blas_threads() <= {1}
    assert _blas_threads() == before


def test_the_planner_runs_on_one_blas_thread(monkeypatch):
    """Negative control of the wrapping: the thread count seen inside the Riccati stage."""
    from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER
    from mavreg.config.controller import load_controller
    from mavreg.config.maneuver import load_maneuver
    from mavreg.config.vehicle import load_vehicle
    from mavreg.maneuver import gain_schedule, plan as planmod
    seen = []
    real = gain_schedule.gains_on_grid

    def spy(*args, **kwargs):
        seen.append(_blas_threads())
        return real(*args, **kwargs)

    monkeypatch.setattr(gain_schedule, "gains_on_grid", spy)
    planmod.plan_spec(load_maneuver(maneuver_file("slalom")), load_vehicle(DEFAULT_VEHICLE),
                      load_controller(PAPER_CONTROLLER))
    assert seen and all(s <= {1} for s in seen)
