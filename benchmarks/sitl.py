"""Lockstep SITL speed: firmware_sim and a controller as two processes over UDP.

``run_sitl(quick)`` returns a flat dict of figures (see :mod:`benchmarks.io_helpers`):

- ``sitl_periods_per_s.trivial``: control periods per wall second of ``firmware_sim
  --lockstep`` (500 Hz control, 1 kHz physics, in flight at hover, the default realistic
  world) against a trivial controller in this process that answers every
  LOCAL_POSITION_NED with a hover SET_ACTUATOR_CONTROL_TARGET. Fast path: the emulator's
  default I/O and a controller on :class:`mavreg.transport.wire.Wire`. Baseline, same run:
  ``MAVREG_IO=reference`` (one message per datagram, pymavlink's codec) and a pymavlink
  controller, what ``benchmarks/bench_firmware_sim.py`` used to measure;
- ``sitl_periods_per_s.trivial_ideal``: the same in the ideal world;
- ``sitl_cycle_us.trivial_p50`` / ``_p99``: wall time between consecutive samples at the
  controller in the ideal world (one full period: telemetry out, command back, physics);
- ``sitl_periods_per_s.regulator``: ``mavreg fly --lockstep`` flying the barrel roll with
  the real daemon, its default world and controller (realistic), periods per wall
  second from the first to the last rotor command of the flight (from the ``.tlog``, written
  with ``--tlog-clock wall``: a lockstep flight's log follows the vehicle's clock otherwise),
  fast path against ``MAVREG_IO=reference`` for both processes;
  ``sitl_periods_per_s.regulator_ideal``: ``--world ideal`` with ``paper_lqr.yaml``;
  ``sitl_cycle_us.regulator_p50`` / ``_p99``: time between consecutive commands;
- ``fsim_engine_us_per_period.ideal`` / ``.realistic``: the emulator's own CPU time per
  period in-process (no peer: telemetry to a sink socket, a decoded target handed in),
  best of 5 runs, against the reference codec and the reference RK4
  (``RigidBody.rk4_step_reference``), what ``bench_fsim_engine.py`` used to measure.

Run alone: ``python -m benchmarks.sitl [--quick]``.
"""
from __future__ import annotations

import json
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink2

from benchmarks.report import standalone
from benchmarks.io_helpers import (BARREL, HOVER, PAPER_CONTROLLER, REPO, env_with_io, figure, percentile,
                                   read_tlog, start_emulator, stop)

__all__ = ["run_sitl", "trivial_lockstep", "fly_lockstep", "engine_cpu_us"]

_LPN = mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED
_TARGET = mavlink2.MAVLINK_MSG_ID_SET_ACTUATOR_CONTROL_TARGET


def trivial_lockstep(io: str, periods: int, preset: str = "realistic") -> dict:
    """Lockstep emulator (``io`` path) against a trivial hover controller on the same path.

    Returns periods per wall second and the cycle times (µs) between consecutive samples.
    """
    proc, port = start_emulator(io, "--lockstep", "--world", preset, "--control-rate-hz", "500",
                                "--physics-hz", "1000", "--start", "z_m=-50", "--lockstep-timeout-s", "2")
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind(("127.0.0.1", 0))
        sock.connect(("127.0.0.1", port))
        sock.settimeout(5.0)
        controls = [HOVER] * 4 + [0.0] * 4
        if io == "fast":
            from mavreg.transport.wire import Wire
            wire = Wire(1, 191)
            parse, pack = wire.parse, wire.pack
        else:
            mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)
            mav.robust_parsing = True
            parse = lambda data: mav.parse_buffer(data) or []          # noqa: E731
            pack = lambda m: m.pack(mav)                               # noqa: E731
        sock.send(pack(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3)))
        warmup = min(500, periods // 10)
        stamps = []
        recv, send, now = sock.recv, sock.send, time.perf_counter
        target = mavlink2.MAVLink_set_actuator_control_target_message
        while len(stamps) < periods + warmup:
            for m in parse(recv(65535)):
                if m.get_msgId() == _LPN:
                    send(pack(target(int(m.time_boot_ms) * 1000, 0, 1, 1, controls)))
                    stamps.append((now(), m.time_boot_ms))
    finally:
        sock.close()
        stop(proc)
    (w0, t0), (w1, t1) = stamps[warmup], stamps[-1]
    cycles = [(b[0] - a[0]) * 1e6 for a, b in zip(stamps[warmup:], stamps[warmup + 1:])]
    return {"periods_per_s": (t1 - t0) / 2.0 / (w1 - w0), "cycles": cycles, "periods": (t1 - t0) // 2}


def fly_lockstep(io: str, world: str, out: Path) -> dict:
    """``mavreg fly --lockstep`` of the barrel roll on the bundled emulator, both on ``io``.

    ``world`` realistic: the default controller; ideal: ``paper_lqr.yaml`` (the paper's).
    """
    args = [sys.executable, "-m", "mavreg.cli.main", "fly", str(BARREL), "--lockstep", "--world", world,
            "--out", str(out), "--timeout-s", "600", "--tlog-clock", "wall"]
    if world == "ideal":
        args += ["--controller", str(PAPER_CONTROLLER)]
    p = subprocess.run(args, cwd=REPO, env=env_with_io(io), capture_output=True, text=True, timeout=900)
    summary = json.loads((out / "summary.json").read_text())
    cmds = [t for t, comp, mid in read_tlog(out / "flight.tlog") if comp == 191 and mid == _TARGET]
    cycles = [(b - a) * 1e6 for a, b in zip(cmds, cmds[1:])]
    return {"periods_per_s": (len(cmds) - 1) / (cmds[-1] - cmds[0]), "cycle_p50_us": percentile(cycles, 50),
            "cycle_p99_us": percentile(cycles, 99), "result": summary["result"], "exit": p.returncode,
            "commands": len(cmds), "latency_ms": summary["latency_ms"]}


def engine_cpu_us(io: str, preset: str, periods: int) -> float:
    """The emulator's CPU time per control period in-process, best of 5 (see the module doc)."""
    import os
    from firmware_sim import cli
    old = os.environ.get("MAVREG_IO")
    os.environ["MAVREG_IO"] = io
    try:
        args = ["--listen", "udpin:127.0.0.1:0", "--quiet", "--start", "z_m=-50", "--control-rate-hz", "500",
                "--world", preset]
        engine, _ = cli.build_engine(cli.build_parser().parse_args(args))
    finally:
        if old is None:
            os.environ.pop("MAVREG_IO", None)
        else:
            os.environ["MAVREG_IO"] = old
    body = engine.sim.body
    if io == "reference":
        body.rk4_step = body.rk4_step_reference
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    sink.setblocking(False)
    engine.link.peers.append(sink.getsockname())
    packed = mavlink2.MAVLink_set_actuator_control_target_message(
        0, 0, 1, 1, [HOVER] * 4 + [0.0] * 4).pack(mavlink2.MAVLink(None, 1, 191))
    target = mavlink2.MAVLink(None).parse_buffer(packed)[0]

    def drain():
        try:
            while True:
                sink.recv(65535)
        except BlockingIOError:
            pass

    def period():
        engine.begin_period()
        engine.receive([target])
        engine.step()
    try:
        for _ in range(300):
            period()
        drain()
        runs = []
        for _ in range(5):
            t0 = time.process_time()
            for k in range(periods):
                period()
                if k % 64 == 0:
                    drain()
            runs.append((time.process_time() - t0) / periods * 1e6)
    finally:
        engine.link.close()
        sink.close()
    return min(runs)


def _median(runs: list, key: str) -> float:
    return float(statistics.median(r[key] for r in runs))


def run_sitl(quick: bool) -> dict:
    """All the figures of the module docstring (``quick``: fewer periods and repeats, the
    ideal-world flight only). Lockstep rates are medians over interleaved repeats (the
    machine is shared); cycle percentiles pool the repeats."""
    n, repeats = (2000, 2) if quick else (5000, 3)
    fig = {}
    for key, preset in (("trivial", "realistic"), ("trivial_ideal", "ideal")):
        runs = {"reference": [], "fast": []}
        for _ in range(repeats):
            for io in ("reference", "fast"):
                runs[io].append(trivial_lockstep(io, n, preset))
        ref, fast = runs["reference"], runs["fast"]
        fig[f"sitl_periods_per_s.{key}"] = figure(
            _median(fast, "periods_per_s"), _median(ref, "periods_per_s"), target=8000.0, unit="periods/s",
            higher_is_better=True,
            note=f"firmware_sim --lockstep --world {preset}, 500 Hz control, 1 kHz physics, trivial hover "
                 f"controller; baseline MAVREG_IO=reference (pymavlink, one message per datagram); median of "
                 f"{repeats} x {n} periods")
        if key == "trivial_ideal":      # in the realistic world samples come in jittered clumps
            for q in (50, 99):
                fig[f"sitl_cycle_us.trivial_p{q}"] = figure(
                    percentile([c for r in fast for c in r["cycles"]], q),
                    percentile([c for r in ref for c in r["cycles"]], q), unit="us", higher_is_better=False,
                    note="ideal world: wall time from one sample to the next at the controller")
    worlds = (("regulator_ideal", "ideal"),) if quick else (("regulator", "realistic"), ("regulator_ideal", "ideal"))
    with tempfile.TemporaryDirectory(prefix="bench_sitl_") as tmp:
        for key, world in worlds:
            ref = fly_lockstep("reference", world, Path(tmp) / f"{key}_ref")
            fast = fly_lockstep("fast", world, Path(tmp) / f"{key}_fast")
            ctl = "paper_lqr.yaml" if world == "ideal" else "realistic.yaml"
            fig[f"sitl_periods_per_s.{key}"] = figure(
                fast["periods_per_s"], ref["periods_per_s"], target=3000.0, unit="periods/s", higher_is_better=True,
                note=f"mavreg fly --lockstep --world {world} ({ctl}), barrel roll from the ground, "
                     f"{fast['commands']} periods; flight {fast['result']} (baseline flight {ref['result']})")
            fig[f"sitl_cycle_us.{key}_p50"] = figure(fast["cycle_p50_us"], ref["cycle_p50_us"], unit="us",
                                                     higher_is_better=False, note="command to next command")
            fig[f"sitl_cycle_us.{key}_p99"] = figure(fast["cycle_p99_us"], ref["cycle_p99_us"], unit="us",
                                                     higher_is_better=False, note="command to next command")
    m = 1500 if quick else 4000
    for preset in ("ideal", "realistic"):
        fig[f"fsim_engine_us_per_period.{preset}"] = figure(
            engine_cpu_us("fast", preset, m), engine_cpu_us("reference", preset, m), unit="us CPU",
            higher_is_better=False,
            note=f"firmware_sim in-process, --world {preset}, best of 5 x {m} periods; baseline: pymavlink "
                 "codec, one datagram per message, rk4_step_reference")
    return fig


def main() -> None:
    standalone(run_sitl, __doc__, quick_help="fewer periods, the ideal-world flight only")


if __name__ == "__main__":
    main()
