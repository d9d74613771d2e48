"""Daemon latency and CPU at a 500 Hz real-time loop.

A thin wrapper kept for the old command: the measurement is
:func:`benchmarks.daemon_rt.run_daemon_rt` (part of ``python -m benchmarks``; alone:
``python -m benchmarks.daemon_rt``): the barrel roll flown in real time against
firmware_sim, on the fast I/O path and on the reference one, latency by phase, the
controllers' share, CPU, deadline misses.

    python benchmarks/bench_daemon.py [--quick]
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.daemon_rt import main  # noqa: E402

if __name__ == "__main__":
    main()
