"""The bundled parameters the tests fly with, loaded (and the barrel roll planned) once per
test process.

Tests take them through the fixtures of ``tests/conftest.py`` (``vehicle``,
``paper_controller``, ``design_controller``, ``realistic_controller``, ``barrel_roll_plan``)
or, at module level, from here. The objects are shared: treat them as read-only and make
variants with :func:`dataclasses.replace`. File paths come from :mod:`mavreg.config.paths`.
"""
from __future__ import annotations

from functools import lru_cache

from mavreg.config.controller import ControllerParams, load_controller
from mavreg.config.maneuver import load_maneuver
from mavreg.config.paths import controller_file, maneuver_file, vehicle_file
from mavreg.config.vehicle import VehicleParams, load_vehicle

__all__ = ["BARREL_ROLL", "vehicle", "controller", "barrel_roll", "barrel_roll_plan"]

BARREL_ROLL = maneuver_file("barrel_roll")
"""The barrel roll's file: the maneuver most tests fly."""


@lru_cache(maxsize=None)
def vehicle(name: str = "mk_quadro") -> VehicleParams:
    """The bundled vehicle file ``name`` (default: the MK-Quadro of the paper), loaded."""
    return load_vehicle(vehicle_file(name))


@lru_cache(maxsize=None)
def controller(name: str = "paper_lqr") -> ControllerParams:
    """The bundled controller file ``name`` (``paper_lqr``, ``paper_governed``, ``design``,
    ``realistic``, ``freestyle``), loaded."""
    return load_controller(controller_file(name))


@lru_cache(maxsize=None)
def barrel_roll():
    """The barrel roll's maneuver specification, loaded."""
    return load_maneuver(BARREL_ROLL)


@lru_cache(maxsize=None)
def barrel_roll_plan(controller_name: str = "paper_lqr", laps: int | None = None,
                     vehicle_name: str = "mk_quadro"):
    """The barrel roll planned for ``vehicle_name`` with the controller file ``controller_name``
    (``laps`` laps; None: the file's)."""
    from mavreg.planning.plan_io import plan_file
    return plan_file(BARREL_ROLL, vehicle(vehicle_name), controller(controller_name), laps=laps)


ONE_GATE = """\
kind: maneuver
version: 1
name: one_gate
description: a gate 2 m east of a line heading north, at 2 m/s
start: {position_m: [0.0, 0.0, -3.0], heading_deg: 0}
segments:
  - name: run_up
    line: {length_m: 3.0}
  - name: gate
    waypoints: {points_m: [[4.0, 2.0, 0.0], [8.0, 0.0, 0.0]]}
  - name: run_out
    line: {length_m: 3.0}
speed:
  initial_m_s: 0.5
  changes:
    - {segment: run_up, offset_m: 0.0, length_m: 2.5, to_m_s: 2.0}
    - {segment: run_out, offset_m: 0.0, length_m: 2.5, to_m_s: 0.5}
yaw: {mode: tangent}
"""
"""A small waypoint maneuver (a gate 2 m east of a line north) for the plan and plot tests."""
