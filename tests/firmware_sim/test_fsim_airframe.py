"""The airframe's world: parasitic drag, thrust scale, the wind and thrust presets, their errors."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mavreg.config.vehicle import load_vehicle
from firmware_sim.cli import build_engine, build_parser
from firmware_sim.params import build_sim_params, default_vehicle_path, parse_start
from firmware_sim.physics import RigidBody, quat_from_euler
from firmware_sim.rotors import Rotors
from firmware_sim.sim import Simulation
from firmware_sim.world import PRESETS, ROTORPY_DRAG, build_world

VEHICLE = load_vehicle(default_vehicle_path())
M = VEHICLE.mass_kg
HOVER_N = M * 9.81 / 4


def _accel(body, v_ned, wind=(0.0, 0.0, 0.0), attitude_deg=(0.0, 0.0, 0.0)):
    q = quat_from_euler(*(math.radians(a) for a in attitude_deg))
    s = (0.0, 0.0, -10.0, *q, *v_ned, 0.0, 0.0, 0.0)
    return np.array(body.derivative(s, M * 9.81, 0.0, 0.0, 0.0, wind, (0.0, 0.0, 0.0))[7:10])


def test_parasitic_drag_is_quadratic_in_the_air_speed_per_body_axis():
    J = ((0.0176, 0, 0), (0, 0.0177, 0), (0, 0, 0.034))
    body = RigidBody(M, J, (0.0, 0.0, 0.0), parasitic_drag_xyz_n_s2_per_m2=(0.01, 0.02, 0.04))
    # level, flying north at 8 m/s: -c_x |v| v_x along body x = north
    assert _accel(body, (8.0, 0.0, 0.0)) == pytest.approx((-0.01 * 64 / M, 0.0, 0.0), abs=1e-12)
    # yawed 90 deg, flying north = along body -y: the y coefficient acts
    assert _accel(body, (8.0, 0.0, 0.0), attitude_deg=(0, 0, 90))[0] == pytest.approx(-0.02 * 64 / M)
    # diagonal air speed: each body axis sees |v_air| times its own component
    a = _accel(body, (3.0, 4.0, 0.0), wind=(0.0, 0.0, 0.0))
    assert a[:2] == pytest.approx((-0.01 * 5 * 3 / M, -0.02 * 5 * 4 / M), rel=1e-12)
    # in a wind blowing with the vehicle at its speed there is no drag
    assert _accel(body, (3.0, 4.0, 0.0), wind=(3.0, 4.0, 0.0))[:2] == pytest.approx((0, 0), abs=1e-12)


def test_thrust_scale_scales_the_thrust_and_the_saturation():
    rotors = Rotors(12.0, 0.0, 0.0, 1e-3, np.random.default_rng(0), thrust_scale=0.9)
    assert rotors.step((5.0, 12.0, 20.0, 0.0), True) == pytest.approx((4.5, 10.8, 10.8, 0.0))
    lagged = Rotors(12.0, 0.02, 0.0, 1e-3, np.random.default_rng(0), thrust_scale=0.9)
    for _ in range(1000):
        f = lagged.step((5.0,) * 4, True)
    assert f == pytest.approx((4.5,) * 4, rel=1e-12)


def test_a_90_percent_vehicle_sinks_at_the_hover_command():
    v = dataclasses.replace(VEHICLE, emulator=PRESETS["thrust90"].airframe.apply(VEHICLE.emulator))
    sim = Simulation(build_sim_params(v, 500, 1000, 0, rotor_time_constant_s=0.0), parse_start("z_m=-50"))
    sim.advance((HOVER_N,) * 4, True, 0)
    vz = sim.state[9]
    # 10 % of the weight missing, less the vertical drag: dv/dt = 0.981 - (c_z/m) v
    assert vz / 0.002 == pytest.approx(0.981, rel=0.01)


def test_presets_add_drag_wind_and_thrust_on_top_of_realistic():
    real = PRESETS["realistic"]
    assert real.airframe == ROTORPY_DRAG and real.airframe.linear_drag_xyz_n_s_per_m[0] / M == pytest.approx(0.45, rel=0.01)
    for name, speed in (("wind3", 3.0), ("wind6", 6.0)):
        p = PRESETS[name]
        assert p.link == real.link and p.estimator == real.estimator
        assert p.airframe.wind_ned_m_s == pytest.approx((-speed, 0.0, 0.0))     # from the north
    assert PRESETS["thrust90"].airframe.thrust_scale == 0.9
    assert PRESETS["ideal"].airframe.apply(VEHICLE.emulator) == VEHICLE.emulator
    east = build_world("wind3", wind_from_deg=90)
    assert east.airframe.wind_ned_m_s == pytest.approx((0.0, -3.0, 0.0), abs=1e-12)
    assert ("--wind-from-deg", 90.0) in east.overrides


@pytest.mark.parametrize("kwargs, flag", [
    ({"wind_speed_m_s": -1.0}, "--wind-speed-m-s"),
    ({"wind_speed_m_s": float("nan")}, "--wind-speed-m-s"),
    ({"wind_from_deg": float("inf")}, "--wind-from-deg"),
    ({"thrust_scale": 0.2}, "--thrust-scale"),
    ({"linear_drag_xyz_n_s_per_m": (0.1, 0.2)}, "--drag-n-s-per-m"),
    ({"parasitic_drag_xyz_n_s2_per_m2": (0.1, -0.2, 0.0)}, "--parasitic-drag-n-s2-per-m2"),
])
def test_bad_airframe_values_name_the_flag(kwargs, flag):
    with pytest.raises(ValueError, match=flag):
        build_world("realistic", **kwargs)


def test_cli_wind_preset_drifts_the_vehicle_downwind():
    args = build_parser().parse_args(["--world", "wind6", "--wind-from-deg", "270", "--listen",
                                      "udpin:127.0.0.1:0", "--start", "z_m=-20", "--quiet",
                                      "--rotor-time-constant-s", "0"])
    engine, _ = build_engine(args)
    try:
        sim = engine.sim
        assert sim.params.vehicle.emulator.linear_drag_xyz_n_s_per_m == ROTORPY_DRAG.linear_drag_xyz_n_s_per_m
        for _ in range(500):
            sim.advance((HOVER_N,) * 4, True, 0)
        # wind from the west blows east: the vehicle accelerates east, nothing north
        assert sim.state[8] > 1.0 and abs(sim.state[7]) < 1e-9
    finally:
        engine.link.close()


def test_fly_world_choices_are_the_emulator_presets():
    import argparse
    from firmware_sim.world import PRESET_NAMES
    from mavreg.cli.fly_cmd import add_arguments
    p = argparse.ArgumentParser()
    add_arguments(p)
    world = next(a for a in p._actions if a.dest == "world")
    assert set(world.choices) == set(PRESET_NAMES)
