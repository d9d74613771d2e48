"""Planning's fast paths against their references: the compiled Riccati sweep against plain
Python, the coarse sweep with Hermite midpoints against a fine sweep, the merged
linearization of repeated rows against computing every row, and the plan cache."""
from __future__ import annotations

import dataclasses
import os
import subprocess
import sys

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, REAL_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver
from mavreg.config.vehicle import load_vehicle
from mavreg.maneuver import plan as pm
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.geometry.build import build_path
from mavreg.control.design.riccati import care
from mavreg.control.design.actuator import augmented_jacobians
from mavreg.maneuver import nominal_grid as ng
from mavreg.maneuver import gain_schedule as gs
from mavreg.planning import plan_io as pio
from mavreg.planning.cache import PlanCache

BARREL = maneuver_file("barrel_roll")
REALISTIC = REAL_CONTROLLER
VEHICLE = load_vehicle(DEFAULT_VEHICLE)
SPEC = load_maneuver(BARREL)


def _blend(s_tab, K_tab, q):
    """The regulator's lookup: linear between table rows."""
    i = np.clip(np.searchsorted(s_tab, q) - 1, 0, len(s_tab) - 2)
    a = ((q - s_tab[i]) / (s_tab[i + 1] - s_tab[i]))[:, None, None]
    return K_tab[i] + a * (K_tab[i + 1] - K_tab[i])


@pytest.mark.parametrize("controller_file", [PAPER_CONTROLLER, REALISTIC], ids=["paper", "realistic"])
def test_gains_match_a_fine_sweep(controller_file):
    """K(s) as the regulator reads it, against a sweep with a 4x finer step: within 3e-5 of
    max |K| (today's 1 ms RK4 with linear lookup: 6e-6 paper, 2.2e-5 realistic, whose weight on
    the achieved torques makes the lag's closed-loop mode faster)."""
    controller = load_controller(controller_file)
    plan = pm.plan_spec(SPEC, VEHICLE, controller)
    fine = pm.plan_spec(SPEC, VEHICLE, dataclasses.replace(controller, riccati_step_s=controller.riccati_step_s / 4))
    q = np.linspace(0.0, plan.length_m, 20001)
    err = np.abs(_blend(plan.s, plan.K, q) - _blend(fine.s, fine.K, q)).max()
    assert err < 3e-5 * np.abs(fine.K).max()


def test_hermite_midpoints_match_the_sweep_through_them():
    """P at the midpoints from the Hermite interpolant equals, to O(h^4), the RK4 sweep that
    steps through the midpoints as nodes."""
    controller = load_controller(PAPER_CONTROLLER)
    model = QuadrotorModel.from_vehicle(VEHICLE)
    path = build_path(SPEC)
    speed, yaw = pm.build_profiles(SPEC, path)
    s = ng.with_midpoints(ng.time_grid(path, speed, controller.riccati_step_s))
    A, B = gs.linearization(model, 0.0, ng.nominal_on_grid(model, path, speed, yaw, s, "fixed"), s)
    Q, R = gs.weights(controller, 0.0)
    P_T, _ = care(A[-1], B[-1], Q, R)
    P, K = gs.gains_on_grid(A, B, s, Q, R, P_T)
    s2 = ng.with_midpoints(s)      # every point of s a node, with midpoints of its own
    A2, B2 = gs.linearization(model, 0.0, ng.nominal_on_grid(model, path, speed, yaw, s2, "fixed"), s2)
    P2, _ = gs.gains_on_grid(A2, B2, s2, Q, R, P_T)
    assert np.abs(P[1::2] - P2[2::4]).max() < 1e-5 * np.abs(P).max()


def test_merged_linearization_equals_every_row():
    controller = load_controller(REALISTIC)
    model = QuadrotorModel.from_vehicle(VEHICLE)
    path = build_path(SPEC)
    speed, yaw = pm.build_profiles(SPEC, path)
    s = ng.with_midpoints(ng.time_grid(path, speed, controller.riccati_step_s))
    nominal = ng.nominal_on_grid(model, path, speed, yaw, s, "fixed")
    tau = VEHICLE.rotor_time_constant_s
    A, B = gs.linearization(model, tau, nominal, s)
    F, k, x, u, dx, v, _ = nominal
    sel = np.arange(0, len(s), 97)
    A_all, B_all = augmented_jacobians(model, tau, F[sel], k[sel], x[sel], u[sel], dx[sel],
                                          gs.du_ds(u, s, False)[sel], v[sel])
    assert np.abs(A[sel] - A_all).max() < 1e-9 * np.abs(A_all).max()
    assert np.abs(B[sel] - B_all).max() < 1e-9 * np.abs(B_all).max()
    first, run = gs.first_of_runs(np.concatenate([x[:, 3:], u], axis=1))
    assert len(first) < 0.8 * len(s)      # the slow ends and the run-up are merged


def test_compiled_sweep_agrees_with_plain_python():
    """The numba sweep and the plain-Python one (MAVREG_PURE=1, a fresh process) give the
    same gains to round-off."""
    code = ("import numpy as np, sys; from mavreg.planning.plan_io import plan_file; "
            "from mavreg.config.vehicle import load_vehicle; from mavreg.config.controller import load_controller; "
            f"p = plan_file({str(BARREL)!r}, load_vehicle({str(DEFAULT_VEHICLE)!r}), "
            f"load_controller({str(REALISTIC)!r}), use_cache=False); np.save(sys.argv[1], p.K)")
    out = {}
    for pure in ("0", "1"):
        path = os.path.join(os.environ["MAVREG_PLAN_CACHE"], f"K{pure}.npy")
        env = dict(os.environ, MAVREG_PURE=pure)
        subprocess.run([sys.executable, "-c", code, path], check=True, env=env, timeout=300)
        out[pure] = np.load(path)
    assert np.abs(out["0"] - out["1"]).max() <= 1e-10 * np.abs(out["1"]).max()


def test_cache_returns_the_same_plan_and_keys_on_contents(tmp_path):
    cache = PlanCache(tmp_path)
    controller = load_controller(PAPER_CONTROLLER)
    first = pio.plan_cached(SPEC, VEHICLE, controller, cache=cache)
    again = pio.plan_cached(SPEC, VEHICLE, controller, cache=cache)
    assert (cache.hits, cache.misses) == (1, 1)
    assert not first.from_cache and again.from_cache          # what `mavreg plan` reports
    assert (first.summary()["from_cache"], again.summary()["from_cache"]) == (False, True)
    assert np.array_equal(first.K, again.K) and np.array_equal(first.x, again.x)
    # another controller, another entry
    other = dataclasses.replace(controller, q_position=(500.0, 500.0))
    changed = pio.plan_cached(SPEC, VEHICLE, other, cache=cache)
    assert cache.misses == 2 and not np.array_equal(changed.K, first.K)
    # a corrupt entry is planned again
    for entry in tmp_path.glob("*.plan.pickle"):
        entry.write_bytes(b"not a pickle")
    pio.plan_cached(SPEC, VEHICLE, controller, cache=cache)
    assert cache.misses == 3


def test_cache_off_and_unwritable(tmp_path, monkeypatch):
    from mavreg.planning.cache import default_cache
    monkeypatch.setenv("MAVREG_PLAN_CACHE", "off")
    assert default_cache() is None
    blocker = tmp_path / "file"
    blocker.write_text("x")
    cache = PlanCache(blocker / "sub")       # cannot be made: planning still works
    plan = pio.plan_cached(SPEC, VEHICLE, load_controller(PAPER_CONTROLLER), cache=cache)
    assert plan.K.shape[0] == len(plan.s) and cache.misses == 1
