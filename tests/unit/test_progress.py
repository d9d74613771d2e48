"""mavreg.progress: stage lines said before the stage's work, on an injected clock."""
from __future__ import annotations

import threading

import pytest

from mavreg.progress import REFERENCE_LOOP_S, Progress, cpu_speed_factor


class FakeClock:
    def __init__(self):
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def _progress(**kw):
    lines: list[str] = []
    clock = FakeClock()
    return Progress(lines.append, clock, **kw), lines, clock


def test_a_line_has_the_daemon_event_format_with_the_time_since_the_start():
    p, lines, clock = _progress()
    clock.t += 1.25
    p.line("hello")
    assert lines == [f"daemon    1.250 s  {'':20s} [start] setup: hello"]


def test_a_tagged_progress_writes_plain_lines_and_quiet_writes_none():
    p, lines, clock = _progress(tag="mavreg warm-up")
    clock.t += 2.0
    p.line("x")
    assert lines == ["mavreg warm-up    2.0 s  x"]
    q, quiet_lines, _ = _progress(quiet=True)
    q.line("x")
    with q.stage("a", "b"):
        pass
    assert quiet_lines == []


def test_an_announced_stage_is_said_before_its_work_and_done_with_its_duration():
    p, lines, clock = _progress(every_s=1e6)
    seen_by_body = []
    with p.stage("compiling", "compiled"):
        seen_by_body.extend(lines)       # what a user saw when the work began
        clock.t += 3.0
    assert seen_by_body == [lines[0]] and lines[0].endswith("setup: compiling ...")
    assert lines[1].endswith("setup: compiled in 3.0 s")
    assert p.stages == [("compiled", 3.0)]


def test_a_quick_unannounced_stage_says_nothing():
    p, lines, clock = _progress()
    with p.stage("loading", "loaded", announce=False, late_s=1e6):
        clock.t += 0.2
    assert lines == [] and p.stages == [("loaded", pytest.approx(0.2))]


def test_an_unannounced_stage_that_lasts_is_said_then_done():
    p, lines, clock = _progress(every_s=1e6)
    said = threading.Event()
    p.write = lambda line: (lines.append(line), said.set())
    with p.stage("loading", "loaded", announce=False, late_s=0.001):
        assert said.wait(30.0)           # the repeating thread said it while the work went on
        clock.t += 5.0
    assert lines[0].endswith("setup: loading ...") and lines[-1].endswith("setup: loaded in 5.0 s")


def test_a_long_stage_is_said_again_while_it_lasts():
    p, lines, clock = _progress(every_s=0.001)
    again = threading.Event()
    p.write = lambda line: (lines.append(line), "(12 s so far)" in line and again.set())
    with p.stage("planning x", "planned x"):
        clock.t += 12.0
        assert again.wait(30.0)
    assert any(line.endswith("setup: planning x (12 s so far)") for line in lines)


def test_end_is_idempotent_and_an_error_in_the_stage_propagates():
    p, lines, clock = _progress(every_s=1e6)
    stage = p.stage("a", "b").begin()
    stage.end()
    stage.end()
    assert len(lines) == 2
    try:
        with p.stage("c", "d"):
            raise KeyError("x")
    except KeyError:
        pass
    else:
        raise AssertionError("the error was swallowed")


def test_the_cpu_speed_factor_compares_the_median_loop_with_the_reference():
    ref = REFERENCE_LOOP_S / 10                                # 100,000 iterations
    ticks = iter([0.0, ref, 1.0, 1.0 + 2 * ref, 2.0, 2.0 + 3 * ref])     # 1x, 2x, 3x the reference
    assert abs(cpu_speed_factor(100_000, lambda: next(ticks)) - 2.0) < 1e-6
    fast = iter([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert cpu_speed_factor(100_000, lambda: next(fast)) == 0.25
