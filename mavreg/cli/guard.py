"""Exit cleanly from a closed pipe or a Ctrl-C: one line, a conventional status, no traceback.

``mavreg plan x.yaml | head -1`` closes the pipe while mavreg still writes; Python then
raises ``BrokenPipeError`` from the write, or from the final flush at interpreter exit,
where it can only print "Exception ignored". :func:`run_guarded` flushes inside the guard,
and on a broken pipe points standard output at ``/dev/null`` so nothing is written after,
and returns 141 (128 + SIGPIPE, what a shell reports for a command that the pipe stopped).
A Ctrl-C anywhere (also while modules load or arguments parse) returns 130 (128 + SIGINT)
after one line on standard error.
"""
from __future__ import annotations

import os
import signal
import sys
from typing import Callable

__all__ = ["run_guarded", "EXIT_BROKEN_PIPE", "EXIT_INTERRUPTED"]

EXIT_BROKEN_PIPE = 128 + signal.SIGPIPE
EXIT_INTERRUPTED = 128 + signal.SIGINT


def _silence_stdout() -> None:
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def run_guarded(prog: str, body: Callable[[], int]) -> int:
    """``body()``'s status, or 141 on a closed pipe, 130 on Ctrl-C."""
    try:
        code = body()
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        try:
            print(f"{prog}: interrupted", file=sys.stderr, flush=True)
        except (BrokenPipeError, OSError):
            pass
        return EXIT_INTERRUPTED
