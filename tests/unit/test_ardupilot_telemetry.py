"""Real ArduCopter telemetry through the daemon's receive path: wire parser, dialect, assembler.

``tests/data/ardupilot_hover_100hz.tlog`` is 2 s of a stock ArduCopter SITL (4.7.0-dev,
freestyle frame) hovering 3 m up in GUIDED, flown by body rates and thrust, with
ATTITUDE_QUATERNION and LOCAL_POSITION_NED asked for at 100 Hz (written by
``scripts/ardupilot/measure_flight.py --tlog``). Its frames are MAVLink 2 with ArduPilot's
own trailing-zero truncation. The test proves that mavreg's fast parser decodes them as
pymavlink does, that the dialect reads the heartbeat, and that :class:`StateAssembler`
(pairing by equal ``time_boot_ms``) yields one state per telemetry period: ArduCopter sends
both parts of a period with the same ``time_boot_ms`` (``docs/autopilots.md``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mavreg.daemon.vehicle.autopilots import ARDUCOPTER, dialect_for
from mavreg.daemon.vehicle.messages import mavlink2 as M
from mavreg.daemon.flight.state import StateAssembler
from mavreg.transport.wire import FAST_IDS, Wire

TLOG = Path(__file__).resolve().parents[1] / "data" / "ardupilot_hover_100hz.tlog"


def frames() -> list[bytes]:
    """The .tlog's MAVLink 2 frames (each after its 8-byte time stamp)."""
    raw, out, i = TLOG.read_bytes(), [], 0
    while i < len(raw):
        i += 8
        assert raw[i] == 0xFD, "MAVLink 2 frames only"
        n = 12 + raw[i + 1] + (13 if raw[i + 2] & 1 else 0)
        out.append(raw[i:i + n])
        i += n
    return out


def decoded() -> list:
    wire = Wire(255, 190)
    msgs = [m for f in frames() for m in wire.parse(f)]
    assert wire.slow_in == sum(m.get_msgId() not in FAST_IDS for m in msgs)   # the hot ones: fast path
    return msgs


def test_fast_parser_matches_pymavlink_on_arducopter_frames():
    ref = M.MAVLink(None)
    fs = frames()
    truncated = 0
    for f, m in zip(fs, decoded()):
        r = ref.parse_buffer(f)[0]
        assert m.to_dict() == r.to_dict()
        spec_len = r.__class__.unpacker.size
        truncated += f[1] < spec_len
    assert truncated > 0                   # ArduPilot drops trailing zeros: that path is covered
    assert len(fs) > 400


def test_heartbeat_says_guided_armed_arducopter():
    hbs = [m for m in decoded() if m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1]
    assert hbs
    dialect = dialect_for(hbs[0])
    assert dialect is ARDUCOPTER
    info = dialect.decode(hbs[-1])
    assert (info.armed, info.mode, info.offboard) == (True, "GUIDED", True)


def test_every_period_gives_one_state():
    msgs = decoded()
    att = [m.time_boot_ms for m in msgs if m.get_type() == "ATTITUDE_QUATERNION"]
    pos = [m.time_boot_ms for m in msgs if m.get_type() == "LOCAL_POSITION_NED"]
    assert set(pos) <= set(att) and len(set(att) - set(pos)) <= 1      # one pair may be cut at an end
    assert np.median(np.diff(att)) == 10                                # 100 Hz granted
    asm = StateAssembler()
    samples = [s for m in msgs if (s := asm.add(m)) is not None]
    assert len(samples) == len(pos)
    assert asm.counters.late == 0 and asm.counters.non_finite == 0
    x = np.array([s.x for s in samples])
    assert np.all(np.abs(-x[:, 2] - 3.0) < 0.1)                        # hovering 3 m up
    assert np.all(np.abs(x[:, 3:5]) < np.radians(3.0))                  # level
    assert np.all(np.abs(x[:, 8]) < 0.1)                                # holding altitude (it drifts sideways)
    v_ned = np.array([s.velocity_ned for s in samples])
    assert np.allclose(np.linalg.norm(x[:, 6:9], axis=1), np.linalg.norm(v_ned, axis=1), atol=1e-9)
