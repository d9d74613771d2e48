r"""State prediction across the link: where the vehicle will be when a command acts.

A sample stamped ``t`` describes the vehicle at ``t`` (less the estimate's own latency,
which the caller adds to the horizon). A command computed from it reaches the rotors
``H`` later: the downlink, the daemon, the uplink, and the estimate latency. Fed back
without compensation, ``H`` is a pure delay inside the loop; the barrel roll's LQR loses
centimetres at 5 ms and diverges by 20 ms (docs/robustness.md). The predictor removes it:

1. The rotor forces at ``t`` are the first-order lag (time constant :math:`\tau`) of the
   commands that have *acted* before ``t``. The command answering the sample of time
   :math:`t_j` acts from :math:`t_j + H` until the next one takes over, so this is a filter
   over the command history, advanced exactly
   (:math:`f \leftarrow c + (f - c)e^{-\Delta/\tau}`) and kept between calls.
2. From the sample's state, the rigid body of the design model (eqs 1-4, on rotation
   matrices: no Euler singularity) is integrated to :math:`t + H` under the commands
   already sent that act in :math:`[t, t + H)`, the rotor lag included. Each step holds
   the exact mean of the lagged force over the step; attitude uses the exponential map;
   position and velocity are second order.

The result is the state and the rotor forces at the moment the next command takes over:
what the regulator needs (the state for ``w``, the forces for the actuator part of the
lag-augmented gain). The horizon is capped at ``max_horizon_s``.

Pure Python floats: no numpy on the hot path (a 30-step prediction costs ~0.2 ms).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from ..config.vehicle import G, VehicleParams
from ..model.rotation import matrix_to_rpy

__all__ = ["StatePredictor", "Prediction"]

_MAX_PENDING = 4096
"""Commands kept before the acted ones are folded into the rotor state (8 s at 500 Hz)."""


@dataclass(frozen=True)
class Prediction:
    """The vehicle at ``time_s`` (= sample time + horizon)."""

    time_s: float
    horizon_s: float
    x: np.ndarray
    """(12,) design-model state (p, roll pitch yaw, v_body, w_body)."""
    rotation: np.ndarray
    """(3, 3) body-to-NED rotation."""
    rotor_forces_n: np.ndarray
    """(4,) the rotors' lagged forces at ``time_s``."""


def _exp_so3(wx: float, wy: float, wz: float):
    """Rotation matrix exp([w]x) as a row-major 9-tuple (Rodrigues)."""
    th2 = wx * wx + wy * wy + wz * wz
    if th2 < 1e-12:
        a, b = 1.0 - th2 / 6.0, 0.5 - th2 / 24.0
    else:
        th = math.sqrt(th2)
        a, b = math.sin(th) / th, (1.0 - math.cos(th)) / th2
    return (1.0 - b * (wy * wy + wz * wz), -a * wz + b * wx * wy, a * wy + b * wx * wz,
            a * wz + b * wx * wy, 1.0 - b * (wx * wx + wz * wz), -a * wx + b * wy * wz,
            -a * wy + b * wx * wz, a * wx + b * wy * wz, 1.0 - b * (wx * wx + wy * wy))


def _matmul(A, B):
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = A
    b0, b1, b2, b3, b4, b5, b6, b7, b8 = B
    return (a0 * b0 + a1 * b3 + a2 * b6, a0 * b1 + a1 * b4 + a2 * b7, a0 * b2 + a1 * b5 + a2 * b8,
            a3 * b0 + a4 * b3 + a5 * b6, a3 * b1 + a4 * b4 + a5 * b7, a3 * b2 + a4 * b5 + a5 * b8,
            a6 * b0 + a7 * b3 + a8 * b6, a6 * b1 + a7 * b4 + a8 * b7, a6 * b2 + a7 * b5 + a8 * b8)


class StatePredictor:
    """Predicts the design model across a known delay, with the commands already sent.

    Parameters
    ----------
    vehicle : VehicleParams
        Mass, inertia, arm length, k, rotor limit and the rotor time constant
        (``rotor_time_constant_s``; 0 for ideal rotors).
    max_step_s : float
        Longest integration step (a command switch always starts a new step).
    max_horizon_s : float
        Cap on the prediction horizon.
    """

    def __init__(self, vehicle: VehicleParams, max_step_s: float = 0.002, max_horizon_s: float = 0.1):
        if not (max_step_s > 0 and max_horizon_s >= 0):
            raise ValueError("max_step_s must be > 0 and max_horizon_s >= 0")
        self.mass_kg = float(vehicle.mass_kg)
        self.jx, self.jy, self.jz = (float(j) for j in vehicle.inertia_kg_m2)
        self.l = float(vehicle.arm_length_m)
        self.k = float(vehicle.drag_torque_ratio_m)
        self.fmax = float(vehicle.max_rotor_thrust_n)
        self.tau = float(vehicle.rotor_time_constant_s)
        self.cxy, self.cz = (float(c) for c in vehicle.rotor_drag_n_s_per_m)
        self.cp = float(vehicle.parasitic_drag_n_s2_per_m2)
        self.max_step_s = float(max_step_s)
        self.max_horizon_s = float(max_horizon_s)
        self._cmds: deque = deque()          # (t_answered_s, (c1..c4)) not yet fully acted
        self._f = (0.0, 0.0, 0.0, 0.0)       # rotor forces at self._t_f
        self._t_f: float | None = None
        self._last_delay_s = 0.0

    def reset(self, rotor_forces_n=(0.0, 0.0, 0.0, 0.0)) -> None:
        """Forget the command history; the rotors are at ``rotor_forces_n``."""
        self._cmds.clear()
        self._f = tuple(float(v) for v in rotor_forces_n)
        self._t_f = None

    def record(self, t_s: float, rotor_cmd_n) -> None:
        """The command sent in answer to the sample of vehicle time ``t_s`` (clipped as the
        vehicle clips it)."""
        fmax = self.fmax
        c = tuple(0.0 if v < 0.0 else (fmax if v > fmax else float(v)) for v in rotor_cmd_n)
        if self._cmds and t_s <= self._cmds[-1][0]:
            self._cmds[-1] = (self._cmds[-1][0], c)   # a second answer to the same sample replaces the first
        else:
            self._cmds.append((float(t_s), c))
        if len(self._cmds) > _MAX_PENDING:
            # Nobody has asked for a prediction for a while (a long preflight): fold the
            # commands that have acted into the rotor state, so the history stays bounded.
            self.rotor_forces(t_s, self._last_delay_s)

    def _lag(self, f, c, dt):
        """Rotor forces after ``dt`` toward ``c`` and their mean over the interval."""
        if dt <= 0.0:
            return f, f
        if self.tau <= 0.0:
            return c, c
        e = math.exp(-dt / self.tau)
        frac = self.tau / dt * (1.0 - e)
        new = tuple(ci + (fi - ci) * e for fi, ci in zip(f, c))
        mean = tuple(ci + (fi - ci) * frac for fi, ci in zip(f, c))
        return new, mean

    def rotor_forces(self, t_s: float, horizon_s: float):
        """Lagged rotor forces at ``t_s`` from the commands that acted before it (each acts
        ``horizon_s`` after the sample it answered). Advances the kept filter state."""
        cmds = self._cmds
        self._last_delay_s = horizon_s
        if self._t_f is None:         # the rotors were at the reset value until the first command
            self._t_f = min(t_s, cmds[0][0] + horizon_s) if cmds else t_s
        t, f = self._t_f, self._f
        if t_s <= t:
            return f
        while cmds:
            start = cmds[0][0] + horizon_s
            if start >= t_s:
                break
            end = cmds[1][0] + horizon_s if len(cmds) > 1 else math.inf
            a = max(start, t)
            b = min(end, t_s)
            if b > a:
                f, _ = self._lag(f, cmds[0][1], b - a)
                t = b
            if end <= t_s and len(cmds) > 1:
                cmds.popleft()       # fully acted
            else:
                break
        self._t_f, self._f = t_s, f
        return f

    def predict(self, t_s: float, x, rotation, horizon_s: float, delay_s: float | None = None,
                external_force_n=(0.0, 0.0, 0.0), thrust_scale: float = 1.0,
                drag_n_s_per_m=None) -> Prediction:
        """The state at ``t_s + horizon_s`` from the sample ``x`` (12,) with body-to-NED
        ``rotation`` (3, 3) at ``t_s``. ``horizon_s`` is capped at ``max_horizon_s``.

        ``delay_s`` (default: the horizon) is when commands act after the sample they
        answered; a longer horizon predicts past the first new command (a telemetry gap,
        :meth:`Forecaster.ahead <mavreg.control.forecast.Forecaster.ahead>`).
        ``external_force_n`` (NED) is a known external force; ``thrust_scale`` the rotors'
        actual per commanded force (the vehicle file's calibration); ``drag_n_s_per_m`` a
        linear body drag (c_xy, c_z) in place of the vehicle file's (an estimate of it)."""
        drag = (self.cxy, self.cz) if drag_n_s_per_m is None else tuple(float(c) for c in drag_n_s_per_m)
        H = min(max(float(horizon_s), 0.0), self.max_horizon_s)
        D = H if delay_s is None else min(max(float(delay_s), 0.0), self.max_horizon_s)
        f = self.rotor_forces(t_s, D)
        R = tuple(float(v) for v in np.asarray(rotation, dtype=float).ravel())
        x = np.asarray(x, dtype=float)
        vb = x[6:9]
        p = [float(x[0]), float(x[1]), float(x[2])]
        v = [R[0] * vb[0] + R[1] * vb[1] + R[2] * vb[2], R[3] * vb[0] + R[4] * vb[1] + R[5] * vb[2],
             R[6] * vb[0] + R[7] * vb[1] + R[8] * vb[2]]
        w = [float(x[9]), float(x[10]), float(x[11])]
        t_end = t_s + H
        # Commands acting in [t_s, t_end): the one in force at t_s, then those starting later.
        segments = []
        current = None
        for tj, c in self._cmds:
            start = tj + D
            if start <= t_s:
                current = c
            elif start < t_end:
                segments.append((start, c))
        t = t_s
        c = current if current is not None else f
        for start, nxt in segments + [(t_end, None)]:
            while t < start - 1e-12:
                dt = min(self.max_step_s, start - t)
                f, fm = self._lag(f, c, dt)
                if thrust_scale != 1.0:
                    fm = tuple(thrust_scale * fi for fi in fm)
                R, p, v, w = self._body_step(R, p, v, w, fm, dt, external_force_n, drag)
                t += dt
            if nxt is not None:
                c = nxt
        Rm = np.array(R).reshape(3, 3)
        vb_new = Rm.T @ np.array(v)
        xp = np.concatenate([p, matrix_to_rpy(Rm), vb_new, w])
        return Prediction(t_end, H, xp, Rm, thrust_scale * np.array(f))

    def _body_step(self, R, p, v, w, f, dt, fext=(0.0, 0.0, 0.0), drag_n_s_per_m=None):
        """One step of eqs 1-4 on (R, p, v_ned, w) with rotor forces ``f`` held."""
        m, l, k = self.mass_kg, self.l, self.k
        jx, jy, jz = self.jx, self.jy, self.jz
        T = f[0] + f[1] + f[2] + f[3]
        g1, g2, g3 = l * (f[3] - f[1]), l * (f[0] - f[2]), k * (-f[0] + f[1] - f[2] + f[3])

        def wdot(p_, q_, r_):
            return ((g1 + (jy - jz) * q_ * r_) / jx, (g2 + (jz - jx) * p_ * r_) / jy,
                    (g3 + (jx - jy) * p_ * q_) / jz)

        d0 = wdot(*w)
        wm = (w[0] + 0.5 * dt * d0[0], w[1] + 0.5 * dt * d0[1], w[2] + 0.5 * dt * d0[2])
        dm = wdot(*wm)
        R1 = _matmul(R, _exp_so3(wm[0] * dt, wm[1] * dt, wm[2] * dt))
        s = T / m
        a0 = [-s * R[2], -s * R[5], G - s * R[8]]       # g e3 - (T/m) R e3
        a1 = [-s * R1[2], -s * R1[5], G - s * R1[8]]
        cxy, cz = (self.cxy, self.cz) if drag_n_s_per_m is None else drag_n_s_per_m
        drag = cxy or cz or self.cp
        for acc, Rm in ((a0, R), (a1, R1)):
            d = self._drag(Rm, v, cxy, cz) if drag else (0.0, 0.0, 0.0)   # at the step's start velocity
            for i in range(3):
                acc[i] += (d[i] + fext[i]) / m
        p1 = [p[i] + dt * v[i] + dt * dt / 6.0 * (2.0 * a0[i] + a1[i]) for i in range(3)]
        v1 = [v[i] + 0.5 * dt * (a0[i] + a1[i]) for i in range(3)]
        w1 = [w[i] + dt * dm[i] for i in range(3)]
        return R1, p1, v1, w1

    def _drag(self, R, v, cxy, cz):
        """Drag force (NED) at velocity ``v``: -R C R^T v - c_p |v| v (quadrotor.py's model),
        C = diag(cxy, cxy, cz)."""
        zx, zy, zz = R[2], R[5], R[8]
        along = (cz - cxy) * (zx * v[0] + zy * v[1] + zz * v[2])
        q = cxy + self.cp * math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        return (-q * v[0] - along * zx, -q * v[1] - along * zy, -q * v[2] - along * zz)
