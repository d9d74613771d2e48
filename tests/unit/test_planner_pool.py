"""The planner worker: lowest CPU priority, a dead worker reported and replaced, no orphans;
it plans with the parameter objects the daemon hands it."""
import asyncio
import dataclasses
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER
from mavreg.config.vehicle import load_vehicle
from mavreg.daemon.jobs.planner_pool import PlannerDied, PlannerPool
from harness.processes import start_time, survivors
from harness import params

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")

VEHICLE = params.vehicle()
CONTROLLER = params.controller("paper_lqr")
BARREL = params.BARREL_ROLL.read_text()
SCHED_IDLE = 5   # <linux/sched.h>


def _thread_sched(pid: int) -> list[tuple[int, int]]:
    """(nice, policy) of every thread of ``pid``."""
    out = []
    for tid in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{tid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        out.append((int(fields[16]), int(fields[38])))
    return out


async def _busy(pool: PlannerPool) -> None:
    while pool.busy == 0:
        await asyncio.sleep(0.01)


def test_worker_threads_run_at_nice_19_and_sched_idle():
    async def main():
        pool = PlannerPool(VEHICLE, CONTROLLER)
        try:
            await pool.warm_up()   # numpy (and its BLAS threads) are loaded by now
            return pool.worker_pid, _thread_sched(pool.worker_pid)
        finally:
            pool.shutdown()
    pid, threads = asyncio.run(main())
    assert pid != os.getpid() and len(threads) >= 1
    assert all(nice == 19 for nice, _ in threads), threads
    if hasattr(os, "SCHED_IDLE"):
        assert all(policy == SCHED_IDLE for _, policy in threads), threads


def test_worker_killed_while_planning_is_reported_and_replaced():
    async def main():
        pool = PlannerPool(VEHICLE, CONTROLLER)
        try:
            await pool.warm_up()
            old = pool.worker_pid
            job = asyncio.create_task(pool.plan(BARREL, "barrel.yaml"))
            await _busy(pool)
            os.kill(old, signal.SIGKILL)
            with pytest.raises(PlannerDied, match=r"died while planning 'barrel.yaml' \(killed by SIGKILL\)"):
                await job
            # the next upload is planned by a new worker: a rejection with the loader's reason
            after = await pool.plan("kind: maneuver\n", "bad.yaml")
            return old, pool.restarts, after
        finally:
            pool.shutdown()
    old, restarts, after = asyncio.run(main())
    assert restarts == 1
    assert not after.accepted and "bad.yaml" in after.reason
    assert start_time(old) is None


def test_shutdown_abandons_a_plan_and_kills_the_worker():
    async def main():
        pool = PlannerPool(VEHICLE, CONTROLLER)
        await pool.warm_up()
        pid = pool.worker_pid
        t0 = start_time(pid)
        job = asyncio.create_task(pool.plan(BARREL, "barrel.yaml"))
        await _busy(pool)
        pool.shutdown()
        with pytest.raises(PlannerDied, match="shut down"):
            await job
        return pid, t0, pool.restarts
    pid, t0, restarts = asyncio.run(main())
    assert restarts == 0
    assert survivors({pid: t0}) == []


_OWNER = textwrap.dedent("""
    import asyncio, sys, time
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.daemon.jobs.planner_pool import PlannerPool

    async def main():
        pool = PlannerPool(load_vehicle({vehicle!r}), load_controller({controller!r}))
        await pool.warm_up()
        print(pool.worker_pid, flush=True)
        await pool.plan(open({barrel!r}).read(), "barrel.yaml")   # killed while planning

    if __name__ == "__main__":
        asyncio.run(main())
""")


def test_worker_dies_with_a_sigkilled_owner(tmp_path):
    script = tmp_path / "owner.py"
    script.write_text(_OWNER.format(vehicle=str(DEFAULT_VEHICLE), controller=str(PAPER_CONTROLLER),
                                    barrel=str(params.BARREL_ROLL)))
    owner = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        worker = int(owner.stdout.readline())
        t0 = start_time(worker)
        assert t0 is not None
        os.kill(owner.pid, signal.SIGKILL)
        owner.wait(10)
        left = survivors({worker: t0})
    finally:
        owner.kill()
        owner.wait()
        owner.stdout.close()
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert left == []


def test_the_worker_plans_with_the_parameters_it_is_handed():
    """The daemon hands the worker the parameters it loaded, not their files: a vehicle that no
    file describes (rotors of 3 N) gets the barrel roll rejected for its rotor limit, and so
    does a restarted worker. Negative control: the vehicle file's rotors give more than the
    9.81 N the loop needs, so a worker that read the file would not reject it for that."""
    weak = dataclasses.replace(VEHICLE, max_rotor_thrust_n=3.0)

    async def main():
        pool = PlannerPool(weak, CONTROLLER)
        try:
            await pool.warm_up()
            first = await pool.plan(BARREL, "barrel.yaml")
            pool._restart()
            again = await pool.plan(BARREL, "barrel.yaml")
            return first, again
        finally:
            pool.shutdown()
    first, again = asyncio.run(main())
    for r in (first, again):
        assert not r.accepted and "needs 9.81 N > max_rotor_thrust_n 3.00 N" in r.reason, r.reason
    assert load_vehicle(DEFAULT_VEHICLE).max_rotor_thrust_n > 9.81
