"""Synthetic flights for the identification tests: the fit's model integrated finely, open loop.

The attitude follows smooth roll, pitch and yaw sinusoids (speeds of several m/s along body x
and y, and some along z); the summed rotor command holds the weight with a slow sinusoid, a
3 Hz square wave (which excites the rotor lag) and per-sample noise, all scaled by ``excite``. The commands act ``delay_s``
after their sample, through a first-order lag of ``tau_s``, scaled by ``thrust_scale``; the
drag is body-frame linear (and optionally quadratic; its rotor-plane part optionally grows as
(thrust / m g)^e, ``drag_thrust_exponent``). Velocity is integrated by Heun's method
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
                     seed=1, tilt_rad=0.35, excite=1.0, drag_thrust_exponent=0.0) -> FlightSeries:
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
        k = (max(thrust[i], 0.0) / (MASS_KG * G)) ** drag_thrust_exponent   # rotor-plane drag's growth
        fb = np.array([-k * cx * vb[0], -k * cy * vb[1], -cz * vb[2] - thrust[i]])
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
    ``timesync_every`` samples (0: none) whose reply says ``link_delay_s``. A flight of the rates output
    has its body rates in ATTITUDE_QUATERNION and its commands as SET_ATTITUDE_TARGET."""
    from pymavlink.dialects.v20 import common as mavlink2

    from mavreg.daemon.vehicle.messages import actuator_target, rate_target, timesync_request
    from mavreg.daemon.logs.tlog import TlogWriter
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
            rates = (0.0, 0.0, 0.0) if series.body_rates_rad_s is None else series.body_rates_rad_s[k]
            tl.write(mavlink2.MAVLink_attitude_quaternion_message(ms, w, x, y, z, *(float(a) for a in rates)).pack(veh))
            p, v = series.position_ned_m[k], series.velocity_ned_m_s[k]
            tl.write(mavlink2.MAVLink_local_position_ned_message(ms, *(float(a) for a in p),
                                                                 *(float(a) for a in v)).pack(veh))
            if pending is not None and t >= pending[0]:
                tl.write(mavlink2.MAVLink_timesync_message(int(round(pending[0] * 1e9)), pending[1]).pack(veh))
                pending = None
            u = series.command_controls[k]
            tl.write((rate_target(int(t * 1e3) + 1, 1, 1, u[:3], u[3]) if series.output == "rates"
                      else actuator_target(int(t * 1e6) + 500, 1, 1, u)).pack(dmn))
            if timesync_every and k % timesync_every == 0 and pending is None:
                ts1 = int(t * 1e9) + 600_000
                tl.write(timesync_request(ts1).pack(dmn))
                pending = (float(t) + link_delay_s, ts1)


def _rodrigues(w_dt: np.ndarray) -> np.ndarray:
    """exp([w_dt]x): the rotation of a body turning at constant rate for one step."""
    a = float(np.linalg.norm(w_dt))
    K = np.array([[0.0, -w_dt[2], w_dt[1]], [w_dt[2], 0.0, -w_dt[0]], [-w_dt[1], w_dt[0], 0.0]])
    if a < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + math.sin(a) / a * K + (1 - math.cos(a)) / (a * a) * K @ K


def synthetic_rate_flight(duration_s=20.0, h=0.002, hover_thrust=0.35, expo=0.4, rate_tau_s=(0.03, 0.03, 0.05),
                          delay_s=0.012, thrust_tau_s=0.03, drag=(0.25, 0.35, 0.15), noise_sd=0.02,
                          noise_tc_s=0.2, gyro_sd=0.01, seed=1, excite=1.0, rate_order=1,
                          squares=True, doublets=None) -> FlightSeries:
    """A flight of the rates output, closed loop: the rigid body under a stock autopilot's
    rate loop (a pure delay, then first order per axis with ``rate_tau_s``; ``rate_order`` 2:
    two cascaded lags of half that, the wrong model order) and thrust map
    F = F_max ((1 - e) t + e t^2) holding MASS_KG at ``hover_thrust``, the collective delayed
    alike and lagged by ``thrust_tau_s``.

    At each sample the "regulator" commands body rates
    ``0.5 w_measured - 2 (roll, pitch, yaw - yaw_ref) + excitation`` (sinusoids and square
    waves per axis, scaled by ``excite``; ``squares`` False: the sinusoids only; ``doublets``,
    an :class:`~mavreg.daemon.flight.excitation.ExcitationParams`: no sinusoids or square waves, but the
    identification flight's doublets from t = 0.5 s, sent as they are on their axis in place of
    the feedback, as the daemon's hold sends them); the measured rates carry white noise ``gyro_sd``)
    and the thrust that holds the weight through the tilt, less a vertical-speed feedback on
    the measured (Gauss-Markov noisy) velocity, with a slow sinusoid, a 3 Hz square wave and
    noise. The fine step is h / 2; body drag as :func:`synthetic_flight`.
    """
    from mavreg.model.rate_interface import ThrustMap
    from mavreg.model.rotation import matrix_to_rpy, matrices_to_quats
    rng = np.random.default_rng(seed)
    tmap = ThrustMap(MASS_KG, hover_thrust, expo)
    sub, n = 2, int(round(duration_s / h)) + 1
    hf = h / sub
    n_delay = delay_s / hf
    tau = np.repeat(np.asarray(rate_tau_s, float), 2) / (1 if rate_order == 1 else 2)
    decay = np.exp(-hf / tau)                       # stages (p1, p2, q1, q2, r1, r2)
    ts = np.arange(n) * h
    sq = np.sign if squares else np.zeros_like
    exc = (0.0 if doublets is not None else excite) * np.stack([1.2 * np.sin(2 * np.pi * 0.4 * ts) + 0.6 * sq(np.sin(2 * np.pi * 2.3 * ts)),
                             1.2 * np.sin(2 * np.pi * 0.3 * ts + 1) + 0.6 * sq(np.sin(2 * np.pi * 1.7 * ts)),
                             0.8 * np.sin(2 * np.pi * 0.2 * ts) + 0.4 * sq(np.sin(2 * np.pi * 1.1 * ts))], 1)
    thr_exc = 1 + excite * (0.15 * np.sin(2 * np.pi * 0.9 * ts) + 0.12 * np.sign(np.sin(2 * np.pi * 3.0 * ts))
                            + 0.02 * rng.standard_normal(n))
    rho = math.exp(-h / noise_tc_s)
    cmd = np.zeros((n, 4))
    out_q, out_v, out_w, out_p = (np.zeros((n, k)) for k in (4, 3, 3, 3))
    R, v, p = np.eye(3), np.zeros(3), np.array([0.0, 0.0, -50.0])
    stages, thrust_state, e_v = np.zeros(6), 0.0, rng.standard_normal(3) * noise_sd
    f_sched = np.zeros(n)                       # the collective each command asks for (N)
    cx, cy, cz = drag
    lag_f = math.exp(-hf / thrust_tau_s)

    def accel(Ri, vi, fi):
        vb = Ri.T @ vi
        return Ri @ np.array([-cx * vb[0], -cy * vb[1], -cz * vb[2] - fi]) / MASS_KG + np.array([0.0, 0.0, G])

    for i in range((n - 1) * sub + 1):
        if i % sub == 0:                        # a sample, and the command answering it
            k = i // sub
            w_true = stages[1::2]
            e_v = rho * e_v + rng.standard_normal(3) * noise_sd * math.sqrt(1 - rho * rho)
            w_m = w_true + gyro_sd * rng.standard_normal(3)
            out_q[k], out_v[k], out_w[k], out_p[k] = matrices_to_quats(R[None])[0], v + e_v, w_m, p
            rpy = matrix_to_rpy(R)
            rpy[2] -= 0.25 * ts[k]
            cmd[k, :3] = 0.5 * w_m - 2.0 * ((rpy + np.pi) % (2 * np.pi) - np.pi) + exc[k]
            step = None if doublets is None else doublets.rate_at(ts[k] - 0.5)
            if step is not None:
                cmd[k, step[0]] = step[1]
            tilt = max(0.5, R[2, 2])
            f_sched[k] = MASS_KG * (G + 1.0 * (v[2] + e_v[2])) / tilt * thr_exc[k]
            cmd[k, 3] = tmap.normalized(f_sched[k])
            if k == n - 1:
                break
        j = int(math.floor((i - n_delay) / sub + 1e-9))        # the command in force over this step
        u = cmd[j] if j >= 0 else np.zeros(4)   # nothing before the first command, as the fit assumes
        f_in = float(tmap.thrust_n(u[3]))
        inputs = np.array([u[0], 0, u[1], 0, u[2], 0], float)
        w0 = stages[1::2].copy()
        if rate_order == 1:
            stages[1::2] = inputs[0::2] + (stages[1::2] - inputs[0::2]) * decay[1::2]
        else:
            stages[0::2] = inputs[0::2] + (stages[0::2] - inputs[0::2]) * decay[0::2]
            stages[1::2] = stages[0::2] + (stages[1::2] - stages[0::2]) * decay[1::2]
        f0 = thrust_state
        thrust_state = f_in + (thrust_state - f_in) * lag_f
        R1 = R @ _rodrigues((w0 + stages[1::2]) / 2 * hf)
        a0 = accel(R, v, f0)
        a1 = accel(R1, v + hf * a0, thrust_state)
        p = p + hf * v + hf * hf / 2 * a0
        v = v + hf / 2 * (a0 + a1)
        R = R1
    return FlightSeries(t_s=ts, position_ned_m=out_p, velocity_ned_m_s=out_v, quaternion_wxyz=out_q,
                        controlled=np.ones(n, bool), command_t_s=ts.copy(), command_controls=cmd,
                        link_delay_s=None, output="rates", body_rates_rad_s=out_w)
