"""End-to-end: firmware_sim --lockstep and the daemon as separate processes, judged by the
emulator's ground-truth recording."""
from __future__ import annotations

import signal
import subprocess
import time

import numpy as np
import pytest

from conftest import fly_lockstep
from mavreg.daemon.jobs.ctrllog import load_control_log
from mavreg.daemon.jobs.report import ground_truth_errors
from tests.helpers.sitl import BARREL, VEHICLE_IDEAL, flight_modes, tilt_deg, vehicle_samples

pytestmark = [pytest.mark.sitl, pytest.mark.lockstep]   # see pyproject.toml's markers

OFFBOARD = 6 << 16


def _maneuver_window(out):
    ctrl = load_control_log(out / "control.npz")
    ph = [e for e in ctrl["events"] if e["kind"] == "phase"]
    i = next(k for k, e in enumerate(ph) if e["phase"] == "maneuver")
    return ph[i]["time_s"], ph[i + 1]["time_s"]


def _truth(flight, plan):
    t0, t1 = _maneuver_window(flight["out"])
    return ground_truth_errors(flight["record"], plan, t0, t1)


def test_barrel_roll_from_the_ground_ideal_actuators(ideal_flight, barrel_plan):
    f = ideal_flight
    assert f["code"] == 0 and f["emu_code"] == 0, "\n".join(f["lines"][-30:])
    rec = f["record"]
    # take-off, maneuver, landing, disarm: seen in the vehicle's own recording
    assert rec["on_ground"][0] and not rec["armed"][0]
    assert -rec["position_ned_m"][:, 2].min() > 10.0            # the loop climbs to ~11 m
    assert np.any(rec["armed"] & (rec["custom_mode"] == OFFBOARD))
    assert rec["on_ground"][-1] and not rec["armed"][-1]
    roll = np.degrees(np.unwrap(np.arctan2(
        2 * (rec["quaternion_wxyz"][:, 0] * rec["quaternion_wxyz"][:, 1]
             + rec["quaternion_wxyz"][:, 2] * rec["quaternion_wxyz"][:, 3]),
        1 - 2 * (rec["quaternion_wxyz"][:, 1] ** 2 + rec["quaternion_wxyz"][:, 2] ** 2))))
    assert roll.max() - roll.min() > 350.0                         # the 360 deg roll happened
    truth = _truth(f, barrel_plan)
    print(f"\nideal actuators: true max transverse error {100 * truth['max_m']:.3f} cm, "
          f"RMS {100 * truth['rms_m']:.3f} cm over {truth['samples']} physics steps")
    for name, st in truth["segments"].items():
        print(f"  {name:<14} max {100 * st['max_m']:.3f} cm  rms {100 * st['rms_m']:.3f} cm")
    assert truth["samples"] > 10000
    assert truth["max_m"] < 0.02
    assert truth["segments"]["loop"]["max_m"] < 0.02


def test_mavlogdump_reads_the_tlog(ideal_flight):
    tlog = ideal_flight["out"] / "flight.tlog"
    res = subprocess.run(["mavlogdump.py", "--types", "SET_ACTUATOR_CONTROL_TARGET,HEARTBEAT,COMMAND_ACK",
                          str(tlog)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    n_act = sum("SET_ACTUATOR_CONTROL_TARGET" in ln for ln in lines)
    st = ideal_flight["summary"]["status"]
    assert n_act == st["counters"]["actuator_sent"] > 10000
    assert any("type : 18, autopilot : 8" in ln for ln in lines)      # our heartbeat (out)
    assert any("type : 2" in ln and "HEARTBEAT" in ln for ln in lines)  # the vehicle's (in)
    assert any("COMMAND_ACK" in ln for ln in lines)


def test_lockstep_tlog_follows_the_vehicle_clock(ideal_flight):
    """A lockstep flight runs faster than real time: its .tlog is stamped with the vehicle's
    clock (not the wall clock), so log tools show the flight's own durations."""
    tlog = ideal_flight["out"] / "flight.tlog"
    rows = vehicle_samples(tlog)
    period_s = 1.0 / 500.0
    stamp, vehicle = rows[:, 0] - rows[0, 0], rows[:, 1] - rows[0, 1]
    # each sample is logged as it arrives, stamped with the vehicle time known then: the
    # previous sample's (at most one sample period behind; time_boot_ms has 1 ms steps)
    lag = vehicle - stamp
    assert lag.min() >= -1e-6 and lag.max() <= period_s + 1e-3 + 1e-6, (lag.min(), lag.max())
    assert vehicle[-1] > 40.0                                    # the whole flight
    # mavflightmodes.py (pymavlink) names the PX4 modes and stamps each change on the vehicle's
    # clock: LOITER lasts from the first sample to the switch to OFFBOARD, as the daemon saw it.
    # (Its time in the last mode is extrapolated from the file's size: checked on the
    # realistic world's flight, test_realistic_sitl.py, whose telemetry is never all zeros.)
    changes, table = flight_modes(tlog)
    assert changes == ["LOITER", "OFFBOARD"] and set(table) == {"LOITER", "OFFBOARD"}
    events = ideal_flight["summary"]["events"]
    offboard_t = next(e["time_s"] for e in events if e["kind"] == "vehicle" and "OFFBOARD" in e["detail"])
    from pymavlink import mavutil
    conn = mavutil.mavlink_connection(str(tlog))
    modes = []
    while (m := conn.recv_match(type="HEARTBEAT", condition=f'MAV.flightmode!="{conn.flightmode}"')) is not None:
        modes.append((conn.flightmode, m._timestamp))
    assert [name for name, _ in modes] == changes
    assert abs((modes[1][1] - modes[0][1]) - (offboard_t - rows[0, 1])) <= period_s + 1e-3


def test_fly_outputs_and_summary(ideal_flight):
    out = ideal_flight["out"]
    for name in ("summary.json", "flight.png", "flight.tlog", "control.npz"):
        assert (out / name).stat().st_size > 0
    s = ideal_flight["summary"]
    assert s["result"] == "ok"
    segs = s["controller_metrics"]["segments"]
    assert {"run_up", "loop", "run_out"} <= set(segs)
    for blk in segs.values():
        assert blk["saturated_s"] == 0.0 and blk["rotor_command_n"]["max"] < 12.0
    text = "\n".join(ideal_flight["lines"])
    assert "loop" in text and "max e_t mm" in text and "nan" not in text
    # every event has a time: the daemon's clock always, the vehicle's (counted back before its
    # first sample, so the queued upload is at a negative time)
    ev = s["events"]
    assert all(e["time_s"] is not None and e["daemon_time_s"] is not None for e in ev)
    assert ev[0]["kind"] == "queued" and ev[0]["time_s"] < 0.0 < ev[0]["daemon_time_s"]
    assert [e["time_s"] for e in ev] == sorted(e["time_s"] for e in ev)
    # how it was produced: the command, the files and their hashes, the software
    import hashlib
    prov = s["provenance"]
    assert prov["argv"][:3] == ["mavreg", "fly", str(BARREL)] and "--vehicle-lockstep" in prov["argv"]
    assert prov["files"]["maneuver"]["sha256"] == hashlib.sha256(BARREL.read_bytes()).hexdigest()
    assert prov["files"]["vehicle"]["sha256"] == hashlib.sha256(VEHICLE_IDEAL.read_bytes()).hexdigest()
    assert len(prov["files"]["controller"]["sha256"]) == 64
    assert prov["world"] is None                 # the vehicle was given by URL: not ours to describe
    assert prov["mavreg_version"] and prov["python_version"] and prov["numpy_version"]


@pytest.mark.slow          # 15 s; the realistic world's flights fly the same lag; before each release
def test_barrel_roll_with_default_motor_lag(tmp_path, barrel_plan):
    f = fly_lockstep(tmp_path)
    assert f["code"] == 0 and f["emu_code"] == 0, "\n".join(f["lines"][-30:])
    truth = _truth(f, barrel_plan)
    print(f"\ndefault motor lag (20 ms): true max transverse error {100 * truth['max_m']:.2f} cm, "
          f"RMS {100 * truth['rms_m']:.2f} cm")
    for name, st in truth["segments"].items():
        print(f"  {name:<14} max {100 * st['max_m']:.2f} cm  rms {100 * st['rms_m']:.2f} cm")
    assert f["record"]["on_ground"][-1] and not f["record"]["armed"][-1]
    # The regulator leads its feedforward by the 20 ms lag it assumes (mk_quadro.yaml):
    # measured 0.4 cm; without the lead it was 4.6 cm.
    assert truth["max_m"] < 0.02


def _same_flight(a, b):
    """Largest distance between two flights' true positions, aligned at the first OFFBOARD step
    (the emulator's clock may start earlier when another peer is heard first)."""
    def from_offboard(f):
        rec = f["record"]
        i0 = int(np.flatnonzero(rec["armed"] & (rec["custom_mode"] == OFFBOARD))[0])
        return rec["position_ned_m"][i0:]
    pa, pb = from_offboard(a), from_offboard(b)
    n = min(len(pa), len(pb))
    return float(np.max(np.linalg.norm(pa[:n] - pb[:n], axis=1))), abs(len(pa) - len(pb))


@pytest.mark.slow     # 14 s: a second ideal flight compared bit for bit; the hostile-uploads flight
# (test_hostile_uploads_sitl.py) keeps rejected uploads mid-flight in the suite
def test_invalid_upload_mid_flight_is_rejected_and_changes_nothing(tmp_path, ideal_flight, barrel_plan):
    sock = tmp_path / "mavreg.sock"
    bad = tmp_path / "bad.yaml"
    bad.write_text(BARREL.read_text().replace("radius_m: 1.5", "radius_m: -1.5"))
    infeasible = tmp_path / "too_fast.yaml"
    infeasible.write_text(BARREL.read_text().replace("to_m_s: 8.0", "to_m_s: 30.0"))

    def during(fly, emu):
        fly.wait_line("[maneuver] phase", 200)
        # The lockstep vehicle waits while the uploads are planned (the planner runs at the
        # lowest priority: on a loaded machine the flight could end first).
        emu.p.send_signal(signal.SIGSTOP)
        try:
            verdicts = []
            for f in (bad, infeasible):
                r = subprocess.run(["mavreg", "upload", str(f), "--socket", str(sock)], capture_output=True,
                                   text=True, timeout=300)
                verdicts.append((r.returncode, r.stdout.strip()))
        finally:
            emu.p.send_signal(signal.SIGCONT)
        return verdicts

    f = fly_lockstep(tmp_path, (), ("--socket", str(sock), "--stale-timeout-s", "300"), during,
                     vehicle=VEHICLE_IDEAL)
    assert f["code"] == 0, "\n".join(f["lines"][-30:])
    (c1, v1), (c2, v2) = f["extra"]
    print(f"\nverdicts: {v1!r}\n          {v2!r}")
    assert c1 == 1 and v1.startswith("rejected:") and "radius_m" in v1
    assert c2 == 1 and v2.startswith("rejected:")
    assert f["summary"]["status"]["uploads"] == {"accepted": 1, "rejected": 2}   # 1: the flight itself
    truth = _truth(f, barrel_plan)
    assert truth["max_m"] < 0.02
    dist, dlen = _same_flight(f, ideal_flight)
    print(f"largest distance to the undisturbed flight: {dist:.2e} m")
    assert dist < 1e-3


# Slow (15 s): the peer filter and the fuzzing targets test foreign traffic in the default suite.
@pytest.mark.slow
def test_foreign_system_actuator_traffic_changes_nothing(tmp_path, ideal_flight):
    from pymavlink.dialects.v20 import common as mavlink2
    import socket as pysocket

    def during(fly, emu):
        port = int(emu.wait_line("listening on", 5).rsplit(":", 1)[1])
        s = pysocket.socket(pysocket.AF_INET, pysocket.SOCK_DGRAM)
        mav = mavlink2.MAVLink(None, srcSystem=42, srcComponent=191)
        impostor = mavlink2.MAVLink(None, srcSystem=42, srcComponent=1)
        sent = 0
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and fly.p.poll() is None:
            for m, frm in ((mavlink2.MAVLink_set_actuator_control_target_message(
                    0, 0, 1, 1, [1.0, 0.0, 1.0, 0.0, 0, 0, 0, 0]), mav),
                    (mavlink2.MAVLink_command_long_message(1, 1, 400, 0, 0, 21196, 0, 0, 0, 0, 0), mav),
                    (mavlink2.MAVLink_heartbeat_message(2, 0, 0, 0, 4, 3), impostor)):
                s.sendto(m.pack(frm), ("127.0.0.1", port))
                sent += 1
            time.sleep(0.005)
        s.close()
        return sent

    # a long lockstep timeout: on a loaded machine a period timed out in one flight and not in
    # the other made them differ by 6 mm; the comparison needs both exactly deterministic
    f = fly_lockstep(tmp_path, ("--lockstep-timeout-s", "3"), (), during, vehicle=VEHICLE_IDEAL)
    assert f["extra"] > 100
    assert f["code"] == 0, "\n".join(f["lines"][-30:])
    dist, _ = _same_flight(f, ideal_flight)
    print(f"\nforeign messages sent: {f['extra']}; largest distance to the clean flight: {dist:.2e} m")
    assert dist < 1e-3


def test_killing_the_daemon_mid_maneuver_lets_the_failsafe_land(tmp_path):
    from tests.helpers.sitl import CONTROLLER, load_record, mavreg, start_emulator
    from mavreg.daemon.jobs.endpoint import request
    record = tmp_path / "gt.npz"
    sock = tmp_path / "mavreg.sock"
    # Lockstep until the kill, then as fast as it can: a 3 s lockstep wait, as the other tests
    # that stall the emulator on purpose take, so that a loaded host's stall of the living daemon
    # (over the default 0.1 s) does not set the emulator running ahead of it into its
    # offboard-loss failsafe before the maneuver (a CI run beside a campaign saw that once).
    emu, url = start_emulator(record, "--lockstep", "--world", "ideal", "--lockstep-timeout-s", "3",
                              "--lockstep-stall-factor", "0", "--duration-s", "100")
    try:
        fly = mavreg("fly", str(BARREL), "--vehicle", url, "--vehicle-lockstep", "--out", str(tmp_path / "out"),
                     "--controller", str(CONTROLLER), "--socket", str(sock))
        fly.wait_line("[maneuver] phase", 200)
        s_kill = None
        for _ in range(20000):   # kill it inside the loop (s between 19.5 and 27 m)
            st = request(sock, {"op": "status"}, 10)["status"]
            if st["s_m"] is not None and st["s_m"] > 21.0:
                s_kill = st["s_m"]
                break
        fly.stop(sig=9)
        assert s_kill is not None
        emu_code = emu.wait(200)
    finally:
        emu.stop()
        fly.stop()
    assert emu_code == 0, "\n".join(emu.lines[-20:])
    rec = load_record(record)
    armed_offboard = np.flatnonzero(rec["armed"] & (rec["custom_mode"] == OFFBOARD))
    t_loss = rec["t_s"][armed_offboard[-1]]
    after = rec["t_s"] > t_loss
    speed = np.linalg.norm(rec["velocity_ned_m_s"], axis=1)
    print(f"\ndaemon killed at s={s_kill:.2f} m; "
          f"command stream lost at t={t_loss:.2f} s at {speed[armed_offboard[-1]]:.1f} m/s, "
          f"altitude {-rec['position_ned_m'][armed_offboard[-1], 2]:.1f} m")
    assert speed[armed_offboard[-1]] > 5.0                      # it really was mid-maneuver
    modes = set(np.unique(rec["custom_mode"][after]).tolist())
    assert (3 << 24) | (4 << 16) in modes and (6 << 24) | (4 << 16) in modes   # HOLD, then LAND
    tilt = tilt_deg(rec["quaternion_wxyz"])
    level = after & (rec["t_s"] > t_loss + 2.0)
    assert tilt[level & ~rec["on_ground"]].max() < 15.0          # levelled
    assert rec["on_ground"][-1] and not rec["armed"][-1]          # landed and disarmed
