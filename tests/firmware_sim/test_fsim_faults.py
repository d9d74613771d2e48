"""firmware_sim's link-fault shim (firmware_sim/faults.py): what the lockstep loop waits for
(usable samples only), commands due in step order, corrupted frames that fail their CRC."""
from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

from firmware_sim.autopilot import state_messages
from firmware_sim.channel import Downlink, Uplink
from firmware_sim.faults import FaultyDownlink, FaultyUplink, link_faults_from_args
from firmware_sim.link import Link
from firmware_sim.world import LinkParams
from mavreg.tools.faultlink import FaultParams, parse_faults

RATE, SUB = 500, 2


def _bundle(k: int):
    return state_messages(k / RATE, (0.0, 0.0, -1.0), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


def _run_down(params: FaultParams, n: int = 3000):
    down = FaultyDownlink(Downlink(LinkParams(), RATE, SUB, 0), params, RATE)
    usable, times, intact = 0, [], 0
    for k in range(n + 20):
        if k < n:
            down.push_period(k, [], _bundle(k))
        msgs, u = down.release(k)
        usable += u
        kinds = [m.get_type() for m in msgs]     # one item a period here (no reordering in the loss test)
        times += [m.time_boot_ms for m in msgs if m.get_type() == "LOCAL_POSITION_NED"]
        intact += min(kinds.count("ATTITUDE_QUATERNION"), kinds.count("LOCAL_POSITION_NED"))
    down.intact = intact
    return down, usable, times


def test_clean_shim_counts_every_sample():
    _, usable, times = _run_down(FaultParams())
    assert usable == 3000 and times == [2 * k for k in range(3000)]


def test_duplicates_and_overtaken_samples_are_not_waited_for():
    down, usable, times = _run_down(FaultParams(duplicate=0.1, reorder=0.1, reorder_s=0.01, seed=3))
    c = down.line.counters
    assert c.duplicated > 200 and c.reordered > 200
    newer = 0
    newest = -1
    for t in times:                   # what the daemon can use: each time newer than all before
        if t > newest:
            newer, newest = newer + 1, t
    assert usable == newer < len(times)


def test_lost_and_corrupted_samples_are_not_waited_for():
    down, usable, times = _run_down(FaultParams(loss=0.2, corrupt=0.2, seed=4))
    c = down.line.counters
    assert c.lost > 400 and c.corrupted > 300
    assert usable == down.intact                     # a damaged quaternion or position is not waited for
    # a damaged ATTITUDE (a third of the hits) leaves its sample usable
    assert 3000 - c.lost - c.corrupted < usable < 3000 - c.lost
    assert down.lost >= c.lost


def test_uplink_due_in_order_and_at_its_physics_step():
    up = FaultyUplink(Uplink(LinkParams(), 1000, 0), FaultParams(delay_s=0.0025, jitter_s=0.004, seed=2), 1000)
    got = []
    for step in range(2000):
        if step < 1900:
            up.push(step, [step], True)
        due = up.next_due()
        assert due is None or due >= step
        got += [(step, d[0]) for d in up.pop_due(step)]
    assert [x for _, x in got] == list(range(1900))
    assert all(3 <= step - x <= 7 for step, x in got)          # 2.5 ms + U(0, 4) ms, in whole steps


def test_a_corrupted_frame_fails_its_crc_alone():
    link = Link("udpin:127.0.0.1:0", 1, 1)
    try:
        down = FaultyDownlink(Downlink(LinkParams(), RATE, SUB, 0), FaultParams(corrupt=1.0, corrupt_from=10, seed=5),
                              RATE)
        down.push_period(0, [], _bundle(0))
        msgs, usable = down.release(0)
        data = b"".join(link.wire.pack(m) for m in msgs)
        parser = mavlink2.MAVLink(None)
        parser.robust_parsing = True
        kinds = [m.get_type() for m in parser.parse_buffer(data)]
        assert kinds.count("BAD_DATA") == 1 and len(kinds) == 3
        assert usable == (1 if "ATTITUDE" not in kinds else 0)
    finally:
        link.close()


def test_command_line_specs():
    assert link_faults_from_args([], [], [], 0) is None
    f = link_faults_from_args(["loss=0.1"], ["jitter_s=0.005"], ["outage=3:0.5"], 7)
    assert f.up == parse_faults("loss=0.1,jitter_s=0.005", seed=7, corrupt_from=10)
    assert f.down.outages == ((3.0, 0.5),) and f.down.seed == 7 and f.down.loss == 0.1


def test_an_old_key_in_ms_warns_once_on_the_command_line(capsys):
    f = link_faults_from_args(["jitter_ms=5"], [], [], 7)      # both ways: one notice, not two
    assert f.up.jitter_s == f.down.jitter_s == 0.005
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["firmware-sim: warning: link faults key jitter_ms is deprecated and goes in the next "
                   "release; use jitter_s (seconds)"]
    link_faults_from_args(["jitter_s=0.005"], [], [], 7)
    assert capsys.readouterr().err == ""
