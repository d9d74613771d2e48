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

Scalar math on floats (the same formulas as :func:`mavreg.model.rotation.quat_to_matrix`,
:func:`~mavreg.model.rotation.matrix_to_rpy` and :func:`~mavreg.model.rotation.rpy_to_matrix`;
``tests/unit/test_state.py`` checks the agreement): numpy on 3- and 4-element arrays cost
about 10 µs a message here, scalar math under 2.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

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
    position_ned: tuple = ()
    """The same numbers as plain floats, for the scalar checks: position (NED, m),"""
    velocity_ned: tuple = ()
    """velocity (NED, m/s, as the vehicle sent it),"""
    rows: tuple = ()
    """the rotation's rows,"""
    rates: tuple = ()
    """and the body rates (rad/s)."""

    @property
    def time_s(self) -> float:
        return self.time_boot_ms / 1000.0

    @property
    def velocity_ned_m_s(self) -> np.ndarray:
        if self.velocity_ned:
            return np.array(self.velocity_ned)
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
        self._att: dict[int, tuple] = {}      # time -> (R rows, rates, from quaternion)
        self._pos: dict[int, tuple] = {}      # time -> (p NED, v NED)
        self._last_ms = -1
        self.quaternion_seen = False

    def restart(self) -> None:
        """Forget the parts and the last sample's time (the vehicle rebooted: its clock starts
        again); the counters are kept."""
        self.__post_init__()

    @property
    def last_time_boot_ms(self) -> int:
        """``time_boot_ms`` of the last complete sample (-1 before the first)."""
        return self._last_ms

    def add(self, msg) -> StateSample | None:
        """Feed one decoded message; return a sample when it completes one, else None."""
        mtype = msg.get_type()
        if mtype == "ATTITUDE_QUATERNION":
            self.quaternion_seen = True
            w, x, y, z = float(msg.q1), float(msg.q2), float(msg.q3), float(msg.q4)
            rates = (float(msg.rollspeed), float(msg.pitchspeed), float(msg.yawspeed))
            n = math.sqrt(w * w + x * x + y * y + z * z)
            if not (math.isfinite(n) and math.isfinite(rates[0] + rates[1] + rates[2])) or n < 0.5:
                self.counters.non_finite += 1
                return None
            return self._add_att(int(msg.time_boot_ms), _quat_to_matrix(w / n, x / n, y / n, z / n), rates, True)
        if mtype == "ATTITUDE":
            if self.quaternion_seen:
                self.counters.euler_ignored += 1
                return None
            roll, pitch, yaw = float(msg.roll), float(msg.pitch), float(msg.yaw)
            rates = (float(msg.rollspeed), float(msg.pitchspeed), float(msg.yawspeed))
            if not (math.isfinite(roll + pitch + yaw) and math.isfinite(rates[0] + rates[1] + rates[2])):
                self.counters.non_finite += 1
                return None
            if abs(pitch) > self.euler_pitch_limit_rad:
                self.counters.euler_near_vertical += 1
                return None
            return self._add_att(int(msg.time_boot_ms), _rpy_to_matrix(roll, pitch, yaw), rates, False)
        if mtype == "LOCAL_POSITION_NED":
            p = (float(msg.x), float(msg.y), float(msg.z))
            v = (float(msg.vx), float(msg.vy), float(msg.vz))
            if not math.isfinite(p[0] + p[1] + p[2] + v[0] + v[1] + v[2]):
                self.counters.non_finite += 1
                return None
            return self._add(self._pos, int(msg.time_boot_ms), (p, v))
        return None

    def _add_att(self, t: int, R: tuple, rates: tuple, from_q: bool) -> StateSample | None:
        return self._add(self._att, t, (R, rates, from_q))

    def _add(self, parts: dict, t: int, value) -> StateSample | None:
        if t <= self._last_ms:
            self.counters.late += 1
            return None
        parts[t] = value
        while len(parts) > self.max_pending:
            del parts[min(parts)]
            self.counters.unmatched += 1
        att, pos = self._att, self._pos
        if t not in att or t not in pos:
            return None
        R, rates, from_q = att[t]
        p, v = pos[t]
        for d in (att, pos):
            if len(d) == 1:
                d.clear()
            else:
                for k in [k for k in d if k <= t]:
                    if k < t:
                        self.counters.unmatched += 1
                    del d[k]
        self._last_ms = t
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R
        vx, vy, vz = v
        x = np.array((p[0], p[1], p[2],
                      math.atan2(r21, r22), -math.asin(min(max(r20, -1.0), 1.0)), math.atan2(r10, r00),
                      r00 * vx + r10 * vy + r20 * vz, r01 * vx + r11 * vy + r21 * vz,
                      r02 * vx + r12 * vy + r22 * vz,
                      rates[0], rates[1], rates[2]))
        return StateSample(t, x, np.array(R), from_q, p, v, R, rates)


def _quat_to_matrix(w: float, x: float, y: float, z: float) -> tuple:
    """Rotation matrix of the unit quaternion (w, x, y, z), rows as tuples."""
    return ((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
            (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
            (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)))


def _rpy_to_matrix(phi: float, theta: float, psi: float) -> tuple:
    """R = Rz(psi) Ry(theta) Rx(phi), rows as tuples."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    return ((cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * st * cf),
            (sp * ct, cp * cf + sp * st * sf, -cp * sf + sp * st * cf),
            (-st, ct * sf, ct * cf))
