"""mavreg's benchmark suite: every figure of issue #8 with its baseline measured in the same run.

    python -m benchmarks [--quick] [--only SECTION ...] [--json FILE]

Prints the machine, then one table (figure, value, baseline, ratio, target, met?, unit) and
a note per figure saying what it measures and against what. ``--json FILE`` writes the same
figures as ``{"plan_s.total": {"value", "baseline", "ratio", "target", "met", "unit",
"note"}, ...}`` plus ``"machine"`` (and the seconds each section took). ``ratio`` is always
"times better than the baseline". Sections, in the order they run (the lockstep and
real-time ones one after the other, never together: each sets ``MAVREG_IO`` in the
environment for its children):

- ``codec``: :mod:`benchmarks.codec` (pymavlink pack and parse of the hot messages, its fast
  CRC path; a warning if it is not in use);
- ``serial``: :mod:`benchmarks.serial_io` (``serial_us.*``: a period's telemetry read off a tty
  and a command written, against pyserial and pymavlink's serial connection);
- ``plan``: :mod:`benchmarks.plan_bench` (``plan_s.*``);
- ``step``: :mod:`benchmarks.step_bench` (``step_us.*``);
- ``controller``: :mod:`benchmarks.controller_bench` (``controller_us.*``: the daemon's
  per-sample forecaster, hover LQR, regulator and command bookkeeping);
- ``monte_carlo``: :mod:`benchmarks.monte_carlo` (``monte_carlo_s.*``);
- ``sitl``: :mod:`benchmarks.sitl` (``sitl_periods_per_s.*``: lockstep firmware_sim);
- ``daemon_rt``: :mod:`benchmarks.daemon_rt` (``daemon_latency_us.*``, ``daemon_cpu_pct``,
  deadline misses: the daemon at 500 Hz in real time, one barrel-roll flight per I/O path);
- ``first_run``: :mod:`benchmarks.first_run` (``first_run_s.*``: ``mavreg fly``'s first line
  and arming, on cold and warm caches, against the code before the start's stage lines);
  only with ``--only first_run`` (:data:`OPT_IN`: two cold starts take minutes).

``--quick`` shortens every section (a smoke test, well under a minute without ``sitl`` and
``daemon_rt``); the full run takes about 4 minutes on a quiet 2-core machine and under 5 at
a load average of 3, most of it the flights of ``sitl`` and ``daemon_rt``
(``docs/performance.md``).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.report import format_notes, format_table, format_targets

SECTIONS = ("codec", "serial", "plan", "step", "controller", "monte_carlo", "sitl", "daemon_rt", "first_run")
OPT_IN = ("first_run",)
"""Sections run only when named in ``--only`` (a cold start takes minutes, twice)."""


def _section(name: str):
    """The ``run_<section>(quick) -> figures`` function of a section (imported when run)."""
    if name == "codec":
        from benchmarks.codec import run_codec
        return run_codec
    if name == "serial":
        from benchmarks.serial_io import run_serial
        return run_serial
    if name == "plan":
        from benchmarks.plan_bench import run_plan
        return run_plan
    if name == "step":
        from benchmarks.step_bench import run_step
        return run_step
    if name == "controller":
        from benchmarks.controller_bench import run_controller
        return run_controller
    if name == "monte_carlo":
        from benchmarks.monte_carlo import run_monte_carlo
        return run_monte_carlo
    if name == "sitl":
        from benchmarks.sitl import run_sitl
        return run_sitl
    if name == "first_run":
        from benchmarks.first_run import run_first_run
        return run_first_run
    from benchmarks.daemon_rt import run_daemon_rt
    return run_daemon_rt


def machine() -> dict:
    """The machine and the software the figures were measured with."""
    import numpy
    import scipy
    from mavreg import accel
    cpu = ""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=10).stdout
        cpu = next((ln.split(":", 1)[1].strip() for ln in out.splitlines() if ln.startswith("Model name")), "")
    except (OSError, subprocess.SubprocessError):
        pass
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    return {"cpu": cpu or platform.processor(), "cpus": os.cpu_count(), "python": platform.python_version(),
            "numpy": numpy.__version__, "scipy": scipy.__version__, "compiled_kernels": accel.reason
            if accel.ACCELERATED else f"no ({accel.reason})", "load_average": load}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short versions of every section (a smoke test)")
    ap.add_argument("--only", nargs="+", choices=SECTIONS, metavar="SECTION",
                    help=f"run only these sections ({', '.join(SECTIONS)})")
    ap.add_argument("--json", metavar="FILE", default=None, help="also write the figures as JSON")
    args = ap.parse_args(argv)
    chosen = [s for s in SECTIONS if (s not in OPT_IN if args.only is None else s in args.only)]
    info = machine()
    print("machine: " + ", ".join(f"{k} {v}" for k, v in info.items() if k != "load_average"), flush=True)
    figs: dict = {}
    took: dict = {}
    t_all = time.perf_counter()
    for name in chosen:
        print(f"[{name}] ...", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        figs.update(_section(name)(args.quick))
        took[name] = round(time.perf_counter() - t0, 1)
        print(f"[{name}] {took[name]:.1f} s", file=sys.stderr, flush=True)
    info["load_average_after"] = os.getloadavg() if hasattr(os, "getloadavg") else None
    print()
    print(format_table(figs))
    print()
    print(format_notes(figs))
    print("\ntargets:\n" + format_targets(figs))
    print("\nsections: " + ", ".join(f"{k} {v:.0f} s" for k, v in took.items())
          + f"; total {time.perf_counter() - t_all:.0f} s" + (" (--quick)" if args.quick else ""))
    if args.json:
        Path(args.json).write_text(json.dumps({**figs, "machine": {**info, "section_s": took,
                                                                    "quick": args.quick}}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
