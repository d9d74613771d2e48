"""Children die with their parent: the parent-death signal, the getppid watcher, the exec wrapper.

Each test starts a parent process that starts a child, SIGKILLs the parent and polls /proc
(at most 10 s) until the child is gone.
"""
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from harness.processes import start_time, survivors

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")

# The parent prints its child's pid, then sleeps until killed.
_PARENT = textwrap.dedent("""
    import subprocess, sys, time
    child = subprocess.Popen({child})
    print(child.pid, flush=True)
    time.sleep(600)
""")


def _orphan_after_parent_killed(child_expr: str, bound_s: float = 10.0) -> list[int]:
    parent = subprocess.Popen([sys.executable, "-c", _PARENT.format(child=child_expr)],
                              stdout=subprocess.PIPE, text=True)
    try:
        child = int(parent.stdout.readline())
        t0 = start_time(child)
        assert t0 is not None
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(10)
        left = survivors({child: t0}, bound_s)
    finally:
        parent.kill()
        parent.wait()
        parent.stdout.close()
    for pid in left:   # do not leave it behind when the test fails
        os.kill(pid, signal.SIGKILL)
    return left


_SLEEPER = [sys.executable, "-c", "import time; time.sleep(600)"]


def test_a_plain_child_outlives_its_killed_parent():
    """The reference: without lifeline a child survives (so the other tests can fail)."""
    assert _orphan_after_parent_killed(repr(_SLEEPER), bound_s=1.0) != []


def test_exec_wrapper_child_dies_with_its_parent():
    expr = f"__import__('mavreg.daemon.jobs.lifeline', fromlist=['x']).wrap_command({_SLEEPER!r})"
    assert _orphan_after_parent_killed(expr) == []


def test_getppid_watcher_alone_ends_the_child():
    """The portable fallback, without the parent-death signal."""
    code = "import time; from mavreg.daemon.jobs.lifeline import watch_parent; watch_parent(%d); time.sleep(600)"
    # the parent's pid is given, not read by the child: the parent may be dead before it looks
    expr = f"[{sys.executable!r}, '-c', {code!r} % __import__('os').getpid()]"
    assert _orphan_after_parent_killed(expr) == []


def test_wrapper_refuses_a_dead_parent_and_bad_usage():
    # parent pid that is not ours: the child exits at once instead of running the program
    r = subprocess.run([sys.executable, "-m", "mavreg.daemon.jobs.lifeline", "1", *_SLEEPER], timeout=30)
    assert r.returncode == 1
    r = subprocess.run([sys.executable, "-m", "mavreg.daemon.jobs.lifeline", "x"], capture_output=True,
                       text=True, timeout=30)
    assert r.returncode == 2 and "usage" in r.stderr
