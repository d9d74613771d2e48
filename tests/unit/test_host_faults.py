"""The host misbehaves (issue 32, item 3): a full disk and a stepped wall clock.

Each file writer meets a write error (a file that fails after N bytes, ``/dev/full``, a
directory where the file should go), stops writing that file, says so once in one line, and
never raises into the code that flies; a wall clock stepped by ±1 h steps no ``.tlog`` stamp
and no signing timestamp back. The flights themselves: ``tests/sitl/test_host_faults_sitl.py``.
"""
from __future__ import annotations

import asyncio
import errno
import json
import os
import socket
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.logs import tlog as tlog_mod
from mavreg.daemon.jobs.ctrllog import ControlLog, decoded, load_control_log
from mavreg.daemon.vehicle.link import open_link
from mavreg.daemon.logs.outputs import stopped_line, write_or_say
from mavreg.daemon.logs.tlog import SteadyWallClock, TlogWriter, VehicleClock, tlog_clock
from mavreg.transport import signing as sg
from mavreg.transport.wire import Wire

MAV = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
FULL = Path("/dev/full")
needs_dev_full = pytest.mark.skipif(not FULL.exists(), reason="no /dev/full on this system")


def _frame(k: int) -> bytes:
    return mavlink2.MAVLink_local_position_ned_message(k, 1.0, 2.0, -3.0, 0, 0, 0).pack(MAV)


class FillingFile:
    """A binary file that takes ``room`` bytes, then fails every write with ``code``; what it
    took is in :attr:`data`."""

    def __init__(self, room: int, code: int = errno.ENOSPC):
        self.room, self.code, self.data, self.closed = room, code, bytearray(), False

    def write(self, b) -> int:
        if len(self.data) + len(b) > self.room:
            raise OSError(self.code, os.strerror(self.code))
        self.data += b
        return len(b)

    def close(self) -> None:
        self.closed = True


def _writer_on(monkeypatch, fake, lines: list) -> TlogWriter:
    monkeypatch.setattr(tlog_mod, "open", lambda *a, **k: fake, raising=False)
    return TlogWriter("/x/flight.tlog", clock_s=lambda: 1.7e9, log=lines.append)


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EIO, errno.EDQUOT])
def test_tlog_stops_at_the_first_write_error_says_it_once_and_never_raises(monkeypatch, code):
    lines: list[str] = []
    fake = FillingFile(room=5 * (8 + len(_frame(0))), code=code)
    w = _writer_on(monkeypatch, fake, lines)
    for k in range(100):
        w.write(_frame(k)) if k % 2 else w.write_many([_frame(k), _frame(k)])
    w.close()
    assert len(lines) == 1, lines
    assert lines[0] == (f"tlog: stopped writing /x/flight.tlog: [Errno {code} {errno.errorcode[code]}] "
                        f"{os.strerror(code)}; the flight goes on")
    # what was written before the error stays whole: five records, then nothing
    assert len(fake.data) == 5 * (8 + len(_frame(0))) or len(fake.data) < 5 * (8 + len(_frame(0)))
    assert w.count * (8 + len(_frame(0))) == len(fake.data)
    assert w.count + w.dropped == 150
    assert w.status()["stopped"] == lines[0] and fake.closed


@needs_dev_full
def test_tlog_on_dev_full_never_raises_and_says_it_once():
    lines: list[str] = []
    w = TlogWriter(FULL, log=lines.append)
    for k in range(20_000):            # about 1 MB: many times the writer's 64 KiB buffer
        w.write(_frame(k))
    w.close()
    assert lines == ["tlog: stopped writing /dev/full: [Errno 28 ENOSPC] No space left on device; "
                     "the flight goes on"]
    assert w.dropped > 0 and w.count + w.dropped == 20_000


def test_tlog_that_cannot_be_created_drops_its_frames_and_says_it_once(tmp_path):
    lines: list[str] = []
    (tmp_path / "d").mkdir()
    w = TlogWriter(tmp_path / "d", log=lines.append)        # a directory: IsADirectoryError
    w.write(_frame(1))
    w.write_many([_frame(2)])
    w.close()
    assert len(lines) == 1 and lines[0].startswith(f"tlog: stopped writing {tmp_path / 'd'}: [Errno 21 EISDIR]")
    assert (w.count, w.dropped) == (0, 2)


@needs_dev_full
def test_a_link_whose_tlog_is_on_dev_full_still_delivers_every_message():
    """The tlog is written inside the link's datagram handler: its error must not close the link."""
    async def main():
        got, lines = [], []
        tlog = TlogWriter(FULL, log=lines.append)
        link = await open_link("udpin:127.0.0.1:0", 1, 1, lambda m, t: got.append(m), tlog)
        port = link.sock.getsockname()[1] if hasattr(link, "sock") else \
            link.transport.get_extra_info("socket").getsockname()[1]
        vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        hb = mavlink2.MAVLink_heartbeat_message(2, 12, 129, 0, 4, 3).pack(MAV)
        try:
            n = 3000                    # 3000 x 62 bytes in: the 64 KiB buffer fills more than once
            for k in range(n):
                vehicle.sendto(hb if k == 0 else _frame(k), ("127.0.0.1", port))
                if k % 100 == 0:
                    await _until(lambda: len(got) == k + 1)
            await _until(lambda: len(got) == n)
            assert link.send_many([mavlink2.MAVLink_timesync_message(0, 1)])
        finally:
            link.close()
            tlog.close()
            vehicle.close()
        return got, lines, tlog
    got, lines, tlog = asyncio.run(main())
    assert len(got) == 3000 and len(lines) == 1 and "ENOSPC" in lines[0]
    assert tlog.dropped > 0


async def _until(condition, timeout_s: float = 10.0) -> None:
    """Run the loop until ``condition()`` (a bound on a broken link, not a wait relied on)."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not condition():
        assert loop.time() < deadline, f"not within {timeout_s} s"
        await asyncio.sleep(0.001)


def test_signing_state_that_cannot_be_rewritten_mid_flight_is_said_once(tmp_path):
    key = tmp_path / "key"
    key.write_text(bytes(range(1, 33)).hex())
    key.chmod(0o600)
    lines: list[str] = []
    s = sg.Signing(key, "mavreg", log=lines.append)          # the first save works
    (tmp_path / "key.mavreg-state.json.tmp").mkdir()          # now every save fails (EISDIR)
    frames = [s.sign(Wire(1, 191).pack(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3)))
              for _ in range(3)]
    s.save()
    s.save()
    assert s.save_errors == 2 and len(lines) == 1
    assert lines[0].startswith(f"signing: cannot write {s.path}: [Errno 21 EISDIR]")
    assert "the flight goes on" in lines[0]
    ts = [int.from_bytes(f[-12:-6], "little") for f in frames]
    assert ts == sorted(set(ts))                              # signing itself goes on


def test_write_or_say_removes_a_partial_file_and_says_once(tmp_path):
    lines: list[str] = []
    target = tmp_path / "summary.json"

    def partial():
        target.write_text("{\"result\": ")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert not write_or_say("summary", target, partial, lines.append, "printed instead")
    assert not target.exists()
    assert lines == [f"summary: stopped writing {target}: [Errno 28 ENOSPC] No space left on device; "
                     "printed instead"]
    assert write_or_say("summary", target, lambda: target.write_text("{}"), lines.append, "x")
    assert len(lines) == 1 and json.loads(target.read_text()) == {}


@needs_dev_full
def test_control_log_to_dev_full_raises_oserror_and_stays_usable_in_memory(tmp_path):
    from mavreg.daemon.flight.phases import LogRecord
    log = ControlLog()
    for k in range(50):
        log.append(LogRecord(0.002 * k, "hold", float("nan"), np.zeros(11), np.zeros(4), np.zeros(4),
                             np.zeros(12), np.zeros(6)))
    arrays = log.arrays()
    lines: list[str] = []
    full = tmp_path / "control.npz"
    full.symlink_to(FULL)           # (numpy adds ".npz" to a name without it)
    assert not write_or_say("control log", full, lambda: log.save(full, arrays), lines.append, "x")
    assert len(lines) == 1 and "ENOSPC" in lines[0]
    mem = decoded(arrays)
    log.save(tmp_path / "c.npz", arrays)
    disk = load_control_log(tmp_path / "c.npz")
    assert mem["phase_names"] == disk["phase_names"] and mem["events"] == disk["events"]
    assert all(np.array_equal(mem[k], disk[k], equal_nan=True) for k in ("t_s", "x", "s_m", "phase"))


def test_stopped_line_without_an_errno():
    assert stopped_line("plot", "/x/p.png", OSError("disk gone"), "goes on") == \
        "plot: stopped writing /x/p.png: disk gone; goes on"


# ----------------------------------------------------------------------- the wall clock
def test_a_wall_clock_step_of_an_hour_steps_no_tlog_stamp():
    wall, mono = [1.7e9], [100.0]
    clock = SteadyWallClock(lambda: wall[0], lambda: mono[0])
    stamps = []
    for step in (+3600.0, -7200.0):
        for _ in range(10):
            mono[0] += 0.002
            wall[0] += 0.002
            stamps.append(clock())
        wall[0] += step                               # the host's clock jumps; real time does not
    d = np.diff(stamps)
    assert np.allclose(d, 0.002, rtol=0, atol=1e-6) and stamps[0] == pytest.approx(1.7e9 + 0.002)


def test_the_tlog_clock_reads_the_wall_clock_once_whichever_it_is():
    reads = []

    def wall():
        reads.append(1)
        return 1.7e9 + 3600.0 * len(reads)           # every read an hour later than the last
    vehicle = [None]
    v = tlog_clock("vehicle", lambda: vehicle[0], wall)
    assert isinstance(v, VehicleClock)
    vehicle[0] = 5.0
    v()
    vehicle[0] = 6.0
    assert v() == pytest.approx(1.7e9 + 3600.0 + 1.0)
    w = tlog_clock("wall", lambda: None, wall)
    a, b = w(), w()
    assert 0.0 <= b - a < 60.0 and len(reads) == 2     # one read each


def test_signing_timestamps_never_go_back_when_the_clock_steps(tmp_path):
    key = tmp_path / "key"
    key.write_text(bytes(range(1, 33)).hex())
    key.chmod(0o600)
    wall = [1.7e9]
    s = sg.Signing(key, "mavreg", wall_s=lambda: wall[0])
    pack = Wire(1, 191).pack
    ts = []
    for step in (0.0, +3600.0, -7200.0, +3600.0):
        wall[0] += step
        for _ in range(5):
            wall[0] += 0.001
            f = s.sign(pack(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3)))
            ts.append(int.from_bytes(f[-12:-6], "little"))
    assert all(b > a for a, b in zip(ts, ts[1:])), ts
    # a verifier that took the frames before the step back takes those after it too
    v = sg.Verifier(bytes(range(1, 33)), ts[0] - 1)
    frames = [s.sign(pack(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))) for _ in range(3)]
    wall[0] -= 3600.0
    frames += [s.sign(pack(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))) for _ in range(3)]
    assert [v.check(f) for f in frames] == [None] * 6
