"""End to end: calibrate the bundled emulator from one barrel roll (`mavreg identify`).

The emulator is made to differ from the vehicle file the daemon flies with, by known amounts:
body drag [0.337, 0.337, 0.652] N s/m with no parasitic part, a 30 ms rotor time constant
(the file says 20 ms) and rotors that give 90 % of the commanded thrust. (With a drag of
[0.3, 0.3, 0.15] the calibrated barrel roll is infeasible: its exit would pull rotor 2 at
-0.28 N; `mavreg plan` says so and the daemon refuses it.) Realistic world (link
delay and jitter, loss, EKF-like estimate), lockstep: deterministic.
"""
from __future__ import annotations

import json

import pytest

from mavreg.config.paths import REAL_CONTROLLER

from tests.helpers.sitl import BARREL, mavreg

pytestmark = pytest.mark.sitl

THRUST_SCALE = 0.9
DRAG = (0.337, 0.337, 0.652)       # the realistic preset's rotor drag (RotorPy's), no parasitic part
TAU_S = 0.03


EMULATOR = ("--emulator-arg=--drag-n-s-per-m", *(f"--emulator-arg={c}" for c in DRAG),
            "--emulator-arg=--parasitic-drag-n-s2-per-m2", *(["--emulator-arg=0"] * 3),
            f"--emulator-arg=--rotor-time-constant-s={TAU_S}", f"--emulator-arg=--thrust-scale={THRUST_SCALE}")


@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("identify")
    out = tmp / "flight"
    fly = mavreg("fly", str(BARREL), "--lockstep", "--out", str(out), "--timeout-s", "300", *EMULATOR)
    fly_code = fly.wait(400)
    # the flight's outcome is not the point, its data is
    assert fly_code in (0, 1) and (out / "flight.tlog").exists(), "\n".join(fly.lines[-20:])
    vehicle = tmp / "calibrated.yaml"
    ident = mavreg("identify", str(out), "--json", "--write-vehicle", str(vehicle))
    assert ident.wait(120) == 0, "\n".join(ident.lines[-20:])
    return json.loads("\n".join(ident.lines)), vehicle, tmp


@pytest.fixture(scope="module")
def identified(calibration):
    return calibration[0]


@pytest.mark.slow
def test_the_calibrated_vehicle_flies_the_drag_forward(calibration):
    """The loop a user closes: fly, identify, fly again on the written vehicle file. The plan
    then feeds the drag, the thrust scale and the lag forward; the observer finds almost
    nothing left to estimate. (Slow: a second realistic flight, about 40 s; the default suite
    keeps the identification itself, and the written file is checked by
    ``tests/unit/test_identify_cli.py``.)"""
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.daemon.jobs.report import ground_truth_errors
    from mavreg.planning.plan_io import plan_file
    from tests.helpers.sitl import load_record
    _, vehicle, tmp = calibration
    out = tmp / "calibrated_flight"
    fly = mavreg("fly", str(BARREL), "--lockstep", "--out", str(out), "--timeout-s", "300",
                 "--vehicle-params", str(vehicle), *EMULATOR)
    assert fly.wait(400) == 0, "\n".join(fly.lines[-20:])
    summary = json.loads((out / "summary.json").read_text())
    plan = plan_file(BARREL, load_vehicle(vehicle), load_controller(REAL_CONTROLLER))
    events = [e for e in summary["events"] if e["kind"] == "phase"]
    i = next(k for k, e in enumerate(events) if e["phase"] == "maneuver")
    truth = ground_truth_errors(load_record(out / "groundtruth.npz"), plan, events[i]["time_s"],
                                events[i + 1]["time_s"])
    loop = truth["segments"]["loop"]
    est = summary["status"]["disturbance"]
    print(f"\ncalibrated vehicle: loop true max {100 * loop['max_m']:.2f} cm, speed error "
          f"{loop['max_speed_error_m_s']:.3f} m/s, estimate {est}")
    assert loop["max_m"] <= 0.03 and loop["max_speed_error_m_s"] <= 0.2
    assert abs(est["thrust_scale"] - THRUST_SCALE) <= 0.02


@pytest.mark.slow          # 32 s: a realistic flight and its identification; before each release (identify from one flight stays in the suite: test_rates_sitl; the fits: tests/unit/test_identify_*)
def test_identify_recovers_drag_thrust_scale_and_rotor_lag(identified):
    d = identified
    ratio = THRUST_SCALE
    s_t = d["thrust_scale"]["value"]
    c_y, c_z = d["drag_n_s_per_m"]["y"]["value"], d["drag_n_s_per_m"]["z"]["value"]
    tau = d["rotor_time_constant_s"]["value"]
    print(f"\nidentified: thrust scale {s_t:.4f} (true {ratio:.4f}), c_y {c_y:.3f} (true {DRAG[1]:.3f}), "
          f"c_z {c_z:.3f} (true {DRAG[2]:.3f}), tau {1e3 * tau:.1f} ms (true {1e3 * TAU_S:.0f}), "
          f"delay {d['delay_source']}, residual {d['residual_rms_m_s2']:.3f} m/s2, R2 {d['r_squared']:.4f}")
    assert s_t == pytest.approx(ratio, rel=0.10)
    assert c_y == pytest.approx(DRAG[1], rel=0.10)
    assert c_z == pytest.approx(DRAG[2], rel=0.10)
    assert tau == pytest.approx(TAU_S, rel=0.20)
    assert d["delay_source"].startswith("TIMESYNC")
    # the barrel roll flies sideways: no speed along body x, so c_x is not claimed
    assert d["drag_n_s_per_m"]["x"]["value"] is None and "body x speed" in d["drag_n_s_per_m"]["x"]["why"]
    assert d["model"] == "linear body drag"          # the emulator's drag has no quadratic part
    assert d["duration_s"] > 30.0
