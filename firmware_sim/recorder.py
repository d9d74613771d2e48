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
``meta_json``        ()        str: JSON with vehicle parameters, rates, seed, world, stop reason
===================  ========  ====================================================

and the state estimate the vehicle published (M rows, one per control period, whether
or not the link then lost it; the truth itself in the ideal world):

=============================  ======  ================================================
``estimate_t_s``               (M,)    its time stamp (``time_boot_ms / 1000``); it
                                       describes the true state of ``t - latency``
``estimate_position_ned_m``    (M, 3)  LOCAL_POSITION_NED x, y, z
``estimate_velocity_ned_m_s``  (M, 3)  LOCAL_POSITION_NED vx, vy, vz
``estimate_quat``              (M, 4)  ATTITUDE_QUATERNION q1..q4 (w, x, y, z)
``estimate_rates_rad_s``       (M, 3)  rollspeed, pitchspeed, yawspeed
=============================  ======  ================================================

plus whatever the emulator put in :attr:`Recorder.arrays` (the true airframe's
``airframe_*`` fields: :func:`firmware_sim.mismatch.airframe_arrays`).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["Recorder", "COLUMNS"]

COLUMNS = 1 + 3 + 4 + 3 + 3 + 4 + 4 + 1 + 1 + 1
ESTIMATE_COLUMNS = 1 + 3 + 3 + 4 + 3
_CHUNK = 8192


class Recorder:
    """Rows are written into preallocated float64 chunks; :meth:`save` assembles them."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._chunks: list[np.ndarray] = []
        self._cur = np.empty((_CHUNK, COLUMNS))
        self._i = 0
        self._est_chunks: list[np.ndarray] = []
        self._est = np.empty((_CHUNK, ESTIMATE_COLUMNS))
        self._est_i = 0
        self.meta: dict = {}
        self.arrays: dict = {}
        """Further named arrays written as they are (fixed at start-up: the true airframe)."""

    def record(self, t_s: float, s, cmd_n, applied_n, armed: bool, mode: int, on_ground: bool):
        """Append one row: time, 13-state, commanded and applied thrusts, flags."""
        if self._i == _CHUNK:
            self._chunks.append(self._cur)
            self._cur = np.empty((_CHUNK, COLUMNS))
            self._i = 0
        self._cur[self._i] = (t_s, *s, *cmd_n, *applied_n, armed, mode, on_ground)
        self._i += 1

    def record_estimate(self, t_s: float, position, velocity, quat, rates) -> None:
        """Append the estimate published at ``t_s`` (one row per control period)."""
        if self._est_i == _CHUNK:
            self._est_chunks.append(self._est)
            self._est = np.empty((_CHUNK, ESTIMATE_COLUMNS))
            self._est_i = 0
        self._est[self._est_i] = (t_s, *position, *velocity, *quat, *rates)
        self._est_i += 1

    def data(self) -> np.ndarray:
        """All rows so far, shape (N, COLUMNS)."""
        return np.concatenate(self._chunks + [self._cur[: self._i]], axis=0)

    def estimate_data(self) -> np.ndarray:
        """All estimate rows so far, shape (M, ESTIMATE_COLUMNS)."""
        return np.concatenate(self._est_chunks + [self._est[: self._est_i]], axis=0)

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
        e = self.estimate_data()
        out.update(estimate_t_s=e[:, 0], estimate_position_ned_m=e[:, 1:4],
                   estimate_velocity_ned_m_s=e[:, 4:7], estimate_quat=e[:, 7:11],
                   estimate_rates_rad_s=e[:, 11:14])
        out.update(self.arrays)
        tmp = self.path.with_name(self.path.name + ".tmp.npz")
        np.savez_compressed(tmp, **out)
        tmp.replace(self.path)
        return self.path
