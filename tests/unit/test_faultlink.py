"""The fault-injecting link (mavreg.tools.faultlink): its rates for a seed, its reorder,
duplicate, corruption and outage semantics, its independence of streams, and the UDP proxy."""
from __future__ import annotations

import asyncio
import socket

import pytest

from mavreg.tools.faultlink import FaultLine, FaultParams, flip_bits, parse_faults
from mavreg.tools.faultlink.proxy import start_proxy
from tests.helpers.waiting import wait_until_async

N = 20000
PERIOD = 0.002


def run(params: FaultParams, n: int = N, direction: str = "down") -> tuple[FaultLine, list]:
    """Push 0..n-1 one per period; release everything; return the line and the items out."""
    line = FaultLine(params, direction)
    out = []
    for k in range(n):
        line.push(k * PERIOD, k)
        out.extend(line.pop_due(k * PERIOD))
    out.extend(line.pop_due(1e9))
    return line, out


def test_clean_line_passes_everything_in_order_at_once():
    line, out = run(FaultParams(), 100)
    assert out == list(range(100)) and line.counters.released == 100


def test_independent_loss_rate_within_tolerance():
    line, out = run(FaultParams(loss=0.1, seed=3))
    rate = 1 - len(out) / N
    assert abs(rate - 0.1) < 0.01                    # 5 sigma of a binomial at N = 20000 is 0.011
    assert line.counters.lost == N - len(out) and out == sorted(out)


def test_gilbert_elliott_bursts_mean_length_and_rate():
    # stationary bad share: enter / (enter + exit) = 0.02 / 0.27; all lost there
    p = FaultParams(burst_enter=0.02, burst_exit=0.25, burst_loss=1.0, seed=5)
    line, out = run(p, 50000)
    got = set(out)
    lost = [k not in got for k in range(50000)]
    bursts = [0]
    for a, b in zip(lost, lost[1:]):
        if b:
            bursts[-1] += 1
        elif a:
            bursts.append(0)
    runs = []
    cur = 0
    for x in lost:
        if x:
            cur += 1
        elif cur:
            runs.append(cur)
            cur = 0
    assert abs(sum(lost) / 50000 - 0.02 / 0.27) < 0.015
    assert 3.0 < sum(runs) / len(runs) < 5.0           # mean burst 1 / exit = 4 items
    assert line.counters.burst_lost == sum(lost)
    # independent losses at the same rate make much shorter runs (negative control)
    _, out2 = run(FaultParams(loss=0.074, seed=5), 50000)
    got2 = set(out2)
    runs2, cur = [], 0
    for k in range(50000):
        if k not in got2:
            cur += 1
        elif cur:
            runs2.append(cur)
            cur = 0
    assert sum(runs2) / len(runs2) < 1.2


def test_jitter_delays_within_bounds_and_never_reorders():
    line = FaultLine(FaultParams(delay_s=0.001, jitter_s=0.005, seed=1))
    released = []
    for k in range(2000):
        line.push(k * PERIOD, (k, k * PERIOD))
    while line.in_flight:
        due = line.next_due()
        released += [(item, due) for item in line.pop_due(due)]
    assert [i for (i, _), _ in released] == list(range(2000))
    delays = [due - t0 for (_, t0), due in released]
    assert min(delays) >= 0.001 - 1e-12 and max(delays) <= 0.006 + 1e-12
    assert max(delays) > 0.005                          # the jitter is used


def test_reordered_items_are_overtaken_and_counted():
    line, out = run(FaultParams(reorder=0.05, reorder_s=0.01, seed=2), 5000)
    assert sorted(out) == list(range(5000))            # nothing lost, nothing added
    late = [k for i, k in enumerate(out) if any(j > k for j in out[:i])]
    assert abs(line.counters.reordered / 5000 - 0.05) < 0.015
    assert len(late) == line.counters.reordered         # each reordered item comes after a later one
    # 10 ms at 2 ms per item: overtaken by the next 5 items
    k = late[0]
    assert out.index(k) - out.index(k + 5) == 1


def test_duplicates_are_released_twice_and_counted():
    line, out = run(FaultParams(duplicate=0.1, dup_gap_s=0.004, seed=4), 5000)
    dups = [k for k in set(out) if out.count(k) == 2]
    assert len(out) == 5000 + len(dups) and len(dups) == line.counters.duplicated
    assert abs(len(dups) / 5000 - 0.1) < 0.02
    assert max(out.count(k) for k in set(out)) == 2


def test_outage_drops_exactly_its_window():
    line, out = run(FaultParams(outages=((1.0, 0.5),)), 2000)
    missing = sorted(set(range(2000)) - set(out))
    assert missing == list(range(500, 750)) and line.counters.outage == 250


def test_corruption_flips_one_to_three_bits_after_the_header():
    line = FaultLine(FaultParams(corrupt=1.0, corrupt_from=10, seed=9))
    frame = bytes(range(40))
    for k in range(200):
        line.push(k * PERIOD, frame)
    out = line.pop_due(10.0)
    assert len(out) == 200 and line.counters.corrupted == 200
    for data in out:
        diff = [a ^ b for a, b in zip(frame, data)]
        bits = sum(bin(d).count("1") for d in diff)
        assert 1 <= bits <= 3 and not any(diff[:10])


def test_each_effect_has_its_own_stream():
    base = run(FaultParams(loss=0.2, seed=11), 3000)[1]
    with_dups = run(FaultParams(loss=0.2, duplicate=0.3, seed=11), 3000)[1]
    assert sorted(set(with_dups)) == base                # the same items lost
    other_seed = run(FaultParams(loss=0.2, seed=12), 3000)[1]
    assert other_seed != base
    up = run(FaultParams(loss=0.2, seed=11), 3000, direction="up")[1]
    assert up != base                                     # the two directions draw independently


def test_same_seed_same_run():
    p = FaultParams(loss=0.1, burst_enter=0.01, jitter_s=0.005, reorder=0.02, duplicate=0.02, seed=7)
    assert run(p, 3000)[1] == run(p, 3000)[1]


def test_parse_faults_and_its_one_line_errors():
    p = parse_faults("loss=0.1,jitter_s=0.005,outage=12:0.5,outage=20:1,corrupt=0.01,seed=3")
    assert (p.loss, p.jitter_s, p.outages, p.corrupt, p.seed) == (0.1, 0.005, ((12.0, 0.5), (20.0, 1.0)), 0.01, 3)
    for bad, needle in (("lose=0.1", "unknown key"), ("loss=abc", "not a number"), ("loss=2", "probability"),
                        ("loss", "KEY=VALUE"), ("jitter_s=nan", "seconds"), ("delay_s=61", "seconds"), ("jitter_ms=x", "not a number"), ("outage=1", "not a number")):
        with pytest.raises(ValueError, match=needle) as e:
            parse_faults(bad)
        assert "\n" not in str(e.value)


def test_flip_bits_short_input():
    import random
    assert flip_bits(b"abc", random.Random(0), 3, start=5) == b"abc"


def test_udp_proxy_forwards_both_ways_with_its_faults():
    """Real sockets on loopback: every datagram up arrives (no faults up), a 50 % lossy
    down line loses about half, and replies go to the daemon's address."""
    async def main():
        vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        vehicle.bind(("127.0.0.1", 0))
        vehicle.setblocking(False)
        daemon = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        daemon.bind(("127.0.0.1", 0))
        daemon.setblocking(False)
        proxy = await start_proxy(("127.0.0.1", 0), vehicle.getsockname(), FaultParams(delay_s=0.001),
                                  FaultParams(loss=0.5, seed=1))
        loop = asyncio.get_running_loop()
        try:
            for k in range(200):
                daemon.sendto(b"up%d" % k, proxy.listen_addr)
            got_up, vaddr = [], None
            while len(got_up) < 200:
                data, vaddr = await asyncio.wait_for(loop.sock_recvfrom(vehicle, 100), 5)
                got_up.append(data)
            for k in range(400):
                vehicle.sendto(b"dn%d" % k, vaddr)
                if k % 20 == 19:
                    await asyncio.sleep(0.002)          # let the proxy read (socket buffers are finite)
            got_down = []

            def all_down() -> bool:
                while True:
                    try:
                        got_down.append(daemon.recvfrom(100)[0])
                    except BlockingIOError:
                        break
                c = proxy.down.counters
                return c.pushed == 400 and c.released + c.lost == 400 and len(got_down) == c.released
            await wait_until_async(all_down, "the 400 datagrams through the proxy, each released or lost", 30)
            return got_up, got_down, proxy
        finally:
            proxy.close()
            vehicle.close()
            daemon.close()

    got_up, got_down, proxy = asyncio.run(main())
    assert got_up == [b"up%d" % k for k in range(200)]
    assert proxy.down.counters.pushed == 400
    assert len(got_down) == proxy.down.counters.released == 400 - proxy.down.counters.lost
    assert 150 < len(got_down) < 250
    assert got_down == sorted(got_down, key=lambda d: int(d[2:]))


def test_the_old_keys_in_ms_give_the_seconds_keys_doubles_and_a_one_line_notice(recwarn):
    """``jitter_ms=9`` is ``jitter_s=0.009`` bit for bit (9 * 1e-3 is not: the conversion is
    decimal), for one release, with a notice naming the key in seconds."""
    new = parse_faults("delay_s=0.013,jitter_s=0.009,reorder=0.1,reorder_s=0.0026,duplicate=0.1,dup_gap_s=0.02")
    assert len(recwarn) == 0
    notices: list = []
    old = parse_faults("delay_ms=13,jitter_ms=9,reorder=0.1,reorder_ms=2.6,duplicate=0.1,dup_gap_ms=20",
                       on_deprecated=notices.append)
    assert old == new and 9 * 1e-3 != new.jitter_s           # negative control: the naive product
    assert notices == [f"link faults key {k}_ms is deprecated and goes in the next release; use {k}_s (seconds)"
                       for k in ("delay", "jitter", "reorder", "dup_gap")]
    with pytest.warns(DeprecationWarning, match="jitter_ms is deprecated.*use jitter_s"):
        assert parse_faults("jitter_ms=5").jitter_s == 0.005
