"""Physics of firmware_sim: hover, free fall, torque-free spin, rotor lag, saturation, ground."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mavreg.config.vehicle import load_vehicle
from firmware_sim.params import build_sim_params, default_vehicle_path, parse_start
from firmware_sim.physics import G, RigidBody, inertia_matrix, quat_from_euler, euler_from_quat, rotate
from firmware_sim.recorder import Recorder
from firmware_sim.rotors import Rotors
from firmware_sim.sim import Simulation
from firmware_sim.status import ExitCode, SimStop

VEHICLE = load_vehicle(default_vehicle_path())
HOVER_N = VEHICLE.mass_kg * 9.81 / 4


def params(**kw):
    return build_sim_params(VEHICLE, 500, 1000, 0, **kw)


def test_hover_holds_position():
    sim = Simulation(params(), parse_start("x_m=1,y_m=2,z_m=-5,yaw_deg=30"))
    for _ in range(5 * 500):
        sim.advance((HOVER_N,) * 4, True, 0)
    s = sim.state
    assert s[0:3] == pytest.approx((1.0, 2.0, -5.0), abs=1e-9)
    assert s[7:13] == pytest.approx((0.0,) * 6, abs=1e-9)


def test_thrust_drop_gives_free_fall():
    sim = Simulation(params(rotor_time_constant_s=0.0), parse_start("z_m=-50"))
    for _ in range(500):                          # 1 s of zero thrust
        sim.advance((0.0,) * 4, True, 0)
    assert sim.t_s == pytest.approx(1.0)
    assert sim.state[2] == pytest.approx(-50 + 9.81 / 2, abs=1e-9)
    assert sim.state[9] == pytest.approx(9.81, abs=1e-9)


def test_torque_free_spin_conserves_momentum_and_energy():
    J = inertia_matrix((0.0176, 0.0177, 0.034), (0.0012, -0.0008, 0.0005))
    body = RigidBody(0.749, J, (0.0, 0.0, 0.0), gravity_m_s2=0.0)
    Jn = np.array(J)
    s = (0, 0, 0, *quat_from_euler(0.3, -0.2, 1.0), 0, 0, 0, 3.0, -2.0, 5.0)

    def invariants(s):
        w = np.array(s[10:13])
        h_body = Jn @ w
        h_ned = np.array(rotate(s[3:7], tuple(h_body)))
        return h_ned, 0.5 * w @ Jn @ w

    h0, e0 = invariants(s)
    dt = 1e-3
    for _ in range(10_000):                       # 10 s at 1 kHz
        s = body.rk4_step(s, dt, 0.0, 0.0, 0.0, 0.0, (0, 0, 0), (0, 0, 0))
        assert abs(math.sqrt(sum(x * x for x in s[3:7])) - 1.0) < 1e-12
    h1, e1 = invariants(s)
    assert np.linalg.norm(h1 - h0) / np.linalg.norm(h0) < 1e-8
    assert abs(e1 - e0) / e0 < 1e-8


def test_rotor_step_response_matches_first_order_lag():
    tau, dt = 0.02, 1e-3
    rotors = Rotors(12.0, tau, 0.0, dt, np.random.default_rng(0))
    for k in range(1, 101):
        f = rotors.step((6.0, 3.0, 0.0, 12.0), True)
        expect = 1.0 - math.exp(-k * dt / tau)
        assert f == pytest.approx((6.0 * expect, 3.0 * expect, 0.0, 12.0 * expect), rel=1e-12)


def test_saturation_clips_commands_and_noise():
    rotors = Rotors(8.5, 0.0, 0.5, 1e-3, np.random.default_rng(1))
    seen = []
    for _ in range(2000):
        seen.extend(rotors.step((20.0, -3.0, 8.4, 4.0), True))
    a = np.array(seen).reshape(-1, 4)
    assert a.min() >= 0.0 and a.max() <= 8.5
    assert 0.4 < (a[:, 0] == 8.5).mean() < 0.6       # noise around a clipped command
    assert 0.4 < (a[:, 1] == 0.0).mean() < 0.6
    ideal = Rotors(8.5, 0.0, 0.0, 1e-3, np.random.default_rng(1))
    assert ideal.step((20.0, -3.0, 8.4, 4.0), True) == (8.5, 0.0, 8.4, 4.0)
    assert a[:, 3].std() == pytest.approx(0.5, rel=0.1)     # noise present, unclipped rotor


def test_noise_is_deterministic_per_seed():
    def run(seed):
        sim = Simulation(build_sim_params(VEHICLE, 500, 1000, seed, rotor_noise_sd_n=0.2),
                         parse_start("z_m=-20"))
        for _ in range(200):
            sim.advance((HOVER_N,) * 4, True, 0)
        return sim.state
    assert run(3) == run(3)
    assert run(3) != run(4)


def test_ground_contact_holds_landed_vehicle():
    sim = Simulation(params())
    for _ in range(1000):
        sim.advance((HOVER_N * 0.9,) * 4, True, 0)        # below hover: stays down
    assert sim.on_ground and sim.state[2] == 0.0 and sim.state[9] == 0.0
    for _ in range(500):
        sim.advance((HOVER_N * 1.3,) * 4, True, 0)        # above hover: lifts off
    assert not sim.on_ground and sim.state[2] < -0.5


def test_soft_touchdown_is_not_a_crash_and_hard_one_is():
    sim = Simulation(params(), parse_start("z_m=-0.5,vz_m_s=1.0"))
    for _ in range(500):
        sim.advance((HOVER_N,) * 4, True, 0)
    assert sim.on_ground and sim.state[2] == 0.0
    sim = Simulation(params(), parse_start("z_m=-2"))
    with pytest.raises(SimStop) as err:
        for _ in range(1000):
            sim.advance((0.0,) * 4, True, 0)
    assert err.value.code == ExitCode.CRASH


def test_non_finite_and_limits_stop_the_sim():
    sim = Simulation(params(), parse_start("z_m=-100"))
    with pytest.raises(SimStop) as err:
        sim.advance((math.nan,) * 4, True, 0)
    assert err.value.code == ExitCode.NON_FINITE
    sim = Simulation(params(rotor_time_constant_s=0.0), parse_start("z_m=-100"))
    with pytest.raises(SimStop) as err:
        for _ in range(5000):
            sim.advance((12.0, 0.0, 0.0, 0.0), True, 0)    # pitch torque spins it up
    assert err.value.code == ExitCode.LIMIT


def test_euler_roundtrip_and_start_parsing():
    q = quat_from_euler(math.radians(120), math.radians(-30), math.radians(45))
    assert euler_from_quat(q) == pytest.approx((math.radians(120), math.radians(-30), math.radians(45)))
    s = parse_start("z_m=-3, vy_m_s=8, roll_deg=120, p_deg_s=90")
    assert s[2] == -3 and s[8] == 8 and s[10] == pytest.approx(math.pi / 2)
    for bad in ("zz=1", "z_m=abc", "z_m=1", "z_m=-1,z_m=-2", "z_m=nan"):
        with pytest.raises(ValueError):
            parse_start(bad)


def test_overrides_and_perturbation():
    p = params(mass_kg=1.0, inertia_kg_m2=(0.02, 0.02, 0.03), inertia_scale=2.0)
    assert p.vehicle.mass_kg == 1.0
    assert np.diag(p.inertia_matrix_kg_m2) == pytest.approx((0.04, 0.04, 0.06))
    a = build_sim_params(VEHICLE, 500, 1000, 7, inertia_perturb_sd_kg_m2=0.0034).inertia_matrix_kg_m2
    b = build_sim_params(VEHICLE, 500, 1000, 7, inertia_perturb_sd_kg_m2=0.0034).inertia_matrix_kg_m2
    assert a == b and np.diag(a).tolist() != list(VEHICLE.inertia_kg_m2)
    with pytest.raises(ValueError):
        params(max_rotor_thrust_n=1.0)          # cannot hover
    with pytest.raises(ValueError):
        build_sim_params(VEHICLE, 300, 1000)


def test_recorder_roundtrip(tmp_path):
    rec = Recorder(tmp_path / "r.npz")
    sim = Simulation(params(), parse_start("z_m=-5"), recorder=rec)
    sim.record_initial(True, 123)
    for _ in range(5000):                         # crosses a chunk boundary
        sim.advance((HOVER_N,) * 4, True, 123)
    rec.save()
    d = np.load(tmp_path / "r.npz")
    assert d["t_s"].shape == (10001,) and d["t_s"][-1] == pytest.approx(10.0)
    assert d["quaternion_wxyz"].shape == (10001, 4) and d["custom_mode"][5] == 123
    assert d["rotor_applied_n"][-1] == pytest.approx([HOVER_N] * 4)


def test_wind_force_gust_and_velocity_through_drag():
    from firmware_sim.wind import Wind, parse_wind
    w = Wind([parse_wind("force:0,1.498,0@0.5:1.5"), parse_wind("velocity:2,0,0")])
    assert w.at(0.0) == ((2.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert w.at(1.0) == ((2.0, 0.0, 0.0), (0.0, 1.498, 0.0))
    sim = Simulation(params(rotor_time_constant_s=0.0), parse_start("z_m=-20"),
                     wind=Wind([parse_wind("force:0,1.498,0@0.5:1.5")]))
    for _ in range(1000):                                  # 2 s; gust of 1 s at 2 m/s^2
        sim.advance((HOVER_N,) * 4, True, 0)
    assert sim.state[8] == pytest.approx(2.0, abs=1e-6)
    drag = dataclasses.replace(VEHICLE, emulator=dataclasses.replace(
        VEHICLE.emulator, linear_drag_xyz_n_s_per_m=(0.3, 0.3, 0.3)))
    sim = Simulation(build_sim_params(drag, 500, 1000, 0), parse_start("z_m=-20"),
                     wind=Wind([parse_wind("velocity:3,0,0")]))
    for _ in range(5000):                                  # 10 s: drifts toward the wind speed
        sim.advance((HOVER_N,) * 4, True, 0)
    assert sim.state[7] == pytest.approx(3.0 * (1 - math.exp(-10 * 0.3 / VEHICLE.mass_kg)), rel=1e-6)
    for bad in ("breeze:1,2,3", "force:1,2", "force:1,2,3@2:1", "velocity:1,2,x"):
        with pytest.raises(ValueError):
            parse_wind(bad)


def test_firmware_sim_imports_only_mavreg_config_and_the_transport():
    """The emulator stands for somebody else's firmware: of mavreg it takes the parameter files,
    the transport (bytes on the wire: the MAVLink codec, signing, serial and TCP streams),
    the fault-injection tool and the old options' action (a module of the standard library
    only), never control or physics code (pyproject's import contracts too)."""
    import re

    from tests.helpers.repo import ROOT
    root = ROOT / "firmware_sim"
    for path in root.glob("*.py"):
        text = path.read_text()
        for mod in re.findall(r"^\s*(?:from|import)\s+(mavreg[\w.]*)", text, re.M):
            assert mod.startswith(("mavreg.config", "mavreg.transport", "mavreg.tools.faultlink",
                                   "mavreg.deprecated_options")), (path.name, mod)
        assert len(text.splitlines()) < 500, path.name
    neutral = (ROOT / "mavreg" / "deprecated_options.py").read_text()
    assert re.findall(r"^\s*(?:from|import)\s+([\w.]+)", neutral, re.M) == [
        "__future__", "argparse", "decimal", "sys"]          # the standard library only


def test_fused_rk4_is_bit_identical_to_the_reference_step():
    """rk4_step (four derivatives on plain floats) against rk4_step_reference (derivative()
    on 13-tuples): the same floats, so the recorded flights' digests do not move."""
    import random
    rng = random.Random(9)
    for drag, parasitic, g in (((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), G), ((0.1, 0.12, 0.3), (0.02, 0.03, 0.05), G),
                               ((0.0, 0.0, 0.0), (0.0, 0.0, 0.01), 0.0)):
        body = RigidBody(0.749, inertia_matrix((0.0176, 0.0177, 0.034), (0.001, -0.0005, 0.0002)), drag, g, parasitic)
        for _ in range(300):
            q = [rng.gauss(0, 1) for _ in range(4)]
            n = math.sqrt(sum(v * v for v in q))
            s = (*(rng.uniform(-20, 20) for _ in range(3)), *(v / n for v in q),
                 *(rng.uniform(-10, 10) for _ in range(3)), *(rng.uniform(-8, 8) for _ in range(3)))
            args = (rng.choice([0.001, 0.002, 0.0005]), rng.uniform(0, 48), rng.uniform(-2, 2), rng.uniform(-2, 2),
                    rng.uniform(-0.3, 0.3), tuple(rng.uniform(-5, 5) for _ in range(3)),
                    tuple(rng.uniform(-3, 3) for _ in range(3)))
            assert body.rk4_step(s, *args) == body.rk4_step_reference(s, *args)
