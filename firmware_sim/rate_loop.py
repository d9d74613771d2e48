"""The autopilot's body-rate loop of OFFBOARD rate set-points, in PX4's form (sans-I/O).

SET_ATTITUDE_TARGET with the attitude ignored (:mod:`firmware_sim.setpoints`) gives body
rates (rad/s, FRD) and a normalized collective thrust ``t`` in [0, 1]. This module flies them
as PX4's multicopter rate controller does, written for the emulator alone:

- **Gyro path.** The loop runs once per control period on the rates the emulator publishes
  (the estimate: in the realistic world the truth of 4 ms ago plus bias and noise), through
  a second-order Butterworth low-pass of ``IMU_GYRO_CUTOFF`` Hz; the angular acceleration is
  the difference of successive raw samples through a second-order low-pass of
  ``IMU_DGYRO_CUTOFF`` Hz (PX4's ``LowPassFilter2p``; a cutoff of 0 or at or above half the
  loop rate is no filter).
- **Controller**, per axis, in PX4's normalized-torque units: those of its control allocator,
  which scales the pseudo-inverse of the frame's effectiveness matrix so that a unit roll or
  pitch torque moves each rotor acting on it by ``f_max / sqrt 2`` (its column's norm squared
  is half the count of those rotors) and a unit yaw torque each rotor by ``f_max`` (the
  column's largest entry is 1), ``f_max`` the file's ``max_rotor_thrust_n``: on this '+' frame
  ``sqrt 2 l f_max`` in roll and pitch, ``4 k f_max`` in yaw (:data:`ROLL_PITCH_UNIT`,
  :data:`YAW_UNIT`)::

      u = P e + I_state - D (d omega_f / dt) + FF omega_sp,      e = omega_sp - omega_f
      I_state += I (1 - (e / 400 deg/s)^2)^+ e dt, clipped to +- *_INT_LIM, not integrated
                 further into an allocator saturation nor on the ground; 0 when the loop starts

  The allocation limits ``u`` (roll and pitch to +-1/sqrt 2, where the axis' rotors span
  ``f_max``; yaw to the room left) and reports it.
- **Processing latency.** A set-point reaches the loop ``latency_s`` after it was received
  (the first loop tick at or after that; ``--rate-latency-s``).
- **Thrust model.** The collective of ``t`` is ``F = 4 f_max ((1 - e) t + e t^2)``,
  ``e = THR_MDL_FAC`` (:func:`collective_thrust_n`): the curve of the motors, which the
  emulator does not linearize (as PX4 with its own factor left at 0 on such motors).
- **Allocation** (:func:`allocate`), PX4's "airmode roll/pitch": roll and pitch are kept
  (only clipped where no collective could give them), the collective is moved up or down
  as far as they need, and yaw gets what room is left; the collective is given up first,
  then yaw. The clipped axes are reported to the integrators (anti-windup).

The gains are tuned for the bundled airframe (0.75 kg, 20 ms motor lag; P 0.25, I 0.2, D
0.003 in roll and pitch and P 1.5 in yaw in the former unit, f_max / 2 a rotor: the same
torques, docs/firmware_sim.md, *Units*), stable over the airframes ``--mismatch-seed`` draws
(10-50 ms lag, inertia +-30 %) at 250 and 500 Hz: in the realistic world a 1 rad/s roll step
reaches 10/50/90 % of the command about 11/27/47 ms after its receipt, 2 % overshoot
(:mod:`firmware_sim.rate_response` gives the exact figures).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

__all__ = ["RateLoopConfig", "RateLoop", "LowPass2p", "allocate", "collective_thrust_n",
           "thrust_for_force", "hover_thrust", "ROLL_PITCH_UNIT", "YAW_UNIT"]

I_FACTOR_RATE_RAD_S = math.radians(400.0)
"""PX4's integrator fade-out: the I gain falls to 0 at this rate error."""
ROLL_PITCH_UNIT = 1.0 / math.sqrt(2.0)
"""Thrust change of each rotor acting on roll (pitch), a fraction of ``f_max``, per unit of
normalized roll (pitch) torque: PX4's allocator normalization (module docstring)."""
YAW_UNIT = 1.0
"""The same per unit of normalized yaw torque."""
_R = ROLL_PITCH_UNIT
_Y = 0.5 / YAW_UNIT


@dataclass(frozen=True)
class RateLoopConfig:
    """Gains (normalized torque per rad/s, per rad, per rad/s^2), filters and thrust model.

    Field ``roll_p`` is PX4's ``MC_ROLLRATE_P`` and so on (:data:`firmware_sim.px4.PARAMS`).
    """

    roll_p: float = 0.25 * _R
    roll_i: float = 0.20 * _R
    roll_d: float = 0.003 * _R
    roll_ff: float = 0.0
    pitch_p: float = 0.25 * _R
    pitch_i: float = 0.20 * _R
    pitch_d: float = 0.003 * _R
    pitch_ff: float = 0.0
    yaw_p: float = 1.5 * _Y
    yaw_i: float = 0.20 * _Y
    yaw_d: float = 0.0
    yaw_ff: float = 0.0
    roll_int_lim: float = 0.30 * _R
    pitch_int_lim: float = 0.30 * _R
    yaw_int_lim: float = 0.30 * _Y
    gyro_cutoff_hz: float = 150.0
    dgyro_cutoff_hz: float = 40.0
    thr_mdl_fac: float = 0.3
    """``e`` of the thrust model: 0 linear, 1 quadratic."""
    latency_s: float = 0.002
    """From the receipt of a set-point to the loop that uses it."""

    def gains(self, axis: int) -> tuple:
        """``(P, I, D, FF, integrator limit)`` of axis 0 roll, 1 pitch, 2 yaw."""
        n = ("roll", "pitch", "yaw")[axis]
        return tuple(getattr(self, f"{n}_{k}") for k in ("p", "i", "d", "ff", "int_lim"))


def collective_thrust_n(t: float, e: float, max_rotor_thrust_n: float) -> float:
    """Total thrust (N) of the normalized collective ``t``: ``4 f_max ((1 - e) t + e t^2)``."""
    return 4.0 * max_rotor_thrust_n * ((1.0 - e) * t + e * t * t)


def thrust_for_force(force_n: float, e: float, max_rotor_thrust_n: float) -> float:
    """The collective ``t`` in [0, 1] whose thrust is ``force_n`` (N), clipped at both ends."""
    y = max(0.0, min(1.0, force_n / (4.0 * max_rotor_thrust_n)))
    if e < 1e-9:
        return y
    return (-(1.0 - e) + math.sqrt((1.0 - e) ** 2 + 4.0 * e * y)) / (2.0 * e)


def hover_thrust(mass_kg: float, e: float, max_rotor_thrust_n: float, g_m_s2: float = 9.81) -> float:
    """The collective that carries ``mass_kg`` (PX4's ``MPC_THR_HOVER``)."""
    return thrust_for_force(mass_kg * g_m_s2, e, max_rotor_thrust_n)


class LowPass2p:
    """PX4's second-order Butterworth low-pass (bilinear transform), one channel.

    A cutoff <= 0 or >= half the sample rate passes the input through.
    """

    def __init__(self, sample_hz: float, cutoff_hz: float):
        self.on = 0.0 < cutoff_hz < 0.5 * sample_hz
        self.d1 = self.d2 = 0.0
        if not self.on:
            return
        ohm = math.tan(math.pi * cutoff_hz / sample_hz)
        c = 1.0 + 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm
        self.b0 = ohm * ohm / c
        self.a1 = 2.0 * (ohm * ohm - 1.0) / c
        self.a2 = (1.0 - 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm) / c

    def reset(self, x: float) -> float:
        """Settle on the constant input ``x``; return it."""
        if self.on:
            self.d1 = self.d2 = x / (4.0 * self.b0)
        return x

    def apply(self, x: float) -> float:
        if not self.on:
            return x
        d0 = x - self.d1 * self.a1 - self.d2 * self.a2
        out = self.b0 * (d0 + 2.0 * self.d1 + self.d2)
        self.d2, self.d1 = self.d1, d0
        return out


def allocate(t: float, u, e: float, max_rotor_thrust_n: float):
    """Rotor forces (N, rotors 1..4 front, right, back, left) of collective ``t`` and normalized
    torques ``u`` (roll, pitch, yaw), and the axes clipped: ``(forces, saturation)`` with
    ``saturation[i]`` = +1 / -1 when axis i lost torque in that direction, else 0.

    Roll and pitch first (each rotor moved by ``u ROLL_PITCH_UNIT f_max``, clipped only beyond
    ``f_max / 2``, where no collective gives them), then the collective, moved as far as roll and
    pitch need (airmode), then yaw (``u YAW_UNIT f_max`` a rotor) in the room left.
    """
    fmax = max_rotor_thrust_n
    half = 0.5 * fmax
    sat = [0, 0, 0]
    d = []
    for i in (0, 1):
        want = u[i] * ROLL_PITCH_UNIT * fmax
        x = max(-half, min(half, want))
        if x != want:
            sat[i] = 1 if want > 0 else -1
        d.append(x)
    dr, dp = d
    m = max(abs(dr), abs(dp))
    c = max(m, min(fmax - m, 0.25 * collective_thrust_n(t, e, fmax)))
    want = u[2] * YAW_UNIT * fmax
    up = min(fmax - c - abs(dr), c - abs(dp))        # room for +yaw: rotors 2, 4 up, 1, 3 down
    down = min(c - abs(dr), fmax - c - abs(dp))
    dy = max(-max(0.0, down), min(max(0.0, up), want))
    if dy != want:
        sat[2] = 1 if want > dy else -1
    forces = (c + dp - dy, c - dr + dy, c - dp - dy, c + dr + dy)
    return tuple(0.0 if f < 0.0 else (fmax if f > fmax else f) for f in forces), sat


class RateLoop:
    """The rate loop of one autopilot: pending set-points, filters, integrators, allocation.

    Parameters
    ----------
    config : RateLoopConfig
    rate_hz : float
        Loop (control) rate.
    max_rotor_thrust_n : float
        ``f_max`` of the vehicle file (the allocation and the thrust model use it).
    """

    def __init__(self, config: RateLoopConfig, rate_hz: float, max_rotor_thrust_n: float):
        self.cfg = config
        self.dt_s = 1.0 / float(rate_hz)
        self.fmax = float(max_rotor_thrust_n)
        self._pending: deque = deque()
        self.setpoint = None
        """``(p, q, r, thrust)`` in use, or ``None`` before the first one is due."""
        self.next_tick_t = -math.inf
        self.last_tick_t = -math.inf
        self.output_n = (0.0, 0.0, 0.0, 0.0)
        self.torque = (0.0, 0.0, 0.0)
        self._build_filters()

    def _build_filters(self) -> None:
        fs, c = 1.0 / self.dt_s, self.cfg
        self._lp = [LowPass2p(fs, c.gyro_cutoff_hz) for _ in range(3)]
        self._dlp = [LowPass2p(fs, c.dgyro_cutoff_hz) for _ in range(3)]
        self._integral = [0.0, 0.0, 0.0]
        self._raw_prev = None
        self._sat = [0, 0, 0]

    def set_rate_hz(self, rate_hz: float) -> None:
        """Run at ``rate_hz`` (the engine's control rate); the filters restart."""
        self.dt_s = 1.0 / float(rate_hz)
        self.configure(self.cfg)

    def configure(self, config: RateLoopConfig) -> None:
        """New gains or filters (a PARAM_SET); the filters restart at the next tick."""
        self.cfg = config
        self._build_filters()
        self.last_tick_t = -math.inf

    def push(self, t_s: float, setpoint: tuple) -> None:
        """A set-point ``(p, q, r, thrust)`` received at ``t_s``: in use from ``t_s + latency``.

        Set-points already due by ``t_s`` are taken first, so that the queue holds only those
        within the latency (also while the loop does not run: disarmed, another mode)."""
        while self._pending and self._pending[0][0] <= t_s + 1e-9:
            self.setpoint = self._pending.popleft()[1]
        self._pending.append((t_s + self.cfg.latency_s, setpoint))

    @property
    def queued(self) -> tuple:
        """The set-points received but not yet in use (within the latency)."""
        return tuple(sp for _, sp in self._pending)

    def clear(self) -> None:
        """Forget set-points in flight (another set-point kind took over)."""
        self._pending.clear()
        self.setpoint = None

    def command_n(self, t_s, gyro_rad_s, on_ground: bool):
        """Rotor forces (N) for the period starting at ``t_s``; between ticks the last output is
        held. ``None`` while no set-point has reached the loop yet (the first ``latency_s`` of a
        rate stream: the caller flies what it flew). ``t_s`` ``None`` (a caller without a clock):
        a tick every call, one period after the last, every set-point received in use."""
        if t_s is not None and t_s < self.next_tick_t - 1e-9:
            return self.output_n
        if t_s is None:
            now = self.last_tick_t + self.dt_s if self.last_tick_t > -math.inf else 0.0
            due = math.inf
        else:
            now = due = t_s
        while self._pending and self._pending[0][0] <= due + 1e-9:
            self.setpoint = self._pending.popleft()[1]
        if self.setpoint is None:
            return None
        if now - self.last_tick_t > 1.5 * self.dt_s:       # (re)starting: filters on the gyro
            self._start(gyro_rad_s)
        self.last_tick_t, self.next_tick_t = now, now + self.dt_s
        self.torque = tuple(self._axis(i, gyro_rad_s[i], on_ground) for i in range(3))
        self._raw_prev = tuple(gyro_rad_s)
        self.output_n, sat = allocate(self.setpoint[3], self.torque, self.cfg.thr_mdl_fac, self.fmax)
        self._sat = sat
        return self.output_n

    def _start(self, gyro) -> None:
        self._build_filters()
        for i in range(3):
            self._lp[i].reset(gyro[i])
            self._dlp[i].reset(0.0)
        self._raw_prev = tuple(gyro)

    def _axis(self, i: int, raw: float, on_ground: bool) -> float:
        kp, ki, kd, kff, lim = self.cfg.gains(i)
        w = self._lp[i].apply(raw)
        accel = self._dlp[i].apply((raw - self._raw_prev[i]) / self.dt_s)
        sp = self.setpoint[i]
        err = sp - w
        u = kp * err + self._integral[i] - kd * accel + kff * sp
        if not (on_ground or self._sat[i] > 0 and err > 0 or self._sat[i] < 0 and err < 0):
            fade = max(0.0, 1.0 - (err / I_FACTOR_RATE_RAD_S) ** 2)
            self._integral[i] = max(-lim, min(lim, self._integral[i] + fade * ki * err * self.dt_s))
        return u
