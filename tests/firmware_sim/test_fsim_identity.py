"""Who the emulator is on the link: its system id, the autopilot its HEARTBEAT announces, and a
remote it sends to before hearing from it (as PX4 SITL does to an offboard computer's port)."""
from __future__ import annotations

import socket
import subprocess
import sys

from pymavlink.dialects.v20 import common as mavlink2

from tests.helpers.emulator import ARM, Emulator


def _recv(sock, mav, mtype, timeout_s=5.0, pred=lambda m: True):
    sock.settimeout(timeout_s)
    while True:
        data, addr = sock.recvfrom(65535)
        for m in mav.parse_buffer(data) or []:
            if m.get_type() == mtype and pred(m):
                return m, addr


def test_a_generic_vehicle_with_id_6_sends_to_its_remote_first_and_takes_only_id_6():
    offboard = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)      # mavreg fly --vehicle udpin:...
    offboard.bind(("127.0.0.1", 0))
    port = offboard.getsockname()[1]
    mav = mavlink2.MAVLink(None)
    with Emulator("--world", "ideal", "--autopilot", "generic", "--vehicle-system-id", "6",
                  "--remote", f"udpout:127.0.0.1:{port}"):
        hb, addr = _recv(offboard, mav, "HEARTBEAT")                  # nothing was sent to it
        assert hb.autopilot == mavlink2.MAV_AUTOPILOT_GENERIC and hb.type == mavlink2.MAV_TYPE_QUADROTOR
        assert (hb.get_srcSystem(), hb.get_srcComponent()) == (6, 1)
        _recv(offboard, mav, "LOCAL_POSITION_NED")                    # telemetry too
        for sysid in (1, 6):                                           # system 1 is another system
            me = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=191)
            offboard.sendto(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3).pack(me), addr)
            offboard.sendto(mavlink2.MAVLink_command_long_message(6, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(me), addr)
        ack, _ = _recv(offboard, mav, "COMMAND_ACK", pred=lambda m: m.command == ARM)
        assert ack.result == mavlink2.MAV_RESULT_ACCEPTED and ack.target_system == 6
        armed, _ = _recv(offboard, mav, "HEARTBEAT", pred=lambda m: m.base_mode & 128)
        assert armed.custom_mode != 0                                  # PX4's mode layout all the same
    offboard.close()


def test_identity_flags_are_checked_in_one_line():
    for args, words in ((["--autopilot", "ardupilot"], "invalid choice: 'ardupilot'"),
                        (["--vehicle-system-id", "0"], "expected an integer > 0"),
                        (["--vehicle-system-id", "256"], "1..255"),
                        (["--remote", "udpin:127.0.0.1:1"], "expected udpout:HOST:PORT"),
                        (["--remote", "udpout:127.0.0.1:0"], "port must be in 1..65535"),
                        (["--remote", "udpout:no.such.host.invalid:14540"], "--remote no.such.host.invalid")):
        r = subprocess.run([sys.executable, "-m", "firmware_sim", "--listen", "udpin:127.0.0.1:0", *args],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and words in r.stderr, (args, r.stderr)
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
