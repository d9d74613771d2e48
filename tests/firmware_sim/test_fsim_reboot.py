"""The emulator's reboots (firmware_sim/reboot.py): MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN refused
while armed and carried out on the ground (ACK, 0.4 s, silent for --reboot-time-s, then a new
autopilot whose time_boot_ms counts from 0), and the injected in-air reboot (--reboot-at-s):
the motors stop, the fall's hard touchdown is recorded, not a crash exit. In process on the
command line's engine (vehicle time), and once as a process in lockstep."""
from __future__ import annotations

import json

import numpy as np
from pymavlink.dialects.v20 import common as M

from firmware_sim import modes
from tests.helpers.emulator import ARM, Client, Emulator, Vehicle

REBOOT = M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN


def _times(msgs, mtype="LOCAL_POSITION_NED") -> list:
    return [m.time_boot_ms for m in msgs if m.get_type() == mtype]


def test_a_reboot_is_denied_while_armed_and_nothing_changes():
    v = Vehicle()
    v.run(0.1)
    assert v.ack(ARM, 1) == M.MAV_RESULT_ACCEPTED
    out = v.command(REBOOT, 1)
    assert [m.result for m in out if m.get_type() == "COMMAND_ACK"] == [M.MAV_RESULT_DENIED]
    assert any(m.get_type() == "STATUSTEXT" and b"reboot denied: armed" in m.text.encode() for m in out)
    after = v.run(2.5)
    assert v.engine.ap.armed and not v.engine.reboots.records
    assert np.all(np.diff(_times(after)) > 0)


def test_param1_zero_is_accepted_and_does_nothing_other_actions_are_unsupported():
    v = Vehicle()
    v.run(0.1)
    assert v.ack(REBOOT, 0) == M.MAV_RESULT_ACCEPTED
    assert v.ack(REBOOT, 2) == M.MAV_RESULT_UNSUPPORTED
    v.run(2.5)
    assert not v.engine.reboots.records


def test_an_accepted_reboot_goes_silent_then_comes_back_as_a_fresh_autopilot():
    v = Vehicle("--reboot-time-s", "1.5")
    v.run(1.0)
    # a requested interval (as mavreg asks of ArduCopter) is forgotten by the reboot
    assert v.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 10_000) == M.MAV_RESULT_ACCEPTED
    old_ap = v.engine.ap
    old_ap.px4.takeoff_height_m = 4.0                  # a parameter: kept, as PX4 stores them
    t_cmd = v.engine.sim.t_s
    out = v.command(REBOOT, 1)
    assert [m.result for m in out if m.get_type() == "COMMAND_ACK"] == [M.MAV_RESULT_ACCEPTED]
    before = v.run(0.4)                                # PX4 goes down 0.4 s after its ACK
    assert _times(before)[-1] >= round(1000 * (t_cmd + 0.39))
    silent = v.run(1.0)
    assert silent == [] and v.engine.reboots.down
    dropped = v.engine.counters["dropped_rebooting"]
    v.command(ARM, 1)                                  # nobody listens
    assert v.engine.counters["dropped_rebooting"] == dropped + 1
    after = v.run(1.0)
    rec = v.engine.reboots.records[0]
    assert rec.up_t_s - rec.down_t_s == 1.5 and rec.on_ground and not rec.armed
    assert after[0].get_type() == "HEARTBEAT"          # it announces itself first
    times = _times(after)
    assert times[0] == 0 and np.all(np.diff(times) == 2)
    ap = v.engine.ap
    assert ap is not old_ap and not ap.armed and ap.mode == modes.HOLD
    assert ap.px4.takeoff_height_m == 4.0
    assert ap.px4.rate_hz_of(M.MAVLINK_MSG_ID_LOCAL_POSITION_NED) == 500.0   # the default again
    assert v.ack(ARM, 1) == M.MAV_RESULT_ACCEPTED      # and it flies again
    ts = [m for m in v.send(M.MAVLink_timesync_message(0, 123)) if m.get_type() == "TIMESYNC"]
    assert abs(ts[0].tc1 * 1e-9 - (v.engine.sim.t_s - rec.up_t_s)) < 1e-6   # its clock, from the boot


def test_an_injected_reboot_in_the_air_stops_the_motors_and_the_fall_is_no_crash_exit(tmp_path):
    v = Vehicle("--start", "z_m=-3", "--reboot-at-s", "0.2", "--reboot-time-s", "1.5")
    v.run(0.2)
    assert v.engine.ap.armed
    v.run(0.02)
    rec = v.engine.reboots.records[0]
    assert rec.armed and not rec.on_ground and rec.down_t_s == 0.2
    v.run(1.0)                                         # free fall from 3 m: 0.78 s
    impacts = v.engine.sim.ground.impacts
    assert len(impacts) == 1 and impacts[0]["speed_m_s"] > 7.0      # far over the 3 m/s crash speed
    assert v.engine.sim.on_ground
    after = v.run(1.0)
    assert _times(after)[0] == 0 and not v.engine.ap.armed
    meta = v.engine.run_meta()
    json.dumps(meta)                                   # the recording's meta_json takes it
    assert meta["reboots"][0]["armed"] and meta["reboot_impacts"] == impacts


def test_in_lockstep_a_client_sees_the_clock_go_back_and_must_say_hello_again(tmp_path):
    rec_path = tmp_path / "rec.npz"
    with Emulator("--lockstep", "--world", "ideal", "--reboot-time-s", "1.0", record=rec_path) as emu:
        c = Client(emu.port)
        c.heartbeat()
        c.lockstep(50, [0.0] * 4)
        c.command(REBOOT, 1)
        assert c.ack(REBOOT, on_msg=lambda m: None) == M.MAV_RESULT_ACCEPTED
        last = None
        while True:                                    # answer until it goes down (0.4 s later)
            m = c.recv(0.5)
            if m is None:
                break
            if m.get_type() == "LOCAL_POSITION_NED":
                last = m.time_boot_ms
                c.target([0.0] * 4)
        assert last is not None and last >= 490       # 0.4 s after the command at 0.1 s
        c.heartbeat()                                  # it forgot us: heard again, it sends again
        first = c.wait_for("LOCAL_POSITION_NED", timeout_s=10.0)
        assert first.time_boot_ms < last                # the clock went back: a new boot
        c.close()
    meta = json.loads(str(np.load(rec_path)["meta_json"]))
    r = meta["reboots"][0]
    assert abs(r["up_t_s"] - r["down_t_s"] - 1.0) < 1e-9 and r["why"].startswith("by command")
    modes_rec = np.load(rec_path)["custom_mode"]
    assert np.any(modes_rec == 0)                      # recorded as mode 0 while down
