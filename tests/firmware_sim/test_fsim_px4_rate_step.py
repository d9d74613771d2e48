"""The emulator's rate mode as PX4's: configured as PX4's SIH quadrotor with PX4's rate-loop
parameters (tests/helpers/emulator_as_sih.py), its roll and pitch step is a stock PX4's, as
measured on SIH (docs/firmware_sim.md, "PX4's SIH quadrotor"). tests/sitl/test_px4_rate_step.py
measures PX4 again where its SITL is present."""
from __future__ import annotations

import math

import pytest

from firmware_sim.cli import build_parser
from firmware_sim.params import build_sim_params, load_sim_params
from firmware_sim.physics import G
from firmware_sim.px4_args import rate_loop_config
from firmware_sim.sim import Simulation
from tests.helpers.emulator_as_sih import PX4_RATE_DEFAULTS, VEHICLE, emulator_sih_args, printed_figures

PX4_STEP = {"roll": {"t10": 28.4, "t50": 78.05, "t90": 142.55, "overshoot": 3.4, "final": 1.024, "tau": 62.65,
                     "delay": 28.9},
            "pitch": {"t10": 27.45, "t50": 76.25, "t90": 140.3, "overshoot": 4.1, "final": 1.0345, "tau": 61.4,
                      "delay": 28.2}}
"""PX4 v1.16.0 SIH with its defaults (MC_ROLLRATE_P 0.15, I 0.2, D 0.003, K 1; IMU_GYRO_CUTOFF 40,
IMU_DGYRO_CUTOFF 30; lockstep at 250 Hz): 1 rad/s steps held 0.4 s, from the send to SIH's true
rate, on PX4's clock (ms, %, fraction); the mean of two runs of 6 steps an axis, measured
2026-11-29 with ``python -m scripts.px4.rate_step --json runN.json`` alone on the machine under
the PX4 lock (PX4's clock at 0.946 and 0.963 of the wall clock). Roll 10/50/90 % at
26.8/77.7/144.3 and 30.0/78.4/140.8 ms, pitch at 27.1/77.3/141.9 and 27.8/75.2/138.7 ms."""


def test_the_emulator_as_sih_steps_as_the_measured_px4():
    emu = printed_figures(emulator_sih_args())
    for axis, px4 in PX4_STEP.items():
        e = emu[axis]
        assert e["t50"] == pytest.approx(px4["t50"], rel=0.10), axis           # the bound
        assert e["t90"] == pytest.approx(px4["t90"], rel=0.10), axis
        assert e["t10"] == pytest.approx(px4["t10"], rel=0.15), axis
        assert e["tau"] == pytest.approx(px4["tau"], rel=0.15) and e["delay"] == pytest.approx(px4["delay"], abs=5.0)
        assert e["final"] == pytest.approx(px4["final"], abs=0.05) and e["overshoot"] <= px4["overshoot"] + 3.0


def test_in_the_old_torque_unit_px4s_gains_give_a_slower_step():
    """Negative control: PX4's gains in the emulator's former unit (a rotor pair differing by
    f_max, 1/sqrt 2 of PX4's torque per unit) make the step a quarter slower at 50 % (96 ms)."""
    old = {name: PX4_RATE_DEFAULTS[name] / math.sqrt(2) for name in PX4_RATE_DEFAULTS
           if name.startswith(("MC_ROLLRATE_", "MC_PITCHRATE_", "MC_RR_", "MC_PR_")) and not name.endswith("_K")}
    emu = printed_figures(emulator_sih_args(old))
    assert emu["roll"]["t50"] > 1.15 * PX4_STEP["roll"]["t50"]


def test_rate_params_on_the_command_line_set_the_loop_and_are_checked(capsys):
    args = build_parser().parse_args(["--rate-param", "MC_ROLLRATE_P=0.15", "--rate-param", "IMU_GYRO_CUTOFF=40",
                                      "--thr-mdl-fac", "0"])
    cfg = rate_loop_config(args)
    assert (cfg.roll_p, cfg.gyro_cutoff_hz, cfg.thr_mdl_fac) == (0.15, 40.0, 0.0)
    for bad in ("MC_ROLLRATE_P=11", "MC_FOO=1", "MC_ROLLRATE_P=x"):
        with pytest.raises(SystemExit) as exc:
            build_parser().parse_args(["--rate-param", bad])
        assert exc.value.code == 2
    assert "not a rate loop parameter" in capsys.readouterr().err


def test_angular_drag_damps_a_free_spin_as_sihs():
    """SIH_KDW 0.025 on 0.025 kg m^2: a free roll rate decays as exp(-t / 1 s)."""
    params = load_sim_params(VEHICLE, 250, 1000, 0, angular_drag_n_m_s_per_rad=0.025, rotor_time_constant_s=0.0)
    v = params.vehicle
    sim = Simulation(params, (0.0, 0.0, -50.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0))
    hover = (v.mass_kg * G / 4,) * 4
    for _ in range(250):
        sim.advance(hover, True, 0)
    assert sim.state[10] == pytest.approx(2.0 * math.exp(-1.0), rel=0.01)
    with pytest.raises(ValueError):
        build_sim_params(v, 250, 1000, 0, angular_drag_n_m_s_per_rad=-1.0)
