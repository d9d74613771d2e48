"""The daemon at 500 Hz in real time against firmware_sim: latency, CPU, deadline misses.

``run_daemon_rt(quick)`` flies the barrel roll the way ``mavreg fly`` does (the bundled
emulator in real time at 500 Hz as a child process, its default realistic world, the
default controller ``realistic.yaml``) with the daemon **in this process**, so that the
figures can be split by phase and the controller's own time told apart from the
daemon's. Once on the fast I/O path and once on the reference path
(``MAVREG_IO=reference``: asyncio datagram transport, pymavlink codec, one datagram per
message, for the daemon and the emulator alike), in that order. Figures:

- ``daemon_latency_us.p50`` / ``.p99``: from taking up the message that completes a state
  sample (its datagram just read; the second of two samples in one datagram from when
  the first is done) to handing the SET_ACTUATOR_CONTROL_TARGET to ``sendto``
  (``time.perf_counter_ns``), in the hover phases (take-off, hold, landing);
  ``daemon_latency_us.maneuver_p50`` / ``_p99`` in the maneuver (run-in included);
  ``daemon_latency_us.with_sendto_p50`` / ``_p99``: to the return of ``sendto``, as
  ``summary.json`` has it, and ``sendto_us``: the call itself (on loopback the kernel may
  run the woken emulator on this core before the call returns);
- ``daemon_overhead_us.hover_p50`` / ``.maneuver_p50``: latency minus the controllers' own
  time for the same sample (forecaster, hover LQR or maneuver regulator, the command
  bookkeeping of the forecaster): what the daemon itself adds (link, codec, state
  assembly, envelope monitor, logs);
- ``daemon_controller_us.hover_p50`` / ``.maneuver_p50``: that controller time;
- ``daemon_cpu_pct``: CPU time of this process (the daemon; the planner worker and the
  emulator are other processes) per wall second while airborne, percent of one core;
  ``daemon_cpu_pct.maneuver`` in the maneuver;
- ``daemon_deadline_misses``: commands whose ``sendto`` returned more than one control
  period (2 ms) after their sample was taken up, airborne; the note also gives the sample
  counts; ``daemon_deadline_misses.hover`` / ``.maneuver`` split by phase, each note with
  the seconds of that phase flown: one flight per path, under a minute airborne in all,
  not the issue's 60 s of each, to keep ``python -m benchmarks`` under 5 minutes.

``quick`` stops each flight after 20 s (take-off and hold only: the hover figures); the
full run flies the whole maneuver (about 60 s of flight per path).

Run alone: ``python -m benchmarks.daemon_rt [--quick]``.
"""
from __future__ import annotations

import asyncio
import collections
import os
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from benchmarks.report import standalone
from benchmarks.io_helpers import BARREL, REALISTIC_CONTROLLER, VEHICLE, figure, percentile

__all__ = ["run_daemon_rt", "realtime_flight"]

_HOVER = ("takeoff", "hold", "land")
_MANEUVER = ("run_in", "maneuver")
_PERIOD_NS = 2_000_000


def _timed(obj, name: str, acc: list) -> None:
    """Wrap ``obj.name`` so that its time is added to ``acc[0]`` (ns)."""
    f = getattr(obj, name)

    def w(*a, **k):
        t0 = time.perf_counter_ns()
        try:
            return f(*a, **k)
        finally:
            acc[0] += time.perf_counter_ns() - t0
    setattr(obj, name, w)


def realtime_flight(io: str, timeout_s: float, out: Path) -> dict:
    """One real-time flight with the daemon in this process on the ``io`` path."""
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.daemon.jobs.app import Daemon, DaemonConfig, regulator_factory
    from mavreg.daemon.jobs.fly import spawn_emulator, stop_process
    from mavreg.daemon.flight.supervisor import SupervisorParams

    old_io = os.environ.get("MAVREG_IO")
    os.environ["MAVREG_IO"] = io                  # the daemon's link and the emulator's
    vehicle = load_vehicle(VEHICLE)
    controller = load_controller(REALISTIC_CONTROLLER)
    out.mkdir(parents=True, exist_ok=True)
    config = DaemonConfig(vehicle_url="", controller=controller, socket_path=None, tlog_path=out / "flight.tlog",
                          supervisor=SupervisorParams(land_when_done=True), envelope=controller.envelope,
                          control_rate_hz=500.0)
    ctl_ns = [0]
    make = regulator_factory(vehicle, 500.0)

    def factory(plan, rotor_lag):
        reg = make(plan, rotor_lag)
        _timed(reg, "step", ctl_ns)
        return reg
    daemon = Daemon(config, vehicle, factory, log=lambda line: None)
    sup = daemon.supervisor
    for obj, name in ((sup.forecaster, "update"), (sup.forecaster, "command"), (sup.hover, "step"),
                      (sup.recovery, "step")):
        _timed(obj, name, ctl_ns)
    lat = collections.defaultdict(list)    # phase -> [(to sendto ns, controller ns, to sendto returned ns)]
    inner = daemon._on_read_end

    def on_read_end():
        n0, c0 = len(daemon.latency_ns), ctl_ns[0]
        t_recv_ns = daemon._inbox_t_ns       # when the read's first message was taken up
        inner()
        if len(daemon.latency_ns) > n0:       # a rotor command answered this read
            full = daemon.latency_ns[-1]
            sent = getattr(daemon.link, "last_send_ns", None)     # None: a link that does not say
            lat[sup.phase].append((full if sent is None else sent - t_recv_ns, ctl_ns[0] - c0, full))
    daemon._on_read_end = on_read_end
    cpu = collections.defaultdict(lambda: [0.0, 0.0])  # phase -> [cpu s, wall s]

    async def sample_cpu():
        w0, c0 = time.monotonic(), time.process_time()
        while True:
            await asyncio.sleep(0.25)
            w1, c1 = time.monotonic(), time.process_time()
            acc = cpu[sup.phase]
            acc[0] += c1 - c0
            acc[1] += w1 - w0
            w0, c0 = w1, c1

    proc = None
    try:
        async def main():
            nonlocal proc
            proc, url = spawn_emulator(VEHICLE, None, False, (), rate_hz=500.0, preset="realistic")
            daemon.config = replace(config, vehicle_url=url)
            task = asyncio.create_task(sample_cpu())
            try:
                await daemon.run([(BARREL.read_text(), str(BARREL))], timeout_s=timeout_s, install_signals=False)
            finally:
                task.cancel()
        asyncio.run(main())
    finally:
        if proc is not None:
            stop_process(proc)
        if old_io is None:
            os.environ.pop("MAVREG_IO", None)
        else:
            os.environ["MAVREG_IO"] = old_io

    def rows(phases):
        return [r for ph in phases for r in lat.get(ph, [])]

    def cpu_pct(phases):
        c = sum(cpu[ph][0] for ph in phases if ph in cpu)
        w = wall_s(phases)
        return 100.0 * c / w if w > 0 else None

    def wall_s(phases):
        return sum(cpu[ph][1] for ph in phases if ph in cpu)

    def misses(rows_):
        return sum(1 for r in rows_ if r[2] > _PERIOD_NS)

    airborne = rows(_HOVER + _MANEUVER + ("recover",))
    counters = sup.status()["counters"]
    return {
        "hover": rows(_HOVER), "maneuver": rows(_MANEUVER),
        "cpu_airborne": cpu_pct(_HOVER + _MANEUVER + ("recover",)), "cpu_maneuver": cpu_pct(_MANEUVER),
        "misses": misses(airborne), "answered": len(airborne),
        "misses_hover": misses(rows(_HOVER)), "misses_maneuver": misses(rows(_MANEUVER)),
        "hover_s": wall_s(_HOVER), "maneuver_s": wall_s(_MANEUVER),
        "phase": sup.phase, "samples": counters["samples"], "sent": counters["actuator_sent"],
        "gap_commands": counters["gap_commands"],
    }


def _p(rows, q, k=0):
    return percentile([r[k] / 1e3 for r in rows], q)


def _overhead(rows, q):
    return percentile([(r[0] - r[1]) / 1e3 for r in rows], q)


def _sendto(rows, q):
    return percentile([(r[2] - r[0]) / 1e3 for r in rows], q)


def run_daemon_rt(quick: bool) -> dict:
    """All the figures of the module docstring."""
    timeout = 20.0 if quick else 300.0
    runs = {}
    with tempfile.TemporaryDirectory(prefix="bench_daemon_rt_") as tmp:
        for io in ("fast", "reference"):
            runs[io] = realtime_flight(io, timeout, Path(tmp) / io)
    f, r = runs["fast"], runs["reference"]
    what = "hover phases of the barrel-roll flight" + (" (first 20 s)" if quick else "")
    note = (f"{what}; real time, realistic world, realistic.yaml; {len(f['hover'])} samples; "
            f"baseline MAVREG_IO=reference")
    fig = {
        "daemon_latency_us.p50": figure(_p(f["hover"], 50), _p(r["hover"], 50), target=60.0, unit="us",
                                        higher_is_better=False, note=note),
        "daemon_latency_us.p99": figure(_p(f["hover"], 99), _p(r["hover"], 99), target=300.0, unit="us",
                                        higher_is_better=False, note=note),
        "daemon_overhead_us.hover_p50": figure(_overhead(f["hover"], 50), _overhead(r["hover"], 50), unit="us",
                                               higher_is_better=False,
                                               note="latency minus the controllers' time (forecaster, hover LQR)"),
        "daemon_controller_us.hover_p50": figure(_p(f["hover"], 50, 1), _p(r["hover"], 50, 1), unit="us",
                                          higher_is_better=False,
                                          note="forecaster update + hover LQR + forecaster command, per sample"),
        "daemon_latency_us.with_sendto_p50": figure(
            _p(f["hover"], 50, 2), _p(r["hover"], 50, 2), unit="us", higher_is_better=False,
            note="hover, to the return of sendto (summary.json's latency): includes the kernel waking the "
                 "emulator on loopback, which may run on this core before sendto returns"),
        "daemon_latency_us.with_sendto_p99": figure(_p(f["hover"], 99, 2), _p(r["hover"], 99, 2), unit="us",
                                                    higher_is_better=False, note="hover, to the return of sendto"),
        "sendto_us.p50": figure(_sendto(f["hover"], 50), _sendto(r["hover"], 50), unit="us", higher_is_better=False,
                                note="the command's sendto call (hover)"),
        "sendto_us.p99": figure(_sendto(f["hover"], 99), _sendto(r["hover"], 99), unit="us", higher_is_better=False,
                                note="the command's sendto call (hover)"),
        "daemon_cpu_pct": figure(f["cpu_airborne"], r["cpu_airborne"], target=10.0, unit="% of a core",
                                 higher_is_better=False,
                                 note="this process (the daemon) while airborne; the planner worker and the "
                                      "emulator are other processes"),
    }
    if not quick:
        mnote = (f"maneuver (run-in and barrel roll), {len(f['maneuver'])} samples; flight ended in "
                 f"{f['phase']} (baseline {r['phase']})")
        fig.update({
            "daemon_latency_us.maneuver_p50": figure(_p(f["maneuver"], 50), _p(r["maneuver"], 50), target=60.0,
                                                     unit="us", higher_is_better=False, note=mnote),
            "daemon_latency_us.maneuver_p99": figure(_p(f["maneuver"], 99), _p(r["maneuver"], 99), target=300.0,
                                                     unit="us", higher_is_better=False, note=mnote),
            "daemon_overhead_us.maneuver_p50": figure(_overhead(f["maneuver"], 50), _overhead(r["maneuver"], 50),
                                                      unit="us", higher_is_better=False,
                                                      note="latency minus the controllers' time"),
            "daemon_controller_us.maneuver_p50": figure(_p(f["maneuver"], 50, 1), _p(r["maneuver"], 50, 1), unit="us",
                                                 higher_is_better=False,
                                                 note="forecaster update + maneuver regulator + forecaster command"),
            "daemon_cpu_pct.maneuver": figure(f["cpu_maneuver"], r["cpu_maneuver"], target=10.0,
                                              unit="% of a core", higher_is_better=False, note="in the maneuver"),
        })
    for part in ("hover", "maneuver") if not quick else ("hover",):
        fig[f"daemon_deadline_misses.{part}"] = figure(
            f[f"misses_{part}"], r[f"misses_{part}"], unit="commands", higher_is_better=False,
            note=f"commands later than 2 ms after their sample over {f[f'{part}_s']:.0f} s of {part} "
                 f"(baseline {r[f'{part}_s']:.0f} s)")
    fig["daemon_deadline_misses"] = figure(
        f["misses"], r["misses"], unit="commands", higher_is_better=False,
        note=f"commands later than 2 ms after their sample, of {f['answered']} airborne (baseline "
             f"{r['answered']}); complete samples {f['samples']}, commands {f['sent']}, gap-filling commands "
             f"{f['gap_commands']} (baseline {r['samples']}, {r['sent']}, {r['gap_commands']})")
    return fig


def main() -> None:
    standalone(run_daemon_rt, __doc__, quick_help="20 s of each flight (hover figures only)")


if __name__ == "__main__":
    main()
