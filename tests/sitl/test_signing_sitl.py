"""Signing end to end: ``mavreg fly --lockstep --signing-key`` (daemon and bundled emulator share
the key) while an attacker in this process floods the vehicle's port with unsigned, forged
(future-timestamped) and MAVLink 1 disarm and rotor commands and address-stealing heartbeats.
The flight must be flown and landed as if nobody had tried, and the emulator must have
counted the attempts (its recording's ``meta_json.drops``)."""
from __future__ import annotations

import json
import os
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from tests.helpers.sitl import CONTROLLER, mavreg

pytestmark = pytest.mark.sitl

HOP = Path(__file__).resolve().parent / "signing_hop.yaml"


def _attack(fly, stop: threading.Event, sent: list) -> None:
    port = int(fly.wait_line("link: udpout:", 120).rsplit(":", 1)[1])
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)      # the daemon's own ids
    disarm = mavlink2.MAVLink_command_long_message(1, 1, 400, 0, 0, 21196, 0, 0, 0, 0, 0)
    rotors = mavlink2.MAVLink_set_actuator_control_target_message(0, 0, 1, 1, [1, 0, 1, 0, 0, 0, 0, 0])
    hb = mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3)
    future = (2**47).to_bytes(6, "little")

    def forge(frame: bytes) -> bytes:          # looks signed; the signature is random
        body = bytearray(frame)
        body[2] |= 1
        crc = mavlink2.x25crc(body[1:-2])
        crc.accumulate(bytes([mavlink2.mavlink_map[frame[7]].crc_extra]))
        body[-2:] = crc.crc.to_bytes(2, "little")
        return bytes(body) + b"\x00" + future + os.urandom(6)

    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        while not stop.is_set() and fly.p.poll() is None:
            frames = [m.pack(mav) for m in (disarm, rotors, hb)]
            frames += [forge(f) for f in frames] + [disarm.pack(mav, force_mavlink1=True)]
            for f in frames:
                s.sendto(f, ("127.0.0.1", port))
            sent[0] += len(frames)
            time.sleep(0.05)
    finally:
        s.close()


def _fly_under_attack(tmp_path, *fly_args):
    """``mavreg fly`` of the hop with the attacker running; (exit code, fly process, frames sent)."""
    fly = mavreg("fly", str(HOP), "--lockstep", "--world", "ideal", "--controller", str(CONTROLLER),
                 "--out", str(tmp_path / "out"), "--timeout-s", "120", *fly_args)
    stop, sent = threading.Event(), [0]
    t = threading.Thread(target=_attack, args=(fly, stop, sent), daemon=True)
    t.start()
    try:
        code = fly.wait(180)
    finally:
        stop.set()
        t.join(10)
        fly.stop()
    return code, fly, sent[0]


@pytest.mark.slow          # 14 s; before each release (signing, forged and replayed frames: tests/unit/test_signing.py, tests/firmware_sim/test_fsim_signing.py)
def test_signed_flight_ignores_unsigned_and_forged_commands(tmp_path):
    key = tmp_path / "key"
    key.write_text(os.urandom(32).hex())
    key.chmod(0o600)
    out = tmp_path / "out"
    code, fly, n_sent = _fly_under_attack(tmp_path, "--signing-key", str(key))
    sent = [n_sent]
    summary = json.loads((out / "summary.json").read_text())
    with np.load(out / "groundtruth.npz") as z:
        meta = json.loads(str(z["meta_json"]))
    drops = meta["drops"]
    print(f"\nattack frames sent: {sent[0]}; emulator drops: "
          f"{ {k: v for k, v in drops.items() if v} }; daemon: {summary['status']['signing']}")
    assert code == 0 and summary["result"] == "ok", "\n".join(fly.lines[-30:])
    assert sent[0] > 300
    assert drops["unsigned"] > 0 and drops["bad_signature"] > 0
    # each burst the emulator read (it stops before the attacker does) was dropped whole: four
    # unsigned frames (three MAVLink 2, one MAVLink 1) and three forged; nothing got further
    assert abs(3 * drops["unsigned"] - 4 * drops["bad_signature"]) <= 12
    assert drops["unsigned"] + drops["bad_signature"] <= sent[0]
    for reason in ("replayed", "foreign_system", "foreign_component", "foreign_address", "wrong_target"):
        assert drops[reason] == 0, reason
    assert summary["status"]["signing"]["accepted"] > 1000
    assert _key_not_in(out, key)


@pytest.mark.slow          # about 30 s; the negative control of the test above, before releases
def test_without_signing_the_same_attack_takes_the_vehicle(tmp_path):
    """The attacker's unsigned HEARTBEAT under the daemon's ids moves the vehicle's peer (and its
    telemetry) to the attacker, whose commands it would now obey: the daemon never gets a
    sample and the flight fails. Signing is what stops it."""
    code, fly, n_sent = _fly_under_attack(tmp_path, "--timeout-s", "20")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    print(f"\nunsigned flight under attack: exit {code}, {summary['reason']!r}")
    assert n_sent > 0 and code == 1 and summary["result"] == "failed"


def _key_not_in(out: Path, key: Path) -> bool:
    """Neither the key nor its bytes are in any output file."""
    text = key.read_text().strip()
    raw = bytes.fromhex(text)
    return all(text.encode() not in p.read_bytes() and raw not in p.read_bytes()
               for p in out.iterdir() if p.is_file())
