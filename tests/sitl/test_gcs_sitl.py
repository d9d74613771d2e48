"""End-to-end: MAVProxy attached through ``mavreg fly --gcs`` watches a lockstep flight live.

MAVProxy listens (``--master udpin:``) as it does for a vehicle; the daemon sends to it
(``--gcs udpout:``). What MAVProxy prints is what a pilot at its console sees (with
``--target-component 0`` it prints the STATUSTEXTs of every component of system 1, the
daemon's included); its ``--out`` re-forwards everything it received to a pymavlink
listener here, which checks the telemetry MAVProxy does not print.
"""
from __future__ import annotations

import json
import socket
import sys
import threading
import time

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from tests.helpers.sitl import REPO, Proc, free_udp_port, mavreg
from tests.helpers.waiting import wait_until

pytestmark = pytest.mark.sitl

try:
    import MAVProxy  # noqa: F401
except ImportError:
    pytest.skip("MAVProxy is not installed: pip install -e '.[gcs]' (the ground-station extra)",
                allow_module_level=True)

HOP = REPO / "tests/sitl/gcs_hop.yaml"
LOCKSTEP = ("--lockstep", "--world", "ideal", "--timeout-s", "120", "--stale-timeout-s", "30")
"""A lockstep flight: the emulator waits for each command, so a busy machine (MAVProxy is one
more Python process on it) pauses the flight instead of losing its link."""
OFFBOARD = 6 << 16


class _Listener:
    """Everything MAVProxy's --out sends, parsed, collected by a thread."""

    def __init__(self):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.msgs: list = []
        self._stop = threading.Event()
        self._parser = mavlink2.MAVLink(None)
        self._parser.robust_parsing = True
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self):
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65535)
            except socket.timeout:
                continue
            self.msgs.extend(m for m in self._parser.parse_buffer(data) or [] if m.get_type() != "BAD_DATA")

    def close(self):
        self._stop.set()
        self._t.join(5)
        self.sock.close()


@pytest.mark.slow          # 15 s: MAVProxy end to end; before each release (the forwarding and its policy: tests/unit/test_gcs*.py)
def test_mavproxy_sees_the_vehicle_its_modes_and_the_daemons_messages(tmp_path):
    t0 = time.monotonic()
    listener = _Listener()
    port = free_udp_port()
    mp = Proc([sys.executable, "-u", "-m", "MAVProxy.mavproxy", "--master", f"udpin:127.0.0.1:{port}",
               "--out", f"udp:127.0.0.1:{listener.port}", "--target-system", "1", "--target-component", "0",
               "--daemon", "--non-interactive", "--no-state"],
              cwd=tmp_path)
    try:
        mp.wait_line("Waiting for heartbeat", 60)
        t1 = time.monotonic()
        fly = mavreg("fly", str(HOP), *LOCKSTEP, "--out", str(tmp_path / "out"),
                     "--gcs", f"udpout:127.0.0.1:{port}")
        code = fly.wait(180)
        t2 = time.monotonic()
        # what is in flight to MAVProxy and back out: the daemon's last phase, re-forwarded
        wait_until(lambda: any(m.get_type() == "NAMED_VALUE_INT" and m.name == "mr_phase" and m.value == 6
                               for m in list(listener.msgs)) and any("DISARMED" in ln for ln in mp.lines),
                   "the disarmed phase through MAVProxy", 60, 0.1)
    finally:
        mp.stop()
        listener.close()
    print(f"\nMAVProxy ready after {t1 - t0:.1f} s, flight {t2 - t1:.1f} s, stopped after {time.monotonic() - t2:.1f} s")
    assert code == 0, "\n".join(fly.lines[-30:])
    seen = mp.lines
    print("\nMAVProxy printed:\n  " + "\n  ".join(ln for ln in seen if not ln.startswith("Unloading")))
    # MAVProxy attached: the vehicle (1:1) and the daemon's own component (1:191)
    for needle in ("Detected vehicle 1:1 ", "Detected vehicle 1:191 ", "ARMED", "DISARMED"):
        assert any(needle in ln for ln in seen), needle
    modes = [ln.split("Mode ", 1)[1] for ln in seen if "> Mode " in ln or ln.startswith("Mode ")]
    assert len(set(modes)) >= 2, modes                       # its mode changes, announced
    assert any(m in ("OFFBOARD", "Mode(393216)") for m in modes), modes
    assert any(ln.startswith("AP: mode OFFBOARD") for ln in seen)      # the vehicle's STATUSTEXTs
    for phase in ("takeoff", "maneuver", "land", "disarmed"):           # the daemon's, reassembled
        assert any(f"AP: mavreg phase {phase}: " in ln for ln in seen), phase
    # behind MAVProxy: the vehicle's telemetry and the daemon's messages, with their ids
    got = listener.msgs
    kinds = {(m.get_type(), m.get_srcSystem(), m.get_srcComponent()) for m in got}
    print("re-forwarded by MAVProxy: " + ", ".join(f"{t} {s}:{c}" for t, s, c in sorted(kinds)))
    assert ("HEARTBEAT", 1, 1) in kinds and ("HEARTBEAT", 1, 191) in kinds
    assert any(m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1 and m.custom_mode == OFFBOARD
               for m in got)
    north = [m.x for m in got if m.get_type() == "LOCAL_POSITION_NED"]
    assert north and max(north) > 4.0                        # the hop, seen live
    phases = [m.value for m in got if m.get_type() == "NAMED_VALUE_INT" and m.name == "mr_phase"]
    assert 0 in phases and 6 in phases, phases                # preflight ... disarmed
    # read-only: what MAVProxy sent (heartbeats, parameter and stream requests) was dropped
    gcs = json.loads((tmp_path / "out/summary.json").read_text())["status"]["gcs"][0]
    print(f"ground-station counters: {gcs}")
    assert gcs["from_gcs"] > 0 and gcs["to_vehicle"] == 0
    assert gcs["dropped_never"] + gcs["dropped_read_only"] == gcs["from_gcs"]
    assert gcs["dropped_queue"] == 0 and gcs["send_errors"] == 0


class _HostileGcs(_Listener):
    """A ground station (pymavlink) that, once the maneuver begins, asks for everything that
    would fight the daemon, one harmless query, and a landing."""

    def __init__(self):
        self.sent = False
        self.replies: list = []
        super().__init__()

    def _run(self):
        gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
        cmd = mavlink2.MAVLink_command_long_message
        while not self._stop.is_set():
            try:
                data, addr = self.sock.recvfrom(65535)
            except socket.timeout:
                continue
            msgs = [m for m in self._parser.parse_buffer(data) or [] if m.get_type() != "BAD_DATA"]
            self.msgs.extend(msgs)
            if self.sent:
                continue
            if any(m.get_type() == "STATUSTEXT" and m.text.startswith("mavreg phase maneuver") for m in msgs):
                self.sent = True
                batch = [cmd(1, 1, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 21196, 0, 0, 0, 0, 0),
                         cmd(1, 1, mavlink2.MAV_CMD_DO_SET_MODE, 0, 1, 4, 3, 0, 0, 0, 0),
                         mavlink2.MAVLink_set_actuator_control_target_message(0, 0, 1, 1, [0.0] * 8),
                         mavlink2.MAVLink_manual_control_message(1, 0, 0, 0, 0, 0),
                         cmd(1, 1, mavlink2.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0),
                         cmd(1, 1, mavlink2.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)]
                self.sock.sendto(b"".join(m.pack(gcs) for m in batch), addr)


@pytest.mark.slow
def test_allowed_commands_cannot_fight_the_daemon_in_flight(tmp_path):
    """With --gcs-allow-commands, a forced disarm, a mode change, zero rotor set-points and
    manual control sent mid-maneuver are refused; the query passes, the landing request
    becomes the daemon's; the flight ends as it would have."""
    gcs = _HostileGcs()
    try:
        fly = mavreg("fly", str(HOP), *LOCKSTEP, "--out", str(tmp_path / "out"),
                     "--gcs", f"udpout:127.0.0.1:{gcs.port}", "--gcs-allow-commands")
        code = fly.wait(180)
    finally:
        gcs.close()
    assert gcs.sent
    assert code == 0, "\n".join(fly.lines[-30:])
    summary = json.loads((tmp_path / "out/summary.json").read_text())
    st = summary["status"]["gcs"][0]
    print(f"\nground-station counters: {st}")
    assert (st["refused"], st["to_vehicle"], st["land_requests"]) == (4, 1, 1)
    assert any(e["kind"] == "land_requested" for e in summary["events"])
    denied = {m.command for m in gcs.msgs if m.get_type() == "COMMAND_ACK" and m.get_srcComponent() == 191
              and m.result == mavlink2.MAV_RESULT_DENIED}
    assert denied == {mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, mavlink2.MAV_CMD_DO_SET_MODE}
    texts = [m.text for m in gcs.msgs if m.get_type() == "STATUSTEXT" and m.get_srcComponent() == 191]
    assert "mavreg gcs: land requested; the daemon lands" in texts
    # the vehicle never saw the refused ones: it stayed armed in OFFBOARD until the daemon landed
    vehicle_texts = [m.text for m in gcs.msgs if m.get_type() == "STATUSTEXT" and m.get_srcComponent() == 1]
    assert not any("disarm" in t and "force" in t for t in vehicle_texts)
    modes = [m.custom_mode for m in gcs.msgs if m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1
             and m.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED]
    assert modes and set(modes[modes.index(OFFBOARD):]) == {OFFBOARD}
