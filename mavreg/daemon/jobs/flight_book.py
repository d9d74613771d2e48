"""The flights one daemon has flown: each flight's outcome, bounded, and its numbered logs.

``mavreg fly`` flies one flight; ``mavreg serve`` flies one after another until it is stopped
(a fresh :class:`~mavreg.daemon.flight.supervisor.Supervisor` for each, on the same link, endpoint
and planner worker). Each flight that ends leaves a :class:`FlightRecord` in the
:class:`FlightBook` (the endpoint's ``status`` shows the totals and the latest records), and
its ``.tlog`` and controller log, when asked for, are files of their own, numbered, of which
only the newest ``keep`` stay on disk (:class:`NumberedFiles`): a serve that runs for weeks
neither grows in memory nor fills its disk.

Pure bookkeeping: no sockets, no clock (the caller passes the times).
"""
from __future__ import annotations

import collections
import math
from dataclasses import asdict, dataclass
from pathlib import Path

from ..flight.phases import Phase
from ..flight.records import Outcome

__all__ = ["outcome", "FlightRecord", "FlightBook", "NumberedFiles"]

_EMULATOR_EXIT = {1: "internal error", 3: "crash", 4: "non-finite state", 5: "speed or body rate limit"}


def outcome(sup, emulator_code: int | None, timeout_s: float) -> Outcome | None:
    """None for a flight flown within its envelope and landed; else the cause.

    The supervisor's first violated bound wins; otherwise the emulator's exit (a crash the
    daemon did not see), a timeout, or a flight that ended without flying its maneuver.
    """
    if sup.failure is not None:
        return sup.failure
    nan = float("nan")
    t = sup.last_sample.time_s if sup.last_sample is not None else nan
    if emulator_code not in (None, 0):
        why = _EMULATOR_EXIT.get(emulator_code, "unknown")
        return Outcome("emulator_exit", sup.phase, t, nan, float(emulator_code), 0.0, "code",
                       f"the emulator stopped: {why} (exit {emulator_code})", "none")
    if not sup.finished:
        return Outcome("timeout", sup.phase, t, nan, timeout_s, timeout_s, "s",
                       f"the flight did not end within --timeout-s {timeout_s:g}",
                       "command stream stopped (vehicle failsafe)")
    if not sup.succeeded:
        return Outcome("not_flown", sup.phase, t, nan, nan, nan, "",
                       sup.reason or f"ended in phase {sup.phase} without flying the maneuver", "none")
    return None


@dataclass(frozen=True)
class FlightRecord:
    """One flight's outcome, as the endpoint's ``status`` and the log give it."""

    number: int
    """1 for the daemon's first flight."""
    result: str
    """``ok``; ``no_flight`` (it ended on the ground with nothing flown: a landing asked for
    before any upload); else the cause's bound (``impact``, ``link_lost``, ...)."""
    phase: str
    """The phase it ended in (``disarmed`` or ``aborted``)."""
    detail: str
    maneuvers: tuple[str, ...]
    recoveries: int
    touchdown_speed_m_s: float | None
    latency_ms: dict
    """Datagram-to-command latency over the flight (median, p99, samples)."""
    ended_daemon_s: float
    """When it ended, in seconds since the daemon started."""
    counters: dict
    """The supervisor's counters over the flight (samples, commands, gaps, ...)."""
    vehicle_span_s: tuple[float | None, float | None] = (None, None)
    """The vehicle's time of the flight's first and last sample (None: no sample)."""

    @classmethod
    def of(cls, number: int, sup, latency_ms: dict, ended_daemon_s: float,
           stopped: bool = False) -> "FlightRecord":
        """The record of ``sup``'s flight, ended (``stopped``: cut short by the daemon's stop)."""
        ctx = sup.ctx
        cause = outcome(sup, None, math.inf)
        if stopped and not sup.finished:
            result, detail = "stopped", f"the daemon stopped in phase {sup.phase}"
        elif cause is not None and cause.bound == "not_flown" and not ctx.maneuvers_done and ctx.failure is None \
                and sup.phase == Phase.DISARMED:
            result, detail = "no_flight", sup.reason or "nothing was flown"
        elif cause is None:
            result, detail = "ok", f"landed after {len(ctx.maneuvers_done)} maneuver(s)"
        else:
            result, detail = cause.bound, cause.line()
        td = ctx.landing.touchdown_speed_m_s
        return cls(number, result, str(sup.phase), detail, tuple(ctx.maneuvers_done), int(ctx.recovery.count),
                   None if td is None or not math.isfinite(td) else float(td), dict(latency_ms),
                   float(ended_daemon_s), dict(sup.counters.__dict__),
                   (ctx.heard.stream_start_vehicle_s, None if ctx.heard.last_sample is None else ctx.heard.last_sample.time_s))

    def line(self) -> str:
        td = "" if self.touchdown_speed_m_s is None else f", touchdown {self.touchdown_speed_m_s:.2f} m/s"
        return f"flight {self.number}: {self.result} ({self.detail}){td}"

    def as_dict(self) -> dict:
        d = asdict(self)
        d["maneuvers"] = list(self.maneuvers)
        d["vehicle_span_s"] = list(self.vehicle_span_s)
        return d


class FlightBook:
    """The outcomes of a daemon's flights: totals by result, and the newest ``keep`` records."""

    def __init__(self, keep: int = 50):
        self.count = 0
        self.by_result: collections.Counter = collections.Counter()
        self.records: collections.deque = collections.deque(maxlen=int(keep))

    def add(self, record: FlightRecord) -> None:
        self.count += 1
        self.by_result[record.result] += 1
        self.records.append(record)

    def status(self) -> dict:
        return {"flown": self.count, "by_result": dict(sorted(self.by_result.items())),
                "last": [r.as_dict() for r in self.records][-5:]}


class NumberedFiles:
    """A log file per flight: ``flight.tlog`` -> ``flight-0001.tlog``, ``flight-0002.tlog``, ...
    of which the newest ``keep`` stay (older ones are deleted as new ones begin).

    With ``numbered=False`` (a daemon of one flight), or a ``path`` that exists and is not a
    regular file (a device such as ``/dev/null``, a pipe), every flight's file is ``path`` itself.

    Examples
    --------
    >>> files = NumberedFiles(Path("/tmp/x/flight.tlog"), keep=2)
    >>> files.path(12).name
    'flight-0012.tlog'
    """

    def __init__(self, path: Path, keep: int = 20, numbered: bool = True):
        if keep < 1:
            raise ValueError(f"keep must be at least 1, got {keep}")
        self.base = Path(path)
        self.keep = int(keep)
        self.numbered = numbered and not (self.base.exists() and not self.base.is_file())

    def path(self, number: int) -> Path:
        if not self.numbered:
            return self.base
        return self.base.with_name(f"{self.base.stem}-{number:04d}{self.base.suffix}")

    def begin(self, number: int) -> Path:
        """The path of flight ``number``'s file; the file ``keep`` flights older is removed."""
        old = number - self.keep
        if self.numbered and old >= 1:
            try:
                self.path(old).unlink()
            except FileNotFoundError:
                pass
            except OSError:
                pass            # a file we cannot remove is left; the next flight tries its own
        return self.path(number)
