"""Controller internals per control step (t, phase, s, w, u, rotor commands, state) in a compact npz.

Arrays of ``control.npz`` (N control steps, float32 unless said):

================  ========  ==============================================================
``t_s``           (N,)      vehicle time (time_boot_ms / 1000), float64
``phase``         (N,)      int8 code; ``phase_names`` (JSON list) gives the names
``s_m``           (N,)      arc length (NaN outside the maneuver)
``w``             (N, 11)   transverse coordinates (NaN outside the maneuver)
``u``             (N, 4)    commanded (f, g1, g2, g3), N and N m
``rotor_cmd_n``   (N, 4)    rotor forces asked by the controller, before clipping
``x``             (N, 12)   state used by the controller
``disturbance``   (N, 6)    observer estimate: c_xy, c_z (N s/m), force NED (N), thrust
                            scale (NaN without an observer; mavreg.control.estimation.disturbance)
``events_json``   ()        JSON list of the supervisor's events: ``time_s`` (vehicle time;
                            an event before the vehicle's first sample is counted back from
                            that sample on the daemon's clock, so it is negative or small;
                            null only if no sample ever came), ``daemon_time_s`` (seconds
                            since the daemon started), ``kind``, ``phase``, ``s_m``, ``detail``
================  ========  ==============================================================
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..flight.supervisor import PHASE_CODES, LogRecord

__all__ = ["ControlLog", "load_control_log", "decoded"]


class ControlLog:
    """Accumulates :class:`LogRecord` rows in memory (about 130 bytes per step)."""

    def __init__(self):
        self._rows: list[np.ndarray] = []
        self._phase: list[int] = []
        self._t: list[float] = []
        self.events: list = []
        self.clock_anchor: tuple[float, float] | None = None
        """(daemon s, vehicle s) at the vehicle's first sample (set by the daemon)."""

    def __len__(self) -> int:
        return len(self._t)

    def append(self, rec: LogRecord) -> None:
        self._t.append(rec.time_s)
        self._phase.append(PHASE_CODES[rec.phase])
        self._rows.append(np.concatenate([[rec.s_m], rec.w, rec.u, rec.rotor_cmd_n, rec.x,
                                          rec.disturbance]).astype(np.float32))

    def arrays(self) -> dict:
        rows = np.array(self._rows, dtype=np.float32).reshape(-1, 1 + 11 + 4 + 4 + 12 + 6)
        return {
            "t_s": np.array(self._t, dtype=np.float64),
            "phase": np.array(self._phase, dtype=np.int8),
            "phase_names": np.array(json.dumps(list(PHASE_CODES))),
            "s_m": rows[:, 0], "w": rows[:, 1:12], "u": rows[:, 12:16],
            "rotor_cmd_n": rows[:, 16:20], "x": rows[:, 20:32], "disturbance": rows[:, 32:38],
            "events_json": np.array(json.dumps([
                {"time_s": self._vehicle_time(e), "daemon_time_s": _num(e.daemon_s), "kind": e.kind,
                 "phase": e.phase, "s_m": _num(e.s_m), "detail": e.detail} for e in self.events])),
        }

    def _vehicle_time(self, e) -> float | None:
        """The event's vehicle time, or (before the first sample) counted back from it."""
        if math.isfinite(e.time_s):
            return e.time_s
        if self.clock_anchor is None or not math.isfinite(e.daemon_s):
            return None
        daemon_s, vehicle_s = self.clock_anchor
        return vehicle_s - (daemon_s - e.daemon_s)

    def save(self, path: str | Path, arrays: dict | None = None) -> Path:
        """Write the log (``arrays``: :meth:`arrays` already built) as a compressed npz.

        Raises
        ------
        OSError
            The file could not be written (a full disk); callers say so once
            (:func:`mavreg.daemon.logs.outputs.write_or_say`), the log stays in memory.
        """
        path = Path(path)
        np.savez_compressed(path, **(self.arrays() if arrays is None else arrays))
        return path


def _num(x: float) -> float | None:
    return x if math.isfinite(x) else None


def load_control_log(path: str | Path) -> dict:
    """The arrays of a saved log, with ``phase_names`` and ``events`` decoded."""
    with np.load(path) as z:
        return decoded({k: z[k] for k in z.files})


def decoded(arrays: dict) -> dict:
    """The arrays of a log (:meth:`ControlLog.arrays`, or as saved) with ``phase_names`` and
    ``events`` decoded: what :func:`load_control_log` returns, from memory when the file could
    not be written."""
    out = dict(arrays)
    out["phase_names"] = json.loads(str(out["phase_names"]))
    out["events"] = json.loads(str(out.pop("events_json")))
    return out
