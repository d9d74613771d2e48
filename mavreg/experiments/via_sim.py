"""Fly one run on the design model (``--via sim``): the controller at 1 kHz, RK4 at 1 ms.

The regulator flies with the sequential simulator of :mod:`mavreg.sim.maneuver_run`
(zero-order hold, the plant's inertia, rotor noise drawn once per control period from the
run's seed, per-rotor saturation of the plant only, a gust window); the time-indexed trackers
(:mod:`mavreg.trackers`) fly on the same plant with the same options through
:func:`mavreg.sim.closed_loop.simulate`. The controller is always designed on the plan's
nominal vehicle. A run starts on the nominal state at ``start_s_m`` (the entry: 0) plus its
offset; a tracker's clock starts where its reference reaches ``start_s_m + reference_lead_m``.
Every run ends when the vehicle's projection on the path reaches its end, or at
``max_time_s`` (default: the nominal time left plus :data:`EXTRA_TIME_S`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..config.controller import load_controller
from ..config.regulation import told_rotor_limit
from ..geometry.projection import Projector
from ..model.mixer import Mixer
from ..model.quadrotor import QuadrotorModel
from ..model.rotation import rpy_to_matrix
from ..sim.closed_loop import SimOptions, simulate, window_force
from ..sim.maneuver_run import fly_on_design_model
from ..trackers.se3 import Se3Tracker
from ..trackers.timed import TimedNominal
from ..trackers.tvlqr import TimeVaryingLqr, TvlqrWeights
from .definitions import REGULATOR, SE3, TVLQR
from .record import Flight

__all__ = ["fly_sim", "flight_from_result", "tracker_for", "max_time_s", "EXTRA_TIME_S", "CONTROL_PERIOD_S"]

EXTRA_TIME_S = 10.0
"""Time allowed beyond the nominal's to reach the path's end: a regulator pushed back resumes
from where it is and is late by design (4 s after an 8 N gust at walking speed)."""
CONTROL_PERIOD_S = 0.001
"""Controller period and physics step of the design model (1 kHz, RK4 at 1 ms)."""


_BUILT: dict = {}
"""(id(plan), what) -> (plan, object): built once per process for each plan it flies (the
plans themselves are cached per process by :func:`.runner.plan_for`; the plan is kept here
so that its id is not reused)."""


def _once(plan, what, build):
    key = (id(plan), what)
    if key not in _BUILT:
        _BUILT[key] = (plan, build())
    return _BUILT[key][1]


def _timed(plan) -> TimedNominal:
    return _once(plan, "timed", lambda: TimedNominal(plan))


def tracker_for(plan, controller_path: Path | None, name: str):
    """The tracker ``name`` (:data:`~.definitions.TVLQR` or :data:`~.definitions.SE3`) on
    ``plan``, built once per process (the TVLQR's gains take a few seconds); the TVLQR takes
    its weights from ``controller_path``."""
    lead = CONTROL_PERIOD_S / 2
    if name == TVLQR:
        if controller_path is None:
            raise ValueError("the TVLQR needs the controller file of its weights")
        return _once(plan, (name, str(controller_path)), lambda: TimeVaryingLqr(
            _timed(plan), TvlqrWeights.from_controller(load_controller(controller_path)), lead_s=lead))
    if name == SE3:
        return _once(plan, name, lambda: Se3Tracker(_timed(plan), lead_s=lead))
    raise ValueError(f"unknown tracker {name!r}")


def _start_state(plan, spec) -> np.ndarray:
    x0 = plan.nominal_state(spec.start_s_m) if spec.start_s_m else plan.entry_state
    x0[:3] += np.asarray(spec.offset_m, dtype=float)
    return x0


def max_time_s(plan, spec) -> float:
    """How long ``spec`` may fly: its ``max_time_s``, else the nominal time left after its
    start plus :data:`EXTRA_TIME_S`."""
    if spec.max_time_s is not None:
        return float(spec.max_time_s)
    return _timed(plan).duration_s - _timed(plan).t_of_s(spec.start_s_m) + EXTRA_TIME_S


def fly_sim(plan, spec, controller_path: Path | None = None) -> Flight:
    """Fly ``spec`` (:class:`~.definitions.RunSpec`) on the design model; the true record.

    ``controller_path``: the controller file whose weights the TVLQR takes (needed for it).
    """
    if spec.controller == REGULATOR:
        # no timed reference: a lead changes nothing, the regulator starts where the vehicle is
        duration = max_time_s(plan, spec)
        ctrl = None if controller_path is None else load_controller(controller_path)
        run = fly_on_design_model(plan, offset_m=spec.offset_m, inertia_kg_m2=spec.inertia_kg_m2,
                                  rotor_noise_sd_n=spec.rotor_noise_sd_n, saturation_n=spec.saturation_n,
                                  seed=spec.seed, extra_time_s=duration - plan.duration_s,
                                  gust_force_n=spec.gust_force_n,
                                  gust_window_s=spec.gust_window_s or (0.0, 0.0), start_s_m=spec.start_s_m,
                                  allocation=None if ctrl is None else told_rotor_limit(ctrl.allocation, spec.saturation_n),
                                  speed_governor=None if ctrl is None else ctrl.speed_governor,
                                  true_metrics=False)      # the campaign judges the truth itself
        res = run.result
    else:
        res = _fly_tracker(plan, spec, tracker_for(plan, controller_path, spec.controller))
    return flight_from_result(res, spec.saturation_n)


def flight_from_result(res, saturation_n: float | None, extra: dict | None = None) -> Flight:
    """The :class:`~.record.Flight` of a design-model run (a :class:`~mavreg.sim.closed_loop.SimResult`)."""
    x = res.x
    R = rpy_to_matrix(*x[:, 3:6].T).transpose(2, 0, 1)
    v_ned = np.einsum("kij,kj->ki", R, x[:, 6:9])
    status = res.status.value
    return Flight(t_s=res.t, position_m=x[:, :3], rotation=R, velocity_m_s=v_ned,
                  rotor_command_n=res.rotor_command_n, rotor_applied_n=res.rotor_applied_n,
                  status=status, reason=res.reason, completed=status == "completed",
                  saturation_n=saturation_n, extra={} if extra is None else extra)


def _fly_tracker(plan, spec, tracker):
    """A time-indexed tracker on the design model; stops when the projection reaches the end."""
    vehicle = plan.vehicle
    x0 = _start_state(plan, spec)
    t_ref0 = tracker.timed.t_of_s(spec.start_s_m + spec.reference_lead_m)
    proj = Projector(plan.path)
    proj.reset(x0[:3], spec.start_s_m)
    end = plan.length_m - 1e-6
    state = {"s": proj.s}

    def controller(t, x):
        state["s"] = proj.update(x[:3]).s
        return tracker.step(t_ref0 + t, x).rotor_forces_n

    force = None if spec.gust_force_n is None else window_force(spec.gust_force_n, *spec.gust_window_s)
    opts = SimOptions(initial_state=tuple(x0), dt_s=CONTROL_PERIOD_S, control_period_steps=1,
                      max_duration_s=max_time_s(plan, spec), inertia_kg_m2=spec.inertia_kg_m2,
                      rotor_noise_sd_n=spec.rotor_noise_sd_n, seed=spec.seed, saturation_n=spec.saturation_n,
                      force_fn=force, done=lambda t, x: state["s"] >= end)
    return simulate(QuadrotorModel.from_vehicle(vehicle),
                    Mixer.from_vehicle(vehicle), controller, opts)
