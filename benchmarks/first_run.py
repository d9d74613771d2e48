"""The first run: how soon ``mavreg fly`` says something, and how soon the vehicle arms.

``run_first_run(quick)`` flies the barrel roll on the bundled emulator in lockstep
(``mavreg fly barrel_roll.yaml --lockstep``, a child process, stdout and stderr read as one
stream) and stops it once the vehicle is armed (the flight itself is measured elsewhere):

- **cold**: numba's cache and the plan cache are empty directories (``NUMBA_CACHE_DIR``,
  ``MAVREG_PLAN_CACHE``): a fresh install, the kernels compile and the maneuver is planned;
- **warm**: the same command again on those caches (a second run, or a first run after
  ``mavreg warm-up``).

Figures (wall seconds from starting the command), each with its baseline from the same run:

- ``first_run_s.{cold,warm}_first_line``: the first line printed; target 1 s (issue 30).
  Baseline: the code before issue 30's item 3 (commit :data:`BASE_COMMIT`, exported with
  ``git archive`` into a temporary directory and run from there on caches of its own), whose
  first line was the maneuver's ``queued`` event;
- ``first_run_s.{cold,warm}_armed``: the ``vehicle armed`` event; target (warm) 10 s.
  Baseline: the same code before item 3.

The old and the new code fly in turn (cold, cold, then warm three times each: the medians),
so that a change of the machine's load falls on both. Without git (an installed copy) the
baselines are left empty. ``--quick`` flies only the current code, warm once (after one
untimed cold run).

Run alone: ``python -m benchmarks.first_run [--quick]``.
"""
from __future__ import annotations

import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.io_helpers import BARREL, REPO, figure

BASE_COMMIT = "f2edb94"
"""The last commit before the start said what it does (issue 30, item 3)."""

ARMED = "vehicle armed"
WARM_RUNS = 3
TIMEOUT_S = 900.0


def fly_until_armed(code_dir: Path, cache_dir: Path) -> dict:
    """``mavreg fly`` of the code in ``code_dir`` on the caches under ``cache_dir``:
    {"first_line_s", "first_event_s" (the first line that is not a start stage), "armed_s"}
    (None for a line never seen); the command is killed once armed."""
    env = {**os.environ, "PYTHONPATH": str(code_dir), "NUMBA_CACHE_DIR": str(cache_dir / "numba"),
           "MAVREG_PLAN_CACHE": str(cache_dir / "plans")}
    env.pop("MAVREG_PURE", None)
    with tempfile.TemporaryDirectory() as out:
        t0 = time.monotonic()
        proc = subprocess.Popen([sys.executable, "-m", "mavreg.cli.main", "fly", str(BARREL), "--lockstep",
                                 "--out", str(Path(out) / "flight")], cwd=out, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, bufsize=1, start_new_session=True)
        seen: dict = {"first_line_s": None, "first_event_s": None, "armed_s": None}
        try:
            for line in proc.stdout:
                t = time.monotonic() - t0
                seen["first_line_s"] = seen["first_line_s"] or t
                if "[start] setup:" not in line:
                    seen["first_event_s"] = seen["first_event_s"] or t
                if ARMED in line:
                    seen["armed_s"] = t
                    break
                if t > TIMEOUT_S:
                    break
        finally:
            _kill_group(proc)
    return seen


def _kill_group(proc: subprocess.Popen) -> None:
    """The command and what it started (the emulator, the planner worker)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()
    proc.stdout.close()


def export_base(into: Path) -> Path | None:
    """:data:`BASE_COMMIT`'s tree in ``into`` (None where git or the commit is missing)."""
    try:
        into.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(["git", "-C", str(REPO), "archive", BASE_COMMIT], capture_output=True,
                                 timeout=120, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(into)], input=archive, capture_output=True, timeout=120,
                       check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return into


def _median(runs: list[dict]) -> dict:
    """Each figure's median over ``runs`` (None where a run did not see it)."""
    keys = ("first_line_s", "first_event_s", "armed_s")
    if not runs:
        return {}
    return {k: None if any(r[k] is None for r in runs) else statistics.median(r[k] for r in runs) for k in keys}


def measure(work: Path, quick: bool) -> tuple[dict, dict, dict, dict]:
    """(cold now, warm now, cold before, warm before): the current code and the code at
    :data:`BASE_COMMIT` one after the other, so that both see the same load; warm is the
    median of three runs (quick: one, and no code before)."""
    base = None if quick else export_base(work / "base")
    codes = {"now": REPO, **({"before": base} if base is not None else {})}
    cold, warm = {}, {name: [] for name in codes}
    for name, code in codes.items():
        (work / name).mkdir()
        cold[name] = fly_until_armed(code, work / name)
    for _ in range(1 if quick else WARM_RUNS):
        for name, code in codes.items():
            warm[name].append(fly_until_armed(code, work / name))
    return cold["now"], _median(warm["now"]), cold.get("before", {}), _median(warm.get("before", []))


def run_first_run(quick: bool) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        cold, warm, base_cold, base_warm = measure(Path(tmp), quick)
    figs = {}
    for name, now, before in (("cold", cold, base_cold), ("warm", warm, base_warm)):
        if quick and name == "cold":
            continue
        runs = "median of 3, " if name == "warm" and not quick else ""
        figs[f"first_run_s.{name}_first_line"] = figure(
            now["first_line_s"], before.get("first_line_s"), target=1.0, unit="s", higher_is_better=False,
            note=f"mavreg fly barrel_roll.yaml --lockstep, {name} caches ({runs}new and old code in turn): "
            f"wall time to the first line printed; baseline: the code at {BASE_COMMIT} (before the "
            "start's stage lines) on caches of its own")
        figs[f"first_run_s.{name}_armed"] = figure(
            now["armed_s"], before.get("armed_s"), target=10.0 if name == "warm" else None, unit="s",
            higher_is_better=False,
            note=f"the same flights, {name}: wall time to the 'vehicle armed' event; baseline: the code at "
            f"{BASE_COMMIT}")
    return figs


if __name__ == "__main__":
    from benchmarks.report import standalone
    standalone(run_first_run, __doc__)
