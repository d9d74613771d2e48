"""End to end on a realistic vehicle: `mavreg fly --lockstep` on the bundled emulator's
default world (10 ms downlink and 5 ms uplink, +-3 ms jitter, 1 % loss, an EKF-like estimate
in telemetry, 20 ms rotor lag, RotorPy-sized drag), with the default controller
(params/controller/realistic.yaml: rotor lag in the design, prediction across the
TIMESYNC-measured delay, the disturbance observer). Judged by the emulator's ground truth;
lockstep at fixed seeds, so the figures are deterministic.

The true attitude is not compared with the plan's: against a drag or a wind the vehicle must
hold another attitude (the compensation turns it by up to 20 deg at 8 m/s). The attitude
error asserted is the regulator's, about the compensated nominal."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER
from mavreg.daemon.jobs.ctrllog import load_control_log
from mavreg.daemon.jobs.report import ground_truth_errors
from mavreg.sim.metrics import rotor_jitter_n
from tests.helpers.sitl import BARREL, flight_modes, load_record, mavreg, vehicle_samples

pytestmark = [pytest.mark.sitl, pytest.mark.lockstep]   # see pyproject.toml's markers


def _fly(tmp, *args):
    out = tmp / "out"
    p = mavreg("fly", str(BARREL), "--lockstep", "--out", str(out), "--timeout-s", "300", *args)
    code = p.wait(400)
    summary = json.loads((out / "summary.json").read_text())
    return {"code": code, "out": out, "summary": summary, "lines": p.lines}


def _maneuver(f, plan):
    ctrl = load_control_log(f["out"] / "control.npz")
    ph = [e for e in ctrl["events"] if e["kind"] == "phase"]
    i = next(k for k, e in enumerate(ph) if e["phase"] == "maneuver")
    t0, t1 = ph[i]["time_s"], ph[i + 1]["time_s"]
    rec = load_record(f["out"] / "groundtruth.npz")
    truth = ground_truth_errors(rec, plan, t0, t1)
    m = (ctrl["t_s"] >= t0) & (ctrl["t_s"] < t1)
    return truth, ctrl["rotor_cmd_n"][m], rec


def _controller_loop_attitude_deg(f, plan) -> float:
    """The regulator's largest attitude error (about its compensated nominal) in the loop:
    the norm of w[2:5], a rotation vector in the SO(3) form of realistic.yaml (2.2 deg on the
    drag case, where the roll-pitch-yaw form's differences read 1.5-2.0 deg)."""
    ctrl = load_control_log(f["out"] / "control.npz")
    lo, hi = next((a, b) for name, a, b in plan.segments if name == "loop")
    m = (ctrl["s_m"] >= lo) & (ctrl["s_m"] < hi)
    return float(np.degrees(np.linalg.norm(ctrl["w"][m, 2:5], axis=1)).max())


def _estimate(f) -> dict:
    return f["summary"]["status"]["disturbance"]


@pytest.fixture(scope="module")
def realistic_plan():
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.planning.plan_io import plan_file
    return plan_file(BARREL, load_vehicle(DEFAULT_VEHICLE),
                     load_controller(REAL_CONTROLLER))


def test_barrel_roll_on_a_realistic_vehicle(tmp_path, realistic_plan):
    f = _fly(tmp_path)
    assert f["code"] == 0 and f["summary"]["result"] == "ok", "\n".join(f["lines"][-20:])
    truth, rotors, rec = _maneuver(f, realistic_plan)
    loop = truth["segments"]["loop"]
    jitter = rotor_jitter_n(rotors, 500.0)
    delay = f["summary"]["status"]["link_delay_ms"]
    att = _controller_loop_attitude_deg(f, realistic_plan)
    est = _estimate(f)
    print(f"\nrealistic world: loop true max {100 * loop['max_m']:.2f} cm, speed error "
          f"{loop['max_speed_error_m_s']:.3f} m/s, regulator attitude {att:.2f} deg, "
          f"jitter {jitter:.3f} N, rotors {rotors.min():.2f}..{rotors.max():.2f} N, "
          f"measured delay {delay['sample_to_actuation']:.1f} ms, estimate {est}")
    assert loop["max_m"] <= 0.03 and att <= 2.5
    # the speed holds the profile, and never overtakes it: nothing catches up
    assert loop["max_speed_error_m_s"] <= 0.2 and loop["max_overspeed_m_s"] <= 0.3
    # the emulator's drag: 0.337 N s/m in the rotor plane (+ 0.0075 |v| parasitic), 0.652 along z
    assert 0.3 <= est["drag_n_s_per_m"][0] <= 0.5 and 0.55 <= est["drag_n_s_per_m"][1] <= 0.85
    assert jitter <= 0.3
    assert rotors.min() >= 0.0 and rotors.max() <= 12.0               # no rotor saturates
    # 10 ms down + 5 ms up, +-3 ms each, quantized to the 2 ms period: TIMESYNC sees 10-22 ms
    assert 10.0 <= delay["sample_to_actuation"] <= 22.0
    assert rec["on_ground"][-1] and not rec["armed"][-1]
    # its lockstep .tlog runs on the vehicle's clock: pymavlink's mavflightmodes.py names the
    # modes and times them as flown (the flight's vehicle time, not the wall time it took)
    changes, table = flight_modes(f["out"] / "flight.tlog")
    assert changes == ["LOITER", "OFFBOARD"]
    events = f["summary"]["events"]
    offboard_t = next(e["time_s"] for e in events if e["kind"] == "vehicle" and "OFFBOARD" in e["detail"])
    samples = vehicle_samples(f["out"] / "flight.tlog")
    loiter_s, offboard_s = offboard_t - samples[0, 1], samples[-1, 1] - offboard_t
    total_s = loiter_s + offboard_s
    print(f"mavflightmodes: {table}; flown LOITER {loiter_s:.2f} s, OFFBOARD {offboard_s:.2f} s")
    assert -0.5 <= offboard_s - table["OFFBOARD"][0] < 1.5         # it prints whole seconds, cut
    assert abs(table["LOITER"][1] * total_s - loiter_s) <= 0.05
    assert abs(table["OFFBOARD"][1] * total_s - offboard_s) <= 0.5


# Slow (20 s): the gate and margin unit tests and scripts/compare_outputs.py (+20 and +40 ms of
# command delay, both outputs) cover a long link; this is the 50 ms end-to-end check.
@pytest.mark.slow
def test_a_50_ms_link_is_flown_on_prediction(tmp_path, realistic_plan):
    f = _fly(tmp_path, "--emulator-arg=--telemetry-delay-s=0.035", "--emulator-arg=--command-delay-s=0.015")
    assert f["code"] == 0 and f["summary"]["result"] == "ok", "\n".join(f["lines"][-20:])
    truth, rotors, _ = _maneuver(f, realistic_plan)
    loop = truth["segments"]["loop"]
    att = _controller_loop_attitude_deg(f, realistic_plan)
    print(f"\n50 ms round trip: loop true max {100 * loop['max_m']:.2f} cm, regulator attitude {att:.2f} deg")
    # 1.5 cm when the world had no drag; with the realistic drag 3.0 cm (3.1 without the
    # observer's lag part): the 15 ms link's 3 cm plus what the longer prediction costs
    assert loop["max_m"] <= 0.035 and att <= 2.5


@pytest.mark.parametrize("preset, flag, check", [
    # 22 s: the observer's thrust scale is also recovered in test_disturbance.py and flown by the
    # robustness campaign's thrust cell; run before releases
    pytest.param("thrust90", None, lambda est: abs(est["thrust_scale"] - 0.9) <= 0.02, marks=pytest.mark.slow),
    # from the east: the air moves west at 3 m/s, a drag of about 1 N west
    # 18 s more for the suite: the wind's estimate is also flown by the robustness campaign's
    # wind cell; run before releases (README)
    pytest.param("wind3", "--wind-from-deg=90", lambda est: abs(est["force_ned_n"][1] + 1.05) <= 0.3
                 and abs(est["force_ned_n"][0]) <= 0.3, marks=pytest.mark.slow),
])
def test_thrust_loss_and_wind_are_estimated_and_compensated(tmp_path, realistic_plan, preset, flag, check):
    args = [f"--emulator-arg=--world={preset}"] + ([f"--emulator-arg={flag}"] if flag else [])
    f = _fly(tmp_path, *args)
    assert f["code"] == 0 and f["summary"]["result"] == "ok", "\n".join(f["lines"][-20:])
    truth, _, _ = _maneuver(f, realistic_plan)
    loop = truth["segments"]["loop"]
    est = _estimate(f)
    print(f"\n{preset} {flag or ''}: loop true max {100 * loop['max_m']:.2f} cm, speed error "
          f"{loop['max_speed_error_m_s']:.3f} m/s, estimate {est}")
    assert loop["max_m"] <= 0.03 and loop["max_speed_error_m_s"] <= 0.4 and check(est)


@pytest.mark.slow          # 18 s: the observer's negative control; before each release
def test_without_the_observer_the_drag_throws_the_loop_off(tmp_path, realistic_plan):
    """The same flight as the first test with the observer off: the drag it no longer knows
    costs the loop several centimetres (the comparison in docs/robustness.md)."""
    ctl = tmp_path / "no_observer.yaml"
    ctl.write_text(REAL_CONTROLLER.read_text()
                   .replace("disturbance:\n  enabled: true", "disturbance:\n  enabled: false"))
    f = _fly(tmp_path, "--controller", str(ctl))
    truth, _, _ = _maneuver(f, realistic_plan)
    loop = truth["segments"]["loop"]
    print(f"\nno observer: loop true max {100 * loop['max_m']:.2f} cm ({f['summary']['result']})")
    assert f["summary"]["status"]["disturbance"] is None
    assert loop["max_m"] >= 0.06


def test_a_link_too_slow_for_the_controller_keeps_the_vehicle_on_the_ground(tmp_path):
    f = _fly(tmp_path, "--emulator-arg=--telemetry-delay-s=0.12", "--emulator-arg=--command-delay-s=0.03")
    s = f["summary"]
    assert f["code"] == 1 and s["result"] == "failed"
    assert s["failure"]["bound"] == "gate_link_delay" and s["failure"]["phase"] == "preflight"
    assert any("gate_link_delay" in ln for ln in f["lines"][-3:])          # the cause in one line
    rec = load_record(f["out"] / "groundtruth.npz")
    assert np.all(rec["position_ned_m"][:, 2] > -0.01)                     # never left the ground
    assert not rec["armed"][-1]
