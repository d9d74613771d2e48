"""Assemble complete state samples from the vehicle's telemetry (sans-I/O).

A control period of the vehicle sends ATTITUDE_QUATERNION (and/or ATTITUDE) and
LOCAL_POSITION_NED with the same ``time_boot_ms``. A :class:`StateSample` is produced only
when an attitude part and a position part of the **same** ``time_boot_ms`` are both in
hand; parts of different times are never mixed. A part not newer than the last complete
sample is late and dropped; unmatched parts wait (a few per kind) for their partner,
and completing time t discards every unmatched part older than t.

Attitude: the quaternion (w, x, y, z; body FRD to NED) when the vehicle sends one.
Once any ATTITUDE_QUATERNION has been seen, ATTITUDE is ignored. On Euler angles alone,
a sample whose pitch is within ``euler_pitch_limit_rad`` of +-90 deg is refused
(roll and yaw are ill-defined there).

Body velocity is ``R^T v_NED``; body rates are the messages' rollspeed, pitchspeed,
yawspeed (p, q, r), as PX4 sends them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..model.rotation import matrix_to_rpy, quat_to_matrix, rpy_to_matrix

__all__ = ["StateSample", "StateAssembler", "StateCounters"]


@dataclass(frozen=True)
class StateSample:
    """One complete, single-time state of the vehicle."""

    time_boot_ms: int
    x: np.ndarray
    """(12,) = (p NED, roll pitch yaw, v_body, w_body), SI."""
    rotation: np.ndarray
    """(3, 3) body-to-NED rotation."""
    from_quaternion: bool

    @property
    def time_s(self) -> float:
        return self.time_boot_ms / 1000.0

    @property
    def velocity_ned_m_s(self) -> np.ndarray:
        return self.rotation @ self.x[6:9]


@dataclass
class StateCounters:
    """What the assembler threw away, by reason."""

    late: int = 0
    unmatched: int = 0
    euler_near_vertical: int = 0
    non_finite: int = 0
    euler_ignored: int = 0


@dataclass
class StateAssembler:
    """Pairs attitude and position parts by ``time_boot_ms``."""

    euler_pitch_limit_rad: float = np.deg2rad(75.0)
    max_pending: int = 4
    """Unmatched parts kept per kind (newest times) while waiting for their partner."""
    counters: StateCounters = field(default_factory=StateCounters)

    def __post_init__(self):
        self._att: dict[int, tuple[np.ndarray, np.ndarray, bool]] = {}
        self._pos: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._last_ms = -1
        self.quaternion_seen = False

    @property
    def last_time_boot_ms(self) -> int:
        """``time_boot_ms`` of the last complete sample (-1 before the first)."""
        return self._last_ms

    def add(self, msg) -> StateSample | None:
        """Feed one decoded message; return a sample when it completes one, else None."""
        mtype = msg.get_type()
        if mtype == "ATTITUDE_QUATERNION":
            self.quaternion_seen = True
            q = np.array([msg.q1, msg.q2, msg.q3, msg.q4], dtype=float)
            rates = np.array([msg.rollspeed, msg.pitchspeed, msg.yawspeed], dtype=float)
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(rates))) or np.linalg.norm(q) < 0.5:
                self.counters.non_finite += 1
                return None
            return self._add_att(int(msg.time_boot_ms), quat_to_matrix(q), rates, True)
        if mtype == "ATTITUDE":
            if self.quaternion_seen:
                self.counters.euler_ignored += 1
                return None
            rpy = np.array([msg.roll, msg.pitch, msg.yaw], dtype=float)
            rates = np.array([msg.rollspeed, msg.pitchspeed, msg.yawspeed], dtype=float)
            if not (np.all(np.isfinite(rpy)) and np.all(np.isfinite(rates))):
                self.counters.non_finite += 1
                return None
            if abs(rpy[1]) > self.euler_pitch_limit_rad:
                self.counters.euler_near_vertical += 1
                return None
            return self._add_att(int(msg.time_boot_ms), rpy_to_matrix(*rpy), rates, False)
        if mtype == "LOCAL_POSITION_NED":
            p = np.array([msg.x, msg.y, msg.z], dtype=float)
            v = np.array([msg.vx, msg.vy, msg.vz], dtype=float)
            if not (np.all(np.isfinite(p)) and np.all(np.isfinite(v))):
                self.counters.non_finite += 1
                return None
            return self._add(self._pos, int(msg.time_boot_ms), (p, v))
        return None

    def _add_att(self, t: int, R: np.ndarray, rates: np.ndarray, from_q: bool) -> StateSample | None:
        return self._add(self._att, t, (R, rates, from_q))

    def _add(self, parts: dict, t: int, value) -> StateSample | None:
        if t <= self._last_ms:
            self.counters.late += 1
            return None
        parts[t] = value
        while len(parts) > self.max_pending:
            del parts[min(parts)]
            self.counters.unmatched += 1
        if t not in self._att or t not in self._pos:
            return None
        R, rates, from_q = self._att[t]
        p, v_ned = self._pos[t]
        for d in (self._att, self._pos):
            for k in [k for k in d if k <= t]:
                if k < t:
                    self.counters.unmatched += 1
                del d[k]
        self._last_ms = t
        x = np.empty(12)
        x[0:3] = p
        x[3:6] = matrix_to_rpy(R)
        x[6:9] = R.T @ v_ned
        x[9:12] = rates
        return StateSample(t, x, R, from_q)
