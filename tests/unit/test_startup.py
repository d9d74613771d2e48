"""The start says what it does before doing it (mavreg.daemon.jobs.startup, mavreg fly's first line),
by the order of events and an injected clock, never by wall-clock limits."""
from __future__ import annotations

import asyncio
import threading
import types

import pytest

from mavreg import accel
from mavreg.config.paths import maneuver_file
from mavreg.daemon.jobs import startup
from mavreg.daemon.jobs.startup import PreflightWatch, compile_kernels, preflight_wait
from mavreg.planning.cache import PlanCache
from mavreg.planning.plan_io import text_in_cache
from mavreg.progress import Progress


def test_the_compile_is_announced_with_an_estimate_before_it_starts(monkeypatch):
    monkeypatch.setattr(startup, "kernels_cold", lambda: True)
    monkeypatch.setattr(startup, "cpu_speed_factor", lambda: 2.0)
    lines: list[str] = []
    seen_when_compiling: list[str] = []
    progress = Progress(lines.append, every_s=1e6)
    asyncio.run(compile_kernels(progress, lambda: seen_when_compiling.extend(lines)))
    assert len(seen_when_compiling) == 1
    assert seen_when_compiling[0].endswith(
        "compiling the controller's kernels (first run on this machine, about 65 s) ...")
    assert lines[-1].split("setup: ")[1].startswith("compiled the controller's kernels in ")


def test_a_warm_cache_loads_without_a_line_and_an_error_reaches_the_caller(monkeypatch):
    monkeypatch.setattr(startup, "kernels_cold", lambda: False)
    lines: list[str] = []
    progress = Progress(lines.append, every_s=1e6)
    asyncio.run(compile_kernels(progress, lambda: None))
    assert lines == []

    def broken():
        raise RuntimeError("no LLVM")
    with pytest.raises(RuntimeError, match="no LLVM"):
        asyncio.run(compile_kernels(progress, broken))


@pytest.mark.parametrize("heard, sample, armed, queued, words", [
    (False, False, None, True, "no message from it yet"),
    (True, False, False, True, "position estimate"),
    (True, True, False, True, "to arm"),
    (True, True, False, False, None),           # serve, no upload yet: the endpoint says that
    (True, True, True, True, None),
])
def test_what_the_preflight_waits_for(heard, sample, armed, queued, words):
    what = preflight_wait(heard, sample, armed, queued)
    assert (what is None) if words is None else (words in what)


def test_a_wait_is_said_when_it_lasts_and_again_every_period():
    said: list[str] = []
    watch = PreflightWatch(said.append, late_s=1.0, every_s=10.0)
    watch.update("waiting for A", 0.0)
    watch.update("waiting for A", 0.5)
    watch.update(None, 0.8)                      # over before it mattered: nothing said
    assert said == []
    watch.update("waiting for B", 1.0)
    watch.update("waiting for B", 2.0)
    watch.update("waiting for B", 2.1)
    watch.update("waiting for B", 12.0)
    assert said == ["waiting for B", "waiting for B (11 s so far)"]


def _fake_kernel(load_index):
    file = types.SimpleNamespace(_load_index=load_index)
    return types.SimpleNamespace(dispatcher=types.SimpleNamespace(_cache=types.SimpleNamespace(_cache_file=file)))


def test_kernel_cached_reads_the_index_without_compiling(monkeypatch):
    monkeypatch.setattr(accel, "ACCELERATED", True)
    monkeypatch.setattr(accel, "materialize", lambda: None)
    assert accel.kernel_cached(_fake_kernel(lambda: {"sig": 1})) is True
    assert accel.kernel_cached(_fake_kernel(lambda: {})) is False         # missing or stale

    def unreadable():
        raise EOFError
    assert accel.kernel_cached(_fake_kernel(unreadable)) is False
    assert accel.kernel_cached(types.SimpleNamespace()) is None           # another layout
    monkeypatch.setattr(accel, "ACCELERATED", False)
    assert accel.kernel_cached(_fake_kernel(lambda: {"sig": 1})) is None


def test_the_plan_cache_tells_a_hit_before_planning(tmp_path, monkeypatch, vehicle, realistic_controller):
    cache = PlanCache(tmp_path)
    assert not cache.has(("a", 1))
    cache.get_or_plan(("a", 1), lambda: "entry")
    assert cache.has(("a", 1)) and not cache.has(("a", 2))
    text = maneuver_file("barrel_roll").read_text()
    monkeypatch.setenv("MAVREG_PLAN_CACHE", str(tmp_path / "plans"))
    assert text_in_cache(text, "x.yaml", vehicle, realistic_controller) is False
    assert text_in_cache("kind: [", "bad.yaml", vehicle, realistic_controller) is None
    monkeypatch.setenv("MAVREG_PLAN_CACHE", "off")
    assert text_in_cache(text, "x.yaml", vehicle, realistic_controller) is None


def test_fly_says_its_first_line_before_the_daemon_is_imported_or_started(monkeypatch, capsys, tmp_path):
    from mavreg.cli.main import main
    from mavreg.daemon.jobs import fly as fly_module
    seen = {}

    def fake_fly(opts):
        seen["err"] = capsys.readouterr().err
        seen["progress"] = opts.progress
        return 0
    monkeypatch.setattr(fly_module, "fly", fake_fly)
    out = tmp_path / "out"
    assert main(["fly", str(maneuver_file("barrel_roll")), "--lockstep", "--out", str(out)]) == 0
    first = seen["err"].splitlines()
    assert len(first) == 1 and first[0].endswith(
        f"setup: starting: barrel_roll.yaml on the bundled emulator (lockstep); outputs in {out}/")
    assert seen["progress"] is not None         # the daemon goes on with the same clock


@pytest.mark.parametrize("argv", [["fly", str(maneuver_file("barrel_roll")), "--gcs", "nonsense"],
                                  ["fly", str(maneuver_file("barrel_roll")), "--vehicle-params", "{file}"],
                                  ["serve", "--gcs", "nonsense"]])
def test_a_refusal_is_one_line_with_no_starting_line_before_it(argv, capsys, tmp_path):
    from mavreg.cli.main import main
    from mavreg.config.paths import DEFAULT_VEHICLE
    file = tmp_path / "vehicle.yaml"                    # a vehicle file with an unknown dialect
    file.write_text(DEFAULT_VEHICLE.read_text() + "\ndialect: inav\n")
    status = main([a.format(file=file) for a in argv] + ["--out", str(tmp_path / "o")] * (argv[0] == "fly"))
    err = capsys.readouterr().err.splitlines()
    assert status == 2 and len(err) == 1 and err[0].startswith(f"mavreg {argv[0]}: error: "), err


def test_the_checks_before_the_first_line_import_no_mavlink_scipy_or_numba(tmp_path):
    """What fly and serve check before their first line is light (a fresh interpreter's
    modules), so that the line comes within a second of the command, not after the imports."""
    import json
    import subprocess
    import sys
    from tests.helpers.repo import ROOT
    probe = (
        "import json, sys\n"
        "from mavreg.cli import fly_cmd, serve_cmd\n"
        "from mavreg.cli.main import build_parser\n"
        "parser = build_parser()[0]\n"
        "heavy = []\n"
        "class Stop(Exception): pass\n"
        "def first_line(text):\n"
        "    heavy.append(sorted({k.split('.')[0] for k in sys.modules} & {'pymavlink', 'scipy', 'numba'}))\n"
        "    raise Stop\n"
        "import mavreg.progress as p\n"
        "p.Progress.line = lambda self, text: first_line(text)\n"
        "for argv in (['fly', sys.argv[1], '--out', sys.argv[2]], ['serve']):\n"
        "    try:\n"
        "        (fly_cmd if argv[0] == 'fly' else serve_cmd).run(parser.parse_args(argv))\n"
        "    except Stop:\n"
        "        pass\n"
        "print(json.dumps(heavy))\n")
    out = subprocess.run([sys.executable, "-c", probe, str(maneuver_file("barrel_roll")), str(tmp_path / "o")],
                         capture_output=True, text=True, timeout=120, cwd=ROOT, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == [[], []], out.stderr


def test_plan_and_simulate_say_a_cache_miss_before_planning_on_a_terminal(monkeypatch, capsys, tmp_path, vehicle,
                                                                         realistic_controller):
    import sys

    from mavreg.cli import plan_progress
    from mavreg.config.maneuver import load_maneuver
    from mavreg.planning import plan_io
    seen = []
    monkeypatch.setattr(plan_io, "plan_cached", lambda *a: seen.append(capsys.readouterr().err) or "plan")
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    monkeypatch.setenv("MAVREG_PLAN_CACHE", str(tmp_path))
    spec = load_maneuver(maneuver_file("barrel_roll"))
    assert plan_progress.plan_saying("plan", spec, vehicle, realistic_controller) == "plan"
    assert seen[0].startswith("mavreg plan ") and seen[0].rstrip().endswith(
        "planning barrel_roll (not in the plan cache yet) ...")
    assert "planned barrel_roll in " in capsys.readouterr().err
    monkeypatch.setenv("MAVREG_PLAN_CACHE", "off")          # no cache: quick unless it lasts
    plan_progress.plan_saying("simulate", spec, vehicle, realistic_controller)
    assert seen[1] == "" and capsys.readouterr().err == ""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)    # piped: an error stays one line
    monkeypatch.setenv("MAVREG_PLAN_CACHE", str(tmp_path / "other"))
    plan_progress.plan_saying("plan", spec, vehicle, realistic_controller)
    assert capsys.readouterr().err == ""


class _FakePool:
    """The planner worker, answering at once; it notes what had been said when it was asked."""

    def __init__(self, log: list, result):
        self.log, self.result, self.controller, self.asked_after = log, result, None, None

    async def warm_up(self):
        return None

    async def plan(self, text, source):
        self.asked_after = list(self.log)
        return self.result


def _daemon_starting(monkeypatch, result, compile_gate: threading.Event | None = None):

    from mavreg.daemon.jobs import app
    from mavreg.daemon.jobs.app import Daemon, DaemonConfig
    from mavreg.daemon.flight.phases import SupervisorParams
    from tests.helpers.supervisor_harness import CONTROLLER, VEHICLE, FakeRegulator
    order: list[str] = []
    lines: list[str] = []

    def fake_compile(*args):
        if compile_gate is not None:
            compile_gate.wait(60.0)
        order.append("compiled")
    monkeypatch.setattr(app, "warm_daemon_kernels", fake_compile)
    monkeypatch.setattr(app, "text_in_cache", lambda *a: False)
    monkeypatch.setattr(startup, "kernels_cold", lambda: False)
    cfg = DaemonConfig("udpout:127.0.0.1:1", CONTROLLER, None, None, SupervisorParams())
    d = Daemon(cfg, VEHICLE, FakeRegulator, log=lines.append)
    d.pool = _FakePool(lines, result)
    real_offer = d.supervisor.offer_plan
    monkeypatch.setattr(d.supervisor, "offer_plan", lambda *a: (order.append("queued"), real_offer(*a))[1])
    return d, order, lines


def test_the_daemon_says_planning_before_it_plans_and_queues_only_once_compiled(monkeypatch):
    from mavreg.daemon.jobs.planner_pool import PlanResult
    from tests.helpers.supervisor_harness import FakePlan
    d, order, lines = _daemon_starting(monkeypatch, PlanResult(FakePlan()))
    asyncio.run(d._start([("kind: maneuver", "some/dir/line.yaml")]))
    assert d.pool.asked_after[-1].endswith("setup: planning line.yaml (not in the plan cache yet) ...")
    assert order == ["compiled", "queued"]
    assert any("setup: planned line.yaml in " in line for line in lines)


def test_a_refused_maneuver_ends_the_start_without_waiting_for_the_compile(monkeypatch):
    from mavreg.daemon.jobs.app import _InitialRejected
    from mavreg.daemon.jobs.planner_pool import PlanResult
    gate = threading.Event()
    d, order, _ = _daemon_starting(monkeypatch, PlanResult(None, "line.yaml: too fast", 1), gate)
    try:
        with pytest.raises(_InitialRejected, match="too fast"):
            asyncio.run(d._start([("kind: maneuver", "line.yaml")]))
        assert order == []                      # the compile was still under way
    finally:
        gate.set()
