"""Synthetic flights for the identification tests: the fit's model integrated finely, open loop.

The attitude follows smooth roll, pitch and yaw sinusoids (speeds of several m/s along body x
and y, and some along z); the summed rotor command holds the weight with a slow sinusoid, a
3 Hz square wave (which excites the rotor lag) and per-sample noise, all scaled by ``excite``. The commands act ``delay_s``
after their sample, through a first-order lag of ``tau_s``, scaled by ``thrust_scale``; the
drag is body-frame linear (and optionally quadratic). Velocity is integrated by Heun's method
at a quarter of the sample period; the telemetry velocity carries Gauss-Markov noise.
"""
from __future__ import annotations

import math

import numpy as np

from mavreg.identify.fit import FlightSeries
from mavreg.model.rotation import rpy_to_matrix, rpy_to_quat

MASS_KG = 0.749
MAX_ROTOR_N = 12.0
G = 9.81


def synthetic_flight(duration_s=20.0, h=0.002, thrust_scale=1.07, drag=(0.25, 0.35, 0.15),
                     parasitic=0.0, tau_s=0.03, delay_s=0.0135, noise_sd=0.02, noise_tc_s=0.2,
                     seed=1, tilt_rad=0.35, excite=1.0) -> FlightSeries:
    rng = np.random.default_rng(seed)
    sub = 4
    hf = h / sub
    n = int(round(duration_s / h)) + 1
    nf = (n - 1) * sub + 1
    tf = np.arange(nf) * hf
    phi = tilt_rad * np.sin(2 * np.pi * 0.11 * tf) + 0.1 * np.sin(2 * np.pi * 0.7 * tf)
    theta = tilt_rad * np.sin(2 * np.pi * 0.08 * tf + 1.0) + 0.08 * np.sin(2 * np.pi * 0.53 * tf)
    psi = 0.25 * tf + 0.3 * np.sin(2 * np.pi * 0.05 * tf)
    R = np.moveaxis(rpy_to_matrix(phi, theta, psi), -1, 0)             # (nf, 3, 3)
    # commands at the samples: the weight, a slow sinusoid, a square wave, noise
    ts = np.arange(n) * h
    tilt = np.cos(phi[::sub]) * np.cos(theta[::sub])
    square = np.sign(np.sin(2 * np.pi * 3.0 * ts))
    csum = (MASS_KG * G / (thrust_scale * tilt)
            * (1 + excite * (0.12 * np.sin(2 * np.pi * 0.9 * ts) + 0.1 * square + 0.02 * rng.standard_normal(n))))
    controls = np.clip(np.repeat(csum[:, None] / 4 / MAX_ROTOR_N, 4, axis=1), 0, 1)
    # the thrust on the fine grid: command k acts from t_k + delay; first-order lag, exact
    k_act = np.floor((tf - delay_s) / h + 1e-9).astype(int)
    c_f = np.where(k_act >= 0, controls.sum(axis=1)[np.clip(k_act, 0, n - 1)] * MAX_ROTOR_N, 0.0)
    a = math.exp(-hf / tau_s) if tau_s > 0 else 0.0
    f = np.empty(nf)
    f[0] = 0.0
    for i in range(1, nf):
        f[i] = a * f[i - 1] + (1 - a) * c_f[i - 1]      # the input held over each fine step
    thrust = thrust_scale * f
    cx, cy, cz = drag
    v = np.zeros((nf, 3))

    def accel(i, vi):
        Ri = R[i]
        vb = Ri.T @ vi
        fb = np.array([-cx * vb[0], -cy * vb[1], -cz * vb[2] - thrust[i]])
        return (Ri @ fb - parasitic * np.linalg.norm(vi) * vi) / MASS_KG + np.array([0.0, 0.0, G])

    for i in range(nf - 1):
        a0 = accel(i, v[i])
        vp = v[i] + hf * a0
        v[i + 1] = v[i] + hf / 2 * (a0 + accel(i + 1, vp))
    p = np.cumsum(v, axis=0) * hf + np.array([0.0, 0.0, -50.0])
    vs, ps = v[::sub], p[::sub]
    # Gauss-Markov velocity noise
    rho = math.exp(-h / noise_tc_s)
    e = np.zeros((n, 3))
    w = rng.standard_normal((n, 3)) * noise_sd * math.sqrt(1 - rho * rho)
    e[0] = rng.standard_normal(3) * noise_sd
    for k in range(1, n):
        e[k] = rho * e[k - 1] + w[k]
    q = rpy_to_quat(phi[::sub], theta[::sub], psi[::sub]).T
    return FlightSeries(t_s=ts, position_ned_m=ps, velocity_ned_m_s=vs + e, quaternion_wxyz=q,
                        controlled=np.ones(n, bool), command_t_s=ts.copy(), command_controls=controls,
                        link_delay_s=None)


def write_tlog(series: FlightSeries, path, link_delay_s: float = 0.018, timesync_every: int = 50) -> None:
    """The flight as the daemon's ``.tlog`` would have it: per sample the vehicle's
    ATTITUDE_QUATERNION and LOCAL_POSITION_NED, then the daemon's command; vehicle HEARTBEATs
    at 1 Hz (armed, OFFBOARD where ``controlled``); a TIMESYNC exchange every
    ``timesync_every`` samples whose reply says ``link_delay_s``."""
    from pymavlink.dialects.v20 import common as mavlink2

    from mavreg.daemon.messages import actuator_target, timesync_request
    from mavreg.daemon.tlog import TlogWriter
    veh = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    dmn = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)
    clock = [1.7e9]
    pending = None
    with TlogWriter(path, clock_s=lambda: clock[0]) as tl:
        for k, t in enumerate(series.t_s):
            clock[0] = 1.7e9 + float(t)
            ms = int(round(t * 1e3))
            if k % int(round(1.0 / (series.t_s[1] - series.t_s[0]))) == 0:
                on = bool(series.controlled[k])
                tl.write(mavlink2.MAVLink_heartbeat_message(
                    mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_PX4, 1 | (128 if on else 0),
                    (6 << 16) if on else (4 << 16) | (3 << 24), mavlink2.MAV_STATE_ACTIVE, 3).pack(veh))
            w, x, y, z = (float(a) for a in series.quaternion_wxyz[k])
            tl.write(mavlink2.MAVLink_attitude_quaternion_message(ms, w, x, y, z, 0.0, 0.0, 0.0).pack(veh))
            p, v = series.position_ned_m[k], series.velocity_ned_m_s[k]
            tl.write(mavlink2.MAVLink_local_position_ned_message(ms, *(float(a) for a in p),
                                                                 *(float(a) for a in v)).pack(veh))
            if pending is not None and t >= pending[0]:
                tl.write(mavlink2.MAVLink_timesync_message(int(round(pending[0] * 1e9)), pending[1]).pack(veh))
                pending = None
            tl.write(actuator_target(int(t * 1e6) + 500, 1, 1, series.command_controls[k]).pack(dmn))
            if k % timesync_every == 0 and pending is None:
                ts1 = int(t * 1e9) + 600_000
                tl.write(timesync_request(ts1).pack(dmn))
                pending = (float(t) + link_delay_s, ts1)
