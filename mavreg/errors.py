"""Errors a user can cause, and the exit status each gives on the command line.

Every command of ``mavreg`` ends with one of these statuses (:data:`EXIT_STATUS_TEXT`
is the text of each command's ``--help``; docs/reliability.md has the cases tested):

====  =====================================================================================
0     done: planned feasible, flown and landed, identified, ...
1     the input was good and the answer is no: an infeasible maneuver, a failed flight, a
      rejected upload, a run that diverged
2     bad input: an option, a file (missing, unreadable, a directory, not UTF-8, not
      writable), a key or a value in a file
70    a bug in mavreg (an exception nobody anticipated): its traceback is printed with a
      line asking to report it (``EX_SOFTWARE`` of BSD's sysexits.h)
130   interrupted (Ctrl-C)
141   standard output closed by its reader (``mavreg plan x.yaml | head -1``)
====  =====================================================================================

Which exceptions are anticipated is said here, explicitly, by :func:`exit_status_of`:

- :class:`UserError` and its subclasses carry their own ``exit_status``: :class:`UsageError`
  (2) for options and files, :class:`ManeuverError` (1) for a maneuver that loads but cannot
  be flown;
- exceptions of other modules that mean "the user's input is at fault" are registered by
  qualified name in :data:`REGISTERED` (the loader's ``ConfigError``, ``identify``'s
  ``IdentifyError``), so that neither module has to import this one;
- an :class:`OSError` (a file that is missing, a directory, unreadable, not writable; a
  socket nobody listens on) is the environment's answer to the user's input: 2.

Anything else, ``ValueError`` included, is a bug and shows as one.
"""
from __future__ import annotations

import os

from .config.loader import ConfigError

__all__ = ["ConfigError", "UserError", "UsageError", "ManeuverError", "exit_status_of", "one_line",
           "EXIT_OK", "EXIT_FAILED", "EXIT_USAGE", "EXIT_BUG", "EXIT_STATUS_TEXT", "REGISTERED"]

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_BUG = 70
"""An unexpected exception: a bug to report (``os.EX_SOFTWARE``)."""

EXIT_STATUS_TEXT = """\
exit status (every mavreg command; docs/reliability.md):
  0    done (feasible, flown and landed, identified ...)
  1    good input, negative answer: infeasible maneuver, failed flight, rejected upload
  2    bad input: an option, a file (missing, unreadable, not writable), a key or value
  70   a bug in mavreg: a traceback and a request to report it
  130  interrupted (Ctrl-C); 141 output pipe closed
"""

MAX_MESSAGE_CHARS = 400
"""A user error's line is cut to this many characters (a hostile file cannot make it long)."""


class UserError(Exception):
    """An anticipated error: the user's input (or what it points at) is at fault.

    The command line prints ``str(err)`` on one line and exits ``exit_status``.
    """

    exit_status = EXIT_USAGE


class UsageError(UserError, ValueError):
    """A bad option, a bad path, a file that cannot be read or written: exit 2.

    A ``ValueError`` too, so that callers that caught ``ValueError`` still do.
    """

    exit_status = EXIT_USAGE


class ManeuverError(UserError, ValueError):
    """A maneuver that loads but cannot be flown: infeasible, or ill-formed geometry (exit 1).

    The message is one line and says where (segment, arc length) and by how much.
    """

    exit_status = EXIT_FAILED


REGISTERED: dict[str, int] = {
    "mavreg.config.loader.ConfigError": EXIT_USAGE,
    "mavreg.identify.regressors.IdentifyError": EXIT_USAGE,
    "mavreg.transport.signing.SigningError": EXIT_USAGE,
}
"""Anticipated exceptions defined elsewhere, by ``module.QualName``, and their status
(a subclass of one is anticipated too)."""


def exit_status_of(exc: BaseException) -> int | None:
    """The exit status of an anticipated exception, or None for a bug.

    Parameters
    ----------
    exc : BaseException
        The exception a command raised.

    Returns
    -------
    int or None
        ``exc.exit_status`` for a :class:`UserError`, the registered status for a class in
        :data:`REGISTERED` (or a subclass), :data:`EXIT_USAGE` for an ``OSError``; None
        otherwise.
    """
    if isinstance(exc, UserError):
        return int(exc.exit_status)
    for cls in type(exc).__mro__:
        status = REGISTERED.get(f"{cls.__module__}.{cls.__qualname__}")
        if status is not None:
            return status
    if isinstance(exc, OSError):
        return EXIT_USAGE
    return None


def one_line(exc: BaseException, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``exc``'s message on one line of at most ``limit`` characters.

    An ``OSError`` reads ``PATH: reason`` (``[Errno 2] No such file or directory:
    'x'`` is Python's wording, not a user's).
    """
    if isinstance(exc, OSError) and exc.strerror:
        names = [n for n in (exc.filename, exc.filename2) if n is not None]
        text = ": ".join([*(os.fsdecode(n) for n in names), exc.strerror])
    else:
        text = str(exc) or exc.__class__.__name__
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."
