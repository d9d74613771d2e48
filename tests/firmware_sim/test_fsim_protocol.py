"""firmware_sim over loopback UDP with a plain pymavlink client (the emulator runs as a process)."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink2

from firmware_sim import modes
from tests.helpers.emulator import ARM, SET_MODE, Client, Emulator

HOVER = 0.749 * 9.81 / 4 / 12.0


def test_arm_disarm_acks_and_offboard_refused_without_stream():
    with Emulator("--world", "ideal") as emu:
        c = Client(emu.port)
        c.heartbeat()
        hb = c.wait_for("HEARTBEAT")
        assert hb.type == mavlink2.MAV_TYPE_QUADROTOR and hb.autopilot == mavlink2.MAV_AUTOPILOT_PX4
        assert hb.custom_mode == modes.HOLD and hb.base_mode == modes.BASE_MODE_CUSTOM
        assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1
        c.command(SET_MODE, 1, 6)
        assert c.ack(SET_MODE) == mavlink2.MAV_RESULT_DENIED
        c.command(ARM, 1)
        assert c.ack(ARM) == mavlink2.MAV_RESULT_ACCEPTED
        c.wait_for("HEARTBEAT", lambda m: m.base_mode & modes.BASE_MODE_ARMED)
        c.command(ARM, 0)
        assert c.ack(ARM) == mavlink2.MAV_RESULT_ACCEPTED
        c.command(31000)
        assert c.ack(31000) == mavlink2.MAV_RESULT_UNSUPPORTED
        c.wait_for("ATTITUDE")
        q = c.wait_for("ATTITUDE_QUATERNION")
        p = c.wait_for("LOCAL_POSITION_NED")
        assert q.q1 == pytest.approx(1.0) and p.z == 0.0 and p.time_boot_ms == q.time_boot_ms
        c.close()


def fly_lockstep(rec, seed="5", kill_at=None):
    """Strict lockstep client: answer every telemetry period; arm, stream, OFFBOARD, climb."""
    args = ["--world", "ideal", "--lockstep", "--seed", seed, "--rotor-noise-sd-n", "0.1", "--lockstep-stall-factor", "0", "--duration-s", "3"]
    with Emulator(*args, record=rec) as emu:
        c = Client(emu.port)
        c.heartbeat()
        texts = []
        for k in range(1500):
            m = c.wait_for("LOCAL_POSITION_NED", on_msg=lambda m: texts.append(m) if m.get_type() in
                           ("STATUSTEXT", "COMMAND_ACK") else None)
            assert m.time_boot_ms == 2 * k
            if k == 1:
                c.command(ARM, 1)
            if k == 400:
                c.command(SET_MODE, 1, 6)
            u = HOVER * (1.1 if k < 1000 else 0.97) if k >= 400 else 0.0
            c.target([u, u * 1.001, u, u])
        assert emu.proc.wait(30) == 0, emu.proc.stderr.read()      # stops itself at --duration-s
        c.close()
    return np.load(rec), texts


def test_lockstep_is_deterministic(tmp_path):
    a, texts = fly_lockstep(tmp_path / "a.npz")
    b, _ = fly_lockstep(tmp_path / "b.npz")
    assert [m.result for m in texts if m.get_type() == "COMMAND_ACK"] == [0, 0]
    assert a["t_s"].shape == b["t_s"].shape and a["t_s"][-1] == 3.0
    for key in ("t_s", "position_ned_m", "quaternion_wxyz", "velocity_ned_m_s", "body_rates_rad_s",
                "rotor_cmd_n", "rotor_applied_n", "armed", "custom_mode"):
        assert np.array_equal(a[key], b[key]), key
    assert a["position_ned_m"][:, 2].min() < -1.0            # it flew
    assert (a["custom_mode"][-1] == modes.OFFBOARD) and a["armed"][-1]
    c, _ = fly_lockstep(tmp_path / "c.npz", seed="6")
    assert not np.array_equal(a["rotor_applied_n"], c["rotor_applied_n"])


def test_failsafe_from_inverted_in_flight_start_lands_and_disarms(tmp_path):
    rec = tmp_path / "f.npz"
    # The emulator stops itself at --duration-s: the test reads nothing (a stalled lockstep
    # runs flat out, and a slow reader would lose datagrams to its full socket buffer).
    with Emulator("--world", "ideal", "--lockstep", "--lockstep-stall-factor", "0", "--start",
                  "z_m=-6,vy_m_s=8,roll_deg=120", "--duration-s", "12", record=rec) as emu:
        c = Client(emu.port)
        c.heartbeat()                  # the daemon "dies" right away: no targets ever
        assert emu.proc.wait(60) == 0, emu.proc.stderr.read()
        c.close()
    d = np.load(rec)
    t, mode, armed = d["t_s"], d["custom_mode"], d["armed"]
    t_hold = t[np.argmax(mode == modes.HOLD)]
    t_land = t[np.argmax(mode == modes.LAND)]
    t_disarm = t[np.argmax(~armed)]
    assert t_hold == pytest.approx(0.25, abs=0.01)
    assert t_land == pytest.approx(0.25 + 1.5, abs=0.01)
    assert t_disarm < 20.0
    q = d["quaternion_wxyz"]
    tilt = np.degrees(np.arccos(np.clip(1 - 2 * (q[:, 1] ** 2 + q[:, 2] ** 2), -1, 1)))
    assert tilt[(t > 1.0) & (t < t_disarm)].max() < 45.0         # upright within 0.75 s of failsafe
    assert tilt[(t > t_land + 1.5) & (t < t_disarm)].max() < 10.0   # level once it stopped
    landing = d["velocity_ned_m_s"][(t > t_land + 3) & ~d["on_ground"], 2]
    assert 0.5 < landing.mean() < 1.0                            # descends at about 0.8 m/s
    assert d["position_ned_m"][-1, 2] == 0.0 and d["on_ground"][-1]
    assert not armed[-1] and mode[-1] == modes.HOLD                 # landed, disarmed, back to HOLD


def test_bad_input_is_dropped_counted_and_sim_keeps_running(tmp_path):
    with Emulator("--world", "ideal", "--lockstep", "--lockstep-stall-factor", "0",
                  record=tmp_path / "r.npz") as emu:
        c = Client(emu.port)
        foreign = Client(emu.port, system_id=9, component_id=191)
        other = Client(emu.port, system_id=1, component_id=190)
        c.heartbeat()
        good = mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3).pack(c.mav)
        crc_bad = bytearray(good); crc_bad[-1] ^= 0xFF
        c.wait_for("LOCAL_POSITION_NED")
        c.target([0.1] * 4)                                    # 191 is the offboard peer
        c.send(b"\x00\x01garbage")
        c.send(bytes(crc_bad))
        c.send(good[:7])                                       # truncated
        foreign.target([0.1] * 4)
        other.target([0.1] * 4)
        c.target([math.nan, 0, 0, 0])
        c.target([0.2, 1.2, 0, 0])
        c.target([0.1] * 4, target_system=3)
        c.command(31000)
        assert c.ack(31000) == mavlink2.MAV_RESULT_UNSUPPORTED
        c.target([0.1] * 4)                                    # disarmed: counted
        c.wait_for("LOCAL_POSITION_NED", lambda m: m.time_boot_ms > 20)
        assert emu.stop() == 0
    meta = __import__("json").loads(str(np.load(tmp_path / "r.npz")["meta_json"]))
    d = meta["drops"]
    assert d["malformed"] >= 3 and d["foreign_system"] == 1 and d["foreign_component"] == 1
    assert d["non_finite"] == 1 and d["out_of_range"] == 1 and d["wrong_target"] == 1
    assert d["unsupported"] == 1 and d["not_armed_or_not_offboard"] >= 2


def test_mavutil_connection_sees_heartbeat_arms_and_reads_telemetry():
    # a ground station (system 255) is a peer only when configured so (docs/firmware_sim.md)
    with Emulator("--world", "ideal", "--peer-system-id", "255") as emu:
        conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{emu.port}", source_system=255,
                                          source_component=190)
        conn.mav.heartbeat_send(6, 8, 0, 0, 0)
        hb = conn.wait_heartbeat(timeout=5)
        assert hb is not None and conn.target_system == 1
        # announced as PX4, so pymavlink names the mode as log tools and ground stations do
        assert hb.autopilot == mavlink2.MAV_AUTOPILOT_PX4 and conn.flightmode == "LOITER"
        assert mavutil.mode_string_v10(hb) == "LOITER"
        conn.mav.command_long_send(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
        ack = conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
        assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
        pos = conn.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=5)
        att = conn.recv_match(type="ATTITUDE_QUATERNION", blocking=True, timeout=5)
        assert pos is not None and att is not None
        end = time.monotonic() + 5
        while time.monotonic() < end:
            hb = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
            if hb.base_mode & modes.BASE_MODE_ARMED:
                break
        assert hb.base_mode & modes.BASE_MODE_ARMED
        conn.close()


def test_cli_bad_input_exits_2_without_traceback(tmp_path):
    import subprocess
    import sys
    bad = tmp_path / "v.yaml"
    bad.write_text("kind: vehicle\nversion: 1\nname: x\nmass_kg: -1\n")
    for args in (["--vehicle-params", str(bad)], ["--control-rate-hz", "300"], ["--wind", "breeze:1"],
                 ["--start", "z_m=1"], ["--listen", "tcp:1"], ["--world", "perfect"], ["--loss", "1.5"],
                 ["--loss", "x"], ["--telemetry-delay-s", "-0.001"], ["--telemetry-jitter-s", "0.02"],
                 ["--command-delay-s", "0.002", "--command-jitter-s", "0.003"], ["--estimator-scale", "nan"],
                 ["--estimate-latency-s", "5"], ["--command-delay-s", "inf"], ["--rate-latency-s", "0.2"],
                 ["--telemetry-delay-ms", "-1"], ["--estimate-latency-ms", "5000"]):
        r = subprocess.run([sys.executable, "-m", "firmware_sim", *args], capture_output=True,
                           text=True, timeout=30)
        assert r.returncode == 2, args
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
