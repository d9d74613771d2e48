"""How long hostile requests stall the daemon's event loop (docs/reliability.md).

``python -m benchmarks.hostile_endpoint`` serves the control endpoint with the daemon's
planner (:class:`~mavreg.daemon.jobs.planner_pool.PlannerPool`, default bounds) on an event loop
that also runs a 20 ms ticker, as the daemon's control loop does, and sends, one kind at a
time: malformed JSON, a 5 MB request, a line past the limit without a newline, slow clients
(a byte every 0.2 s, never done within the 10 s read timeout) filling the connection cap
plus one more, another user's request
(the peer check made to see another uid), a YAML alias bomb, and for reference a valid
barrel roll upload. For each it prints the reply and the longest gap between two ticks
(and the most CPU the loop's thread used between two) while it was handled. The gaps include
the time the process waited for a CPU: on a loaded machine, run it twice.
"""
from __future__ import annotations

import asyncio
import json
import os
import socket
import tempfile
import threading
import time
from pathlib import Path

from mavreg.config.controller import load_controller
from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, PARAMS_DIR
from mavreg.config.vehicle import load_vehicle
from mavreg.daemon.jobs import endpoint
from mavreg.daemon.jobs.endpoint import EndpointServer, request
from mavreg.daemon.jobs.planner_pool import PlannerPool

TICK_S = 0.02


def alias_bomb(levels: int) -> str:
    lines = ["a0: &a0 [" + ", ".join(['"lol"'] * 10) + "]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, levels)]
    return "\n".join(lines + [f"kind: *a{levels - 1}"]) + "\n"


class Ticker:
    """The control loop's stand-in: wakes every TICK_S and keeps the worst gap since reset."""

    def __init__(self):
        self.reset()

    def reset(self):
        self.gap_s, self.cpu_s = 0.0, 0.0

    async def run(self):
        last, last_cpu = time.perf_counter(), time.thread_time()
        while True:
            await asyncio.sleep(TICK_S)
            now, cpu = time.perf_counter(), time.thread_time()
            self.gap_s, self.cpu_s = max(self.gap_s, now - last), max(self.cpu_s, cpu - last_cpu)
            last, last_cpu = now, cpu


def _send(path, data: bytes, pace_s: float = 0.0) -> bytes:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(300)
        s.connect(str(path))

        def send():
            try:
                if pace_s:
                    for b in data:
                        s.sendall(bytes([b]))
                        time.sleep(pace_s)
                else:
                    s.sendall(data)
            except OSError:
                pass
        threading.Thread(target=send, daemon=True).start()
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
    return buf


def upload(text: str, name: str) -> bytes:
    return (json.dumps({"op": "upload", "name": name, "yaml": text}) + "\n").encode()


def _cases(path):
    """(name, client) pairs; the payloads are built here, not while the ticker is watched."""
    barrel = upload((PARAMS_DIR / "maneuvers/barrel_roll.yaml").read_text(), "barrel_roll.yaml")
    huge, bomb = upload("#" * (5 << 20), "huge.yaml"), upload(alias_bomb(10), "bomb.yaml")
    slow = upload("x" * 100, "slow.yaml")
    return [
        ("malformed JSON", lambda: _send(path, b'{"op": "upload", "name": \n')),
        ("5 MB request", lambda: _send(path, huge)),
        ("1 MB without newline", lambda: _send(path, b"x" * (1 << 20))),
        ("9 slow clients (cap 8)", lambda: b"".join(
            f for f in _parallel([lambda: _send(path, slow, 0.2)] * 9))),
        ("another uid", lambda: _as_other_user(path)),
        ("alias bomb (10 levels)", lambda: _send(path, bomb)),
        ("barrel roll (accepted)", lambda: _send(path, barrel)),
        ("nothing, 30 s (the machine's own share of the gaps)", lambda: time.sleep(30) or b""),
    ]


def _parallel(fns):
    out = [None] * len(fns)

    def run(i):
        out[i] = fns[i]()
    threads = [threading.Thread(target=run, args=(i,)) for i in range(len(fns))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return out


def _as_other_user(path):
    real = endpoint.peer_uid
    endpoint.peer_uid = lambda sock: os.geteuid() + 1
    try:
        return (json.dumps(request(path, {"op": "status"}, 30)) + "\n").encode()
    finally:
        endpoint.peer_uid = real


async def main():
    pool = PlannerPool(load_vehicle(DEFAULT_VEHICLE), load_controller(PAPER_CONTROLLER))
    await pool.warm_up()

    async def handler(req):
        if req["op"] != "upload":
            return {"ok": True}
        r = await pool.plan(req["yaml"], req["name"])
        return ({"ok": True, "verdict": "accepted"} if r.accepted
                else {"ok": False, "verdict": "rejected", "reason": r.reason})
    ticker = Ticker()
    tick = asyncio.create_task(ticker.run())
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mavreg.sock"
        server = EndpointServer(path, handler, lambda text: None, read_timeout_s=10.0)
        await server.start()
        loop = asyncio.get_running_loop()
        try:
            cases = _cases(path)             # built before the ticker is watched
            ticker.reset()
            await asyncio.sleep(1.0)
            print(f"idle: longest tick gap {ticker.gap_s * 1e3:.1f} ms (CPU {ticker.cpu_s * 1e3:.1f} ms)")
            for name, case in cases:
                ticker.reset()
                t0 = time.perf_counter()
                reply = await loop.run_in_executor(None, case)
                wall = time.perf_counter() - t0
                lines = reply.decode(errors="replace").splitlines()
                reasons = sorted({json.loads(x).get("reason", json.loads(x).get("verdict", "ok")) for x in lines})
                print(f"{name}: {wall:.1f} s, longest tick gap {ticker.gap_s * 1e3:.1f} ms "
                      f"(CPU {ticker.cpu_s * 1e3:.1f} ms); {len(lines)} replies: {'; '.join(reasons)[:300]}")
        finally:
            await server.close()
            tick.cancel()
            pool.shutdown()


if __name__ == "__main__":
    asyncio.run(main())
