"""The planner worker's bounds: a hostile upload costs a one-line rejection, never the daemon
(mavreg.daemon.jobs.planner_pool, "Bounds"): memory (RLIMIT_AS), CPU per plan, wall clock (the
worker killed and replaced), the queue of waiting uploads, the length of a reason."""
from __future__ import annotations

import asyncio
import dataclasses
import os
import re
import signal
import sys

import pytest

from mavreg.daemon.jobs.planner_pool import PlannerBounds, PlannerPool
from mavreg.errors import EXIT_FAILED, EXIT_USAGE, MAX_MESSAGE_CHARS
from harness import params
from tests.helpers.waiting import wait_until_async

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS, /proc")

VEHICLE = params.vehicle()
CONTROLLER = params.controller("paper_lqr")
BARREL = params.BARREL_ROLL.read_text()
BAD = BARREL.replace("radius_m: 1.5", "radius_m: -1.5")


def alias_bomb(levels: int) -> str:
    """'Billion laughs': ten references to the level below, ``levels`` deep, in ``kind:``."""
    lines = ["a0: &a0 [" + ", ".join(['"lol"'] * 10) + "]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, levels)]
    return "\n".join(lines + [f"kind: *a{levels - 1}"]) + "\n"


def _with_pool(bounds: PlannerBounds, body):
    async def main():
        pool = PlannerPool(VEHICLE, CONTROLLER, bounds)
        try:
            await pool.warm_up()
            return await body(pool)
        finally:
            pool.shutdown()
    return asyncio.run(main())


def _vm_limit(pid: int) -> int | None:
    with open(f"/proc/{pid}/limits") as f:
        for line in f:
            if line.startswith("Max address space"):
                soft = line.split()[3]
                return None if soft == "unlimited" else int(soft)
    return None


def test_an_alias_bomb_and_a_plan_over_its_cpu_budget_are_rejected_and_the_worker_plans_on():
    """Ten levels (10^10 'lol's, 530 bytes) grew a process to 3 GB in a minute: the loader now
    refuses it, and the worker's address space is capped for what passes the loader and the
    planning budget (40 laps: 645 MiB estimated, under the budget's 768 MiB, over the 384 MiB here);
    each upload is rejected in one line. Then the barrel roll over
    a CPU budget of 0.3 s. The pool answers throughout, with one new worker after the memory bound."""
    async def body(pool):
        pid, limit = pool.worker_pid, _vm_limit(pool.worker_pid)
        bomb = await pool.plan(alias_bomb(10), "bomb.yaml")
        big = await pool.plan(re.sub(r"count: \d+", "count: 40", BARREL), "big.yaml")
        pool.bounds = dataclasses.replace(pool.bounds, cpu_s=0.3)
        over = await pool.plan(BARREL, "barrel.yaml")
        after = await pool.plan(BAD, "bad.yaml")
        return pid, limit, bomb, big, over, after, pool.worker_pid, pool.restarts
    pid, limit, bomb, big, over, after, pid_after, restarts = _with_pool(
        PlannerBounds(memory_bytes=384 << 20, cpu_s=20), body)
    assert limit is not None and limit < 2 << 30
    print(f"\nalias bomb: {bomb.reason}")
    # the loader refuses the bomb before it expands (its alias budget); a plan within the
    # planning budget but over the worker's memory is abandoned at the memory bound
    assert not bomb.accepted and bomb.status == EXIT_USAGE and "bomb.yaml" in bomb.reason and "alias" in bomb.reason
    print(f"40 laps: {big.reason}")
    assert not big.accepted and big.status == EXIT_FAILED and "memory" in big.reason
    for r in (bomb, big):
        assert "\n" not in r.reason and len(r.reason) <= MAX_MESSAGE_CHARS
    assert not over.accepted and over.status == EXIT_FAILED and "more than its 0.3 s of CPU" in over.reason
    assert not after.accepted and after.status == EXIT_USAGE and "radius_m" in after.reason
    assert restarts == 1 and pid_after != pid     # replaced after its memory bound, once


def test_a_stalled_worker_is_replaced_and_uploads_beyond_the_queue_are_rejected_at_once():
    """A worker that does not answer (stopped here; hung in C code in the wild) is killed and
    replaced when the wall clock runs out; meanwhile an upload beyond the queue is refused."""
    async def body(pool):
        old = pool.worker_pid
        os.kill(old, signal.SIGSTOP)
        first = asyncio.create_task(pool.plan(BAD, "stalled.yaml"))
        await wait_until_async(lambda: pool.busy == 1, "the first upload in the pool", 30)
        second = await pool.plan(BAD, "second.yaml")       # the queue (0) is full
        stalled = await first
        after = await pool.plan(BAD, "after.yaml")
        return old, second, stalled, after, pool.restarts, pool.timeouts
    old, second, stalled, after, restarts, timeouts = _with_pool(PlannerBounds(wall_s=1.0, queue=0), body)
    assert not second.accepted and "busy" in second.reason
    assert not stalled.accepted and "no plan within 1 s" in stalled.reason
    assert restarts == 1 and timeouts == 1
    assert not after.accepted and "radius_m" in after.reason       # a new worker answers
    with pytest.raises(ProcessLookupError):
        os.kill(old, 0)
