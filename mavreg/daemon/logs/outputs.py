"""The files a flight writes, and what a write error does to them: never the flight.

A full disk (``ENOSPC``), a quota (``EDQUOT``), a failing disk (``EIO``) or a file made
unwritable while the daemon flies turn up as an ``OSError`` in whichever writer meets them
first. None of the daemon's files steers the vehicle, so each writer stops writing the file
that failed, says so once in one line (what, which file, why, and what goes on), and the
flight goes on and lands; what the file would have told the user reaches them another way
(the summary printed when ``summary.json`` cannot be written; the outcome line and the exit
status in any case).

The files: the ``.tlog`` (:mod:`.tlog`, written while flying), the signing state
(:mod:`mavreg.transport.signing`, every 10 s and at the end), and after the flight the
controller log (:mod:`.ctrllog`), ``summary.json`` and ``flight.png`` (:mod:`.fly`).
"""
from __future__ import annotations

import errno
from pathlib import Path
from typing import Callable

from ...errors import one_line

__all__ = ["stopped_line", "write_or_say"]


def stopped_line(what: str, path, exc: OSError, goes_on: str) -> str:
    """The one line a writer says when it stops: ``WHAT: stopped writing PATH: [Errno N]
    reason; GOES_ON`` (the errno's number and name, then the system's wording)."""
    code = f"[Errno {exc.errno} {errno.errorcode.get(exc.errno, '?')}] " if exc.errno else ""
    reason = exc.strerror or one_line(exc)
    return f"{what}: stopped writing {Path(path)}: {code}{reason}; {goes_on}"


def write_or_say(what: str, path, write: Callable[[], object], log: Callable[[str], None],
                 goes_on: str) -> bool:
    """``write()``; on an ``OSError`` the line of :func:`stopped_line` is logged once, the
    partial file is removed where it can be, and False is returned (True when written)."""
    try:
        write()
        return True
    except OSError as exc:
        log(stopped_line(what, path, exc, goes_on))
        try:
            p = Path(path)
            if p.is_file() and not p.is_symlink():
                p.unlink()          # a truncated npz or json is worse than none
        except OSError:
            pass
        return False
