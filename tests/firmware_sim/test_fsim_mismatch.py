"""The seeded airframe mismatch (--mismatch-seed): the draws, the physics they drive, the
start-up line and the recording. The physics is checked against closed forms with the
emulator's own objects (rotors, mixer, rigid body), never mavreg's model."""
from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from firmware_sim.cli import build_engine, build_parser
from firmware_sim.mismatch import (BOUNDS, KEEPABLE, MismatchDraw, airframe_arrays, apply_mismatch,
                                   draw_mismatch)
from firmware_sim.params import build_sim_params, default_vehicle_path, parse_start
from firmware_sim.rotors import Rotors, mix
from firmware_sim.sim import Simulation
from tests.helpers.emulator import REPO
from mavreg.config.vehicle import load_vehicle

VEHICLE = load_vehicle(default_vehicle_path())
G = 9.81
N_DRAWS = 2000
SEEDS = range(N_DRAWS)


def _nominal(**overrides):
    return build_sim_params(VEHICLE, 500, 1000, 0, **overrides)


def _draw(**errors) -> MismatchDraw:
    """A hand-made draw: every error zero (the time constant the file's) but those given."""
    base = dict(seed=0, scale=1.0, mass_rel=0.0, inertia_rel=(0.0, 0.0, 0.0),
                rotor_gain_rel=(0.0, 0.0, 0.0, 0.0), drag_torque_ratio_rel=0.0, arm_length_rel=0.0,
                rotor_time_constant_s=VEHICLE.true_rotor_time_constant_s,
                com_offset_m=(0.0, 0.0, 0.0))
    return MismatchDraw(**{**base, **errors})


def _engine_params(*argv):
    args = build_parser().parse_args(["--listen", "udpin:127.0.0.1:0", "--quiet", *argv])
    engine, _ = build_engine(args)
    try:
        return engine.sim.params, engine
    finally:
        engine.link.close()


@pytest.fixture(scope="module")
def draws():
    return [draw_mismatch(s) for s in SEEDS]


@pytest.fixture(scope="module")
def airframes(draws):
    nominal = _nominal()
    return [apply_mismatch(nominal, d) for d in draws]


# ------------------------------------------------------------------------------ the draws
def test_a_seed_always_gives_the_same_airframe_and_another_seed_another():
    assert draw_mismatch(3) == draw_mismatch(3)
    assert draw_mismatch(3) != draw_mismatch(4)
    assert apply_mismatch(_nominal(), draw_mismatch(3)) == apply_mismatch(_nominal(), draw_mismatch(3))
    # independent of the noise seed: --seed moves the noise, not the airframe
    a, _ = _engine_params("--mismatch-seed", "3", "--seed", "0")
    b, _ = _engine_params("--mismatch-seed", "3", "--seed", "99")
    assert airframe_arrays(a).keys() == airframe_arrays(b).keys()
    for key, value in airframe_arrays(a).items():
        assert np.array_equal(value, airframe_arrays(b)[key]), key
    # a fixed value, so that a change of the stream (numpy, the spawn key, the order) shows
    assert a.vehicle.mass_kg == pytest.approx(0.649196, abs=1e-6)
    assert a.rotor_gain == pytest.approx((1.05425, 0.963435, 1.06343, 1.09749), abs=1e-5)


def test_every_parameter_stays_inside_its_bounds(airframes):
    v, emu = VEHICLE, VEHICLE.emulator
    for p in airframes:
        t = p.vehicle
        assert abs(t.mass_kg / v.mass_kg - 1.0) <= BOUNDS.mass_rel
        for i in range(3):
            assert abs(p.inertia_matrix_kg_m2[i][i] / v.inertia_kg_m2[i] - 1.0) <= BOUNDS.inertia_rel
        assert all(abs(g - 1.0) <= BOUNDS.rotor_gain_rel for g in p.rotor_gain)
        assert abs(t.drag_torque_ratio_m / v.drag_torque_ratio_m - 1.0) <= BOUNDS.drag_torque_ratio_rel
        assert abs(t.arm_length_m / v.arm_length_m - 1.0) <= BOUNDS.arm_length_rel
        tau = t.true_rotor_time_constant_s
        assert BOUNDS.rotor_time_constant_min_s <= tau <= BOUNDS.rotor_time_constant_max_s
        cx, cy, cz = p.com_offset_m
        assert math.hypot(cx, cy) <= BOUNDS.com_offset_max_m and cz == 0.0
        # untouched: saturation, noise, drag, thrust scale, products of inertia
        assert t.max_rotor_thrust_n == v.max_rotor_thrust_n
        assert t.emulator.rotor_noise_sd_n == emu.rotor_noise_sd_n
        assert t.emulator.thrust_scale == emu.thrust_scale
        assert p.inertia_matrix_kg_m2[0][1] == p.inertia_matrix_kg_m2[0][2] == 0.0


def _uniform_ks(x, lo: float, hi: float) -> float:
    """Kolmogorov-Smirnov distance of the sample ``x`` from U(lo, hi)."""
    u = np.sort((np.asarray(x) - lo) / (hi - lo))
    n = u.size
    return float(max(np.max(np.arange(1, n + 1) / n - u), np.max(u - np.arange(n) / n)))


def test_the_draws_are_uniform_as_documented(draws):
    n = len(draws)
    ks_limit = 1.95 / math.sqrt(n)               # the KS test's 0.1 % critical value
    samples = {
        "mass": ([d.mass_rel for d in draws], BOUNDS.mass_rel),
        "yaw": ([d.drag_torque_ratio_rel for d in draws], BOUNDS.drag_torque_ratio_rel),
        "arm": ([d.arm_length_rel for d in draws], BOUNDS.arm_length_rel),
        **{f"inertia{i}": ([d.inertia_rel[i] for d in draws], BOUNDS.inertia_rel) for i in range(3)},
        **{f"rotor{i}": ([d.rotor_gain_rel[i] for d in draws], BOUNDS.rotor_gain_rel) for i in range(4)},
    }
    for name, (x, b) in samples.items():
        x = np.asarray(x)
        # mean 0 (within 4 standard errors), SD b / sqrt 3, the range reaching both ends
        assert abs(x.mean()) < 4 * b / math.sqrt(3 * n), name
        assert x.std() == pytest.approx(b / math.sqrt(3), rel=0.05), name
        assert x.min() < -0.99 * b and x.max() > 0.99 * b, name
        assert _uniform_ks(x, -b, b) < ks_limit, name
    tau = np.array([d.rotor_time_constant_s for d in draws])
    assert tau.mean() == pytest.approx(0.030, abs=4 * 0.040 / math.sqrt(12 * n))
    assert tau.min() < 0.0102 and tau.max() > 0.0498
    assert _uniform_ks(tau, 0.010, 0.050) < ks_limit
    # the offset is uniform on the 1 cm disc: r^2 / R^2 and the angle uniform
    c = np.array([d.com_offset_m for d in draws])
    r = np.hypot(c[:, 0], c[:, 1])
    assert _uniform_ks((r / BOUNDS.com_offset_max_m) ** 2, 0.0, 1.0) < ks_limit
    assert _uniform_ks(np.arctan2(c[:, 1], c[:, 0]) % (2 * math.pi), 0.0, 2 * math.pi) < ks_limit
    assert abs(c[:, 0].mean()) < 4 * 0.005 / math.sqrt(n) and abs(c[:, 1].mean()) < 4 * 0.005 / math.sqrt(n)
    # independent: no correlation between any two of the 13 numbers beyond chance
    cols = np.column_stack([x for x, _ in samples.values()] + [tau, r, c[:, 0]])
    corr = np.corrcoef(cols, rowvar=False)[np.triu_indices(cols.shape[1], 1)]
    assert np.max(np.abs(corr)) < 4.5 / math.sqrt(n)


def test_without_a_seed_the_airframe_is_the_file_exactly():
    nominal = _nominal()
    assert apply_mismatch(nominal, None) is nominal
    p, engine = _engine_params()
    assert p.mismatch is None and p.rotor_gain == (1.0,) * 4 and p.com_offset_m == (0.0,) * 3
    assert p.vehicle == dataclasses.replace(VEHICLE, emulator=p.vehicle.emulator)
    assert engine.sim.rotors.gain == (1.0,) * 4 and engine.sim.com_offset_m == (0.0,) * 3
    a = airframe_arrays(p)
    assert a["airframe_mismatch_seed"] == -1 and a["airframe_mismatch_scale"] == 0.0
    assert a["airframe_mass_kg"] == VEHICLE.mass_kg
    assert a["airframe_inertia_kg_m2"].tolist() == list(VEHICLE.inertia_kg_m2)


def test_the_scale_shrinks_every_deviation_of_the_same_draw():
    nominal = _nominal()
    full = apply_mismatch(nominal, draw_mismatch(11))
    half = apply_mismatch(nominal, draw_mismatch(11, 0.5))
    v = VEHICLE
    for get in (lambda p: p.vehicle.mass_kg, lambda p: p.vehicle.arm_length_m,
                lambda p: p.vehicle.drag_torque_ratio_m, lambda p: p.inertia_matrix_kg_m2[2][2],
                lambda p: p.rotor_gain[1], lambda p: p.com_offset_m[0],
                lambda p: p.vehicle.true_rotor_time_constant_s):
        assert get(half) - get(nominal) == pytest.approx(0.5 * (get(full) - get(nominal)), rel=1e-9, abs=1e-15)
    assert half.vehicle.mass_kg != v.mass_kg
    with pytest.raises(ValueError, match="mismatch-scale"):
        draw_mismatch(1, 1.5)
    with pytest.raises(ValueError, match="mismatch-seed"):
        draw_mismatch(-1)


def test_explicit_flags_win_over_the_draw_and_the_rest_is_drawn_alike():
    drawn, _ = _engine_params("--mismatch-seed", "5")
    flags, _ = _engine_params("--mismatch-seed", "5", "--mass-kg", "0.8", "--inertia-scale", "2",
                              "--rotor-time-constant-s", "0.03")
    assert flags.mismatch_kept == tuple(sorted(KEEPABLE))
    assert flags.vehicle.mass_kg == 0.8
    assert [flags.inertia_matrix_kg_m2[i][i] for i in range(3)] == pytest.approx(
        [2 * j for j in VEHICLE.inertia_kg_m2])
    assert flags.vehicle.true_rotor_time_constant_s == 0.03
    assert flags.rotor_gain == drawn.rotor_gain and flags.com_offset_m == drawn.com_offset_m
    assert flags.vehicle.arm_length_m == drawn.vehicle.arm_length_m
    assert flags.vehicle.drag_torque_ratio_m == drawn.vehicle.drag_torque_ratio_m


def test_the_autopilot_is_tuned_on_the_file_not_the_draw():
    p, engine = _engine_params("--mismatch-seed", "3")
    assert p.vehicle.mass_kg != VEHICLE.mass_kg
    assert engine.ap.stab.m == VEHICLE.mass_kg and engine.ap.stab.l == VEHICLE.arm_length_m
    assert engine.sim.body.mass_kg == p.vehicle.mass_kg


# ------------------------------------------------------------------------------ the physics
def _rates_after_one_step(params, cmd_n):
    """Body rates (rad/s) one physics step after ``cmd_n`` from a level hover at rest."""
    sim = Simulation(params, parse_start("z_m=-50"))
    sim.advance(cmd_n, True, 0, steps=1)
    return np.array(sim.state[10:13]), sim.dt_s


def _analytic_rates(params, forces_n, arm_m, k_m, com_m, dt_s):
    """J^-1 tau dt with tau = sum (p_i - c) x (0, 0, -f_i) + k (-f1 + f2 - f3 + f4) e_z."""
    pos = np.array([[arm_m, 0, 0], [0, arm_m, 0], [-arm_m, 0, 0], [0, -arm_m, 0]], dtype=float)
    tau = sum(np.cross(p - np.asarray(com_m), [0.0, 0.0, -f]) for p, f in zip(pos, forces_n))
    tau = tau + np.array([0.0, 0.0, k_m * (-forces_n[0] + forces_n[1] - forces_n[2] + forces_n[3])])
    return np.linalg.solve(np.array(params.inertia_matrix_kg_m2), tau) * dt_s, tau


def _ideal_rotors(**errors):
    return apply_mismatch(_nominal(rotor_time_constant_s=0.0),
                          _draw(rotor_time_constant_s=0.0, **errors), kept=("rotor_time_constant_s",))


def test_per_rotor_thrust_gains_give_the_analytic_hover_torque_imbalance():
    e = (0.08, -0.05, -0.02, 0.1)
    p = _ideal_rotors(rotor_gain_rel=e)
    hover = VEHICLE.mass_kg * G / 4
    rotors = Rotors(12.0, 0.0, 0.0, 1e-3, np.random.default_rng(0), rotor_gain=p.rotor_gain)
    f = rotors.step((hover,) * 4, True)
    assert f == pytest.approx([hover * (1 + x) for x in e], rel=1e-15)
    l, k = VEHICLE.arm_length_m, VEHICLE.drag_torque_ratio_m
    T, tx, ty, tz = mix(f, l, k)
    assert T == pytest.approx(4 * hover * (1 + sum(e) / 4), rel=1e-14)
    assert tx == pytest.approx(l * hover * (e[3] - e[1]), rel=1e-12)        # l (f4 - f2)
    assert ty == pytest.approx(l * hover * (e[0] - e[2]), rel=1e-12)        # l (f1 - f3)
    assert tz == pytest.approx(k * hover * (-e[0] + e[1] - e[2] + e[3]), rel=1e-12)
    rates, dt = _rates_after_one_step(p, (hover,) * 4)
    want, _ = _analytic_rates(p, f, l, k, (0, 0, 0), dt)
    assert rates == pytest.approx(want, rel=1e-4, abs=1e-12)
    # the saturation scales with each rotor's gain
    assert rotors.step((20.0,) * 4, True) == pytest.approx([12.0 * (1 + x) for x in e])


def test_a_centre_of_mass_offset_gives_the_torque_r_cross_f():
    c = (0.006, -0.008, 0.0)
    p = _ideal_rotors(com_offset_m=c)
    f = (1.7, 2.1, 1.9, 1.6)
    l, k = VEHICLE.arm_length_m, VEHICLE.drag_torque_ratio_m
    _, tau = _analytic_rates(p, f, l, k, c, 1.0)
    assert mix(f, l, k, c[0], c[1]) == pytest.approx((sum(f), *tau), rel=1e-12)
    # at equal thrusts only the offset acts: tau = (cy T, -cx T, 0)
    hover = VEHICLE.mass_kg * G / 4
    T, tx, ty, tz = mix((hover,) * 4, l, k, c[0], c[1])
    assert (tx, ty, tz) == pytest.approx((c[1] * T, -c[0] * T, 0.0), abs=1e-15)
    rates, dt = _rates_after_one_step(p, f)
    want, _ = _analytic_rates(p, f, l, k, c, dt)
    assert rates == pytest.approx(want, rel=1e-4)


def test_the_yaw_coefficient_scales_the_yaw_torque():
    f = (1.7, 2.1, 1.9, 1.6)
    nominal = _ideal_rotors()
    yawed = _ideal_rotors(drag_torque_ratio_rel=0.3)
    assert yawed.vehicle.drag_torque_ratio_m == pytest.approx(1.3 * VEHICLE.drag_torque_ratio_m)
    r0, _ = _rates_after_one_step(nominal, f)
    r1, dt = _rates_after_one_step(yawed, f)
    assert r1[2] == pytest.approx(1.3 * r0[2], rel=1e-4)
    assert r1[:2] == pytest.approx(r0[:2], rel=1e-6)
    want, _ = _analytic_rates(yawed, f, VEHICLE.arm_length_m, yawed.vehicle.drag_torque_ratio_m, (0, 0, 0), dt)
    assert r1 == pytest.approx(want, rel=1e-4)


def test_the_arm_length_scales_the_roll_and_pitch_torques():
    f = (1.7, 2.1, 1.9, 1.6)
    nominal = _ideal_rotors()
    longer = _ideal_rotors(arm_length_rel=-0.05)
    r0, _ = _rates_after_one_step(nominal, f)
    r1, dt = _rates_after_one_step(longer, f)
    assert r1[:2] == pytest.approx(0.95 * r0[:2], rel=1e-4)
    assert r1[2] == pytest.approx(r0[2], rel=1e-6)
    want, _ = _analytic_rates(longer, f, 0.95 * VEHICLE.arm_length_m, VEHICLE.drag_torque_ratio_m, (0, 0, 0), dt)
    assert r1 == pytest.approx(want, rel=1e-4)


def test_mass_inertia_and_time_constant_reach_the_rigid_body_and_the_rotors():
    d = _draw(mass_rel=0.15, inertia_rel=(0.3, -0.3, 0.1), rotor_time_constant_s=0.045)
    p = apply_mismatch(_nominal(), d)
    sim = Simulation(p, parse_start("z_m=-50"))
    assert sim.body.mass_kg == pytest.approx(1.15 * VEHICLE.mass_kg)
    assert [sim.body.J[i][i] for i in range(3)] == pytest.approx(
        [j * (1 + e) for j, e in zip(VEHICLE.inertia_kg_m2, d.inertia_rel)])
    assert sim.rotors.alpha == pytest.approx(1 - math.exp(-1e-3 / 0.045))
    # the file's hover command, held with the rotors at it, sinks the heavier vehicle at g (1 - 1/1.15)
    hover = VEHICLE.mass_kg * G / 4
    sim.rotors.lagged_n = [hover] * 4
    sim.advance((hover,) * 4, True, 0, steps=1)
    assert sim.state[9] / sim.dt_s == pytest.approx(G * (1 - 1 / 1.15), rel=1e-6)


# ------------------------------------------------------------------------------ output
def _run(*argv, timeout=60):
    return subprocess.run([sys.executable, "-m", "firmware_sim", "--listen", "udpin:127.0.0.1:0",
                           "--quiet", "--duration-s", "0.02", *argv],
                          capture_output=True, text=True, timeout=timeout, cwd=REPO)


def test_the_start_up_line_and_the_recording_say_what_was_drawn(tmp_path):
    rec = tmp_path / "g.npz"
    out = _run("--mismatch-seed", "3", "--mass-kg", "0.8", "--record", str(rec))
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].startswith("firmware_sim listening on udpin:127.0.0.1:")
    assert lines[1].startswith("firmware_sim world: preset realistic:")
    assert lines[2].startswith("firmware_sim airframe: mismatch_seed=3 mismatch_scale=1 ")
    fields = dict(tok.split("=", 1) for tok in lines[2].split(": ", 1)[1].split())
    with np.load(rec) as z:
        for key in ("mass_kg", "inertia_kg_m2", "arm_length_m", "drag_torque_ratio_m", "rotor_gain",
                    "thrust_scale", "rotor_time_constant_s", "com_offset_m"):
            printed = [float(x) for x in fields[key].split(",")]
            assert printed == pytest.approx(np.atleast_1d(z[f"airframe_{key}"]).tolist(), rel=1e-5), key
        assert int(z["airframe_mismatch_seed"]) == 3 and float(z["airframe_mismatch_scale"]) == 1.0
        assert float(z["airframe_mass_kg"]) == 0.8 and fields["kept"] == "mass_kg"
        meta = json.loads(str(z["meta_json"]))
        # what mavreg's readers take is still there
        for key in ("t_s", "position_ned_m", "quaternion_wxyz", "velocity_ned_m_s", "rotor_cmd_n",
                    "rotor_applied_n"):
            assert z[key].shape[0] > 0
    assert meta["airframe"]["mismatch"]["seed"] == 3 and meta["airframe"]["kept"] == ["mass_kg"]
    assert meta["airframe"]["true"]["rotor_gain"] == pytest.approx(
        [float(x) for x in fields["rotor_gain"].split(",")], rel=1e-5)
    assert meta["airframe"]["bounds"]["mass_rel"] == 0.15
    # no seed: the two lines of old, the file's airframe recorded
    plain = _run("--record", str(rec))
    assert plain.returncode == 0 and len(plain.stdout.splitlines()) == 2
    with np.load(rec) as z:
        assert int(z["airframe_mismatch_seed"]) == -1 and float(z["airframe_mass_kg"]) == VEHICLE.mass_kg
        assert json.loads(str(z["meta_json"]))["airframe"]["mismatch"] is None


@pytest.mark.parametrize("argv, needle", [
    (("--mismatch-seed", "1.5"), "--mismatch-seed: expected an integer >= 0"),
    (("--mismatch-seed", "-3"), "--mismatch-seed: expected an integer >= 0"),
    (("--mismatch-seed", "x"), "--mismatch-seed: expected an integer >= 0"),
    (("--mismatch-seed", "2", "--mismatch-scale", "1.5"), "--mismatch-scale: expected a number in (0, 1]"),
    (("--mismatch-seed", "2", "--mismatch-scale", "0"), "--mismatch-scale"),
    (("--mismatch-scale", "0.5",), "--mismatch-scale needs --mismatch-seed"),
])
def test_bad_mismatch_options_exit_2_with_one_line(argv, needle):
    out = _run(*argv)
    assert out.returncode == 2 and out.stdout == ""
    assert len(out.stderr.splitlines()) == 1 and needle in out.stderr, out.stderr
