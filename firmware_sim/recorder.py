"""Flight recorder: the true state and rotor forces at every physics step, saved as npz.

Arrays in the file (N rows, one per physics step plus the initial state):

===================  ========  ====================================================
``t_s``              (N,)      simulation time (s)
``position_ned_m``   (N, 3)    position, NED
``quaternion_wxyz``  (N, 4)    attitude, body FRD to NED, scalar first
``velocity_ned_m_s`` (N, 3)    velocity, NED
``body_rates_rad_s`` (N, 3)    p, q, r (FRD)
``rotor_cmd_n``      (N, 4)    commanded rotor thrusts 1..4 (offboard target or stabilizer)
``rotor_applied_n``  (N, 4)    thrusts acting on the airframe (lag, noise, saturation)
``armed``            (N,)      bool
``custom_mode``      (N,)      uint32 HEARTBEAT custom_mode (see firmware_sim.modes)
``on_ground``        (N,)      bool, ground contact
``meta_json``        ()        str: JSON with vehicle parameters, rates, seed, stop reason
===================  ========  ====================================================
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["Recorder", "COLUMNS"]

COLUMNS = 1 + 3 + 4 + 3 + 3 + 4 + 4 + 1 + 1 + 1
_CHUNK = 8192


class Recorder:
    """Rows are written into preallocated float64 chunks; :meth:`save` assembles them."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._chunks: list[np.ndarray] = []
        self._cur = np.empty((_CHUNK, COLUMNS))
        self._i = 0
        self.meta: dict = {}

    def record(self, t_s: float, s, cmd_n, applied_n, armed: bool, mode: int, on_ground: bool):
        """Append one row: time, 13-state, commanded and applied thrusts, flags."""
        if self._i == _CHUNK:
            self._chunks.append(self._cur)
            self._cur = np.empty((_CHUNK, COLUMNS))
            self._i = 0
        self._cur[self._i] = (t_s, *s, *cmd_n, *applied_n, armed, mode, on_ground)
        self._i += 1

    def data(self) -> np.ndarray:
        """All rows so far, shape (N, COLUMNS)."""
        return np.concatenate(self._chunks + [self._cur[: self._i]], axis=0)

    def save(self) -> Path:
        """Write the npz file (atomic rename) and return its path."""
        d = self.data()
        out = {
            "t_s": d[:, 0],
            "position_ned_m": d[:, 1:4],
            "quaternion_wxyz": d[:, 4:8],
            "velocity_ned_m_s": d[:, 8:11],
            "body_rates_rad_s": d[:, 11:14],
            "rotor_cmd_n": d[:, 14:18],
            "rotor_applied_n": d[:, 18:22],
            "armed": d[:, 22].astype(bool),
            "custom_mode": d[:, 23].astype(np.uint32),
            "on_ground": d[:, 24].astype(bool),
            "meta_json": np.array(json.dumps(self.meta, default=str)),
        }
        tmp = self.path.with_name(self.path.name + ".tmp.npz")
        np.savez_compressed(tmp, **out)
        tmp.replace(self.path)
        return self.path
