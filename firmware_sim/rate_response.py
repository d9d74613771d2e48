"""The emulator's true rate-mode figures: its thrust map and its closed-loop rate step response.

What an identification of the vehicle (mavreg's rate mode) should find, computed from the
emulator itself (``firmware-sim --print-rate-response``, docs/firmware_sim.md, "Rate mode, as
PX4 OFFBOARD"):

- **Thrust map**: total thrust of the normalized collective ``t``,
  ``F = g_T 4 f_max ((1 - e) t + e t^2)``, ``e = THR_MDL_FAC``, ``f_max`` the file's
  ``max_rotor_thrust_n`` and ``g_T`` the thrust per newton commanded of the true airframe
  (the world's thrust scale times the mean rotor gain of ``--mismatch-seed``); and the hover
  collective, where ``F`` equals the true weight.
- **Rate step response**: the engine itself (the true airframe, the autopilot, the world's
  estimate latency and gyro path, its estimator errors and rotor noise off, so the answer is
  the mean behaviour) hovers on rate set-points, then one axis gets a step; the true body rate
  after the receipt of the step. Receipts fall on physics steps while the loop ticks once per
  control period, so the response is the mean over the receipt phases (a receipt between ticks
  waits for the next one). From it: the 10/50/90 % times, the overshoot, the final value (mean
  of the last quarter), and a first-order-plus-delay fit ``y = K (1 - exp(-(t - delay) / tau))``
  (least squares over the first 150 ms, ``K`` the final value).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2
from scipy.optimize import least_squares

from .autopilot import Autopilot, AutopilotConfig
from .engine import Engine
from .physics import G
from .rate_loop import RateLoopConfig, collective_thrust_n, hover_thrust, thrust_for_force
from .sim import Simulation
from .stabilizer import Stabilizer
from .world import LinkParams, WorldPreset

__all__ = ["StepResponse", "step_response", "true_thrust_n", "true_hover_thrust", "fit_first_order_delay",
           "describe_rate_mode", "step_figures", "AXES"]

AXES = ("roll", "pitch", "yaw")
_FIT_WINDOW_S = 0.15


@dataclass(frozen=True)
class StepResponse:
    """One axis' true rate response to a step of ``step_rad_s`` (times after the receipt)."""

    axis: int
    step_rad_s: float
    t_s: np.ndarray
    rate_rad_s: np.ndarray
    t10_s: float
    t50_s: float
    t90_s: float
    overshoot: float
    """Peak beyond the final value, a fraction of the step."""
    final: float
    """Final value, a fraction of the step."""
    tau_s: float
    delay_s: float


def _thrust_gain(params) -> float:
    return params.vehicle.emulator.thrust_scale * sum(params.rotor_gain) / 4.0


def true_thrust_n(t: float, params, e: float, max_rotor_thrust_n: float | None = None) -> float:
    """Total thrust (N) the true airframe of ``params`` gives for the collective ``t`` (below
    saturation): the map of the autopilot's ``f_max`` (default the airframe's) times the true
    thrust per newton commanded."""
    fmax = max_rotor_thrust_n if max_rotor_thrust_n is not None else params.vehicle.max_rotor_thrust_n
    return _thrust_gain(params) * collective_thrust_n(t, e, fmax)


def true_hover_thrust(params, e: float, max_rotor_thrust_n: float | None = None) -> float:
    """The collective that carries the true airframe of ``params``."""
    fmax = max_rotor_thrust_n if max_rotor_thrust_n is not None else params.vehicle.max_rotor_thrust_n
    return thrust_for_force(params.vehicle.mass_kg * G / _thrust_gain(params), e, fmax)


class _NullLink:
    peers: list = []

    def send(self, msgs) -> None:
        pass

    def recv_datagram(self):
        return None


class _RateTrace:
    """A recorder that keeps the true body rates of every physics step."""

    def __init__(self):
        self.t: list = []
        self.w: list = []

    def record(self, t, s, cmd, applied, armed, mode, on_ground) -> None:
        self.t.append(t)
        self.w.append((s[10], s[11], s[12]))

    def record_estimate(self, *args) -> None:
        pass


def _engine(params, nominal, world: WorldPreset, cfg: RateLoopConfig, fmax_n: float, phase_steps: int):
    """The engine of the measurement: commands received ``phase_steps`` physics steps after
    each period's start (a command delay of exactly that), no estimator errors, no rotor noise."""
    v, n = params.vehicle, nominal.vehicle
    quiet = dataclasses.replace(v, emulator=dataclasses.replace(v.emulator, rotor_noise_sd_n=0.0))
    params = dataclasses.replace(params, vehicle=quiet)
    trace = _RateTrace()
    sim = Simulation(params, (0.0, 0.0, -50.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), None, trace)
    stab = Stabilizer(n.mass_kg, nominal.inertia_matrix_kg_m2, n.arm_length_m, n.drag_torque_ratio_m,
                      n.max_rotor_thrust_n)
    ap = Autopilot(AutopilotConfig(max_rotor_thrust_n=fmax_n), stab, n.mass_kg * G / 4, rate_loop=cfg)
    ap.start_in_flight(0.0)
    link = LinkParams(command_delay_s=phase_steps / params.physics_hz)
    quiet_world = dataclasses.replace(world, link=link, estimator=world.estimator.scaled(0.0))
    return Engine(sim, ap, _NullLink(), quiet_world), trace


def _phase_response(params, nominal, world, cfg, fmax_n, axis, step_rad_s, settle_s, duration_s, phase_steps):
    """The true rate of ``axis`` after the receipt of the step, at every physics step."""
    engine, trace = _engine(params, nominal, world, cfg, fmax_n, phase_steps)
    codec = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)
    t_h = hover_thrust(nominal.vehicle.mass_kg, cfg.thr_mdl_fac, fmax_n)
    rate_hz = params.rate_hz
    k_step = int(round(settle_s * rate_hz))
    for k in range(k_step + int(round(duration_s * rate_hz)) + 1):
        rates = [0.0, 0.0, 0.0]
        if k >= k_step:
            rates[axis] = step_rad_s
        msg = mavlink2.MAVLink_set_attitude_target_message(k, 1, 1, 128, (1.0, 0.0, 0.0, 0.0), *rates, t_h)
        engine.begin_period()
        engine.receive([codec.decode(bytearray(msg.pack(codec)))])
        engine.step()
    t = np.asarray(trace.t) - (k_step / rate_hz + phase_steps / params.physics_hz)
    w = np.asarray(trace.w)[:, axis]
    start = int(np.argmin(np.abs(t)))
    n = int(round(duration_s * params.physics_hz))
    return t[start:start + n], w[start:start + n] - w[start]


def step_response(params, world: WorldPreset, cfg: RateLoopConfig | None = None, axis: int = 0,
                  step_rad_s: float = 1.0, nominal=None, max_rotor_thrust_n: float | None = None,
                  settle_s: float = 0.3, duration_s: float = 0.4) -> StepResponse:
    """The true response of ``axis`` (0 roll, 1 pitch, 2 yaw) to a rate step (see the module
    docstring); ``params`` the true airframe, ``nominal`` the file's (default ``params``),
    ``max_rotor_thrust_n`` the autopilot's ``f_max`` (default the nominal one)."""
    cfg = cfg if cfg is not None else RateLoopConfig()
    nominal = nominal if nominal is not None else params
    fmax = max_rotor_thrust_n if max_rotor_thrust_n is not None else nominal.vehicle.max_rotor_thrust_n
    runs = [_phase_response(params, nominal, world, cfg, fmax, axis, step_rad_s, settle_s, duration_s, j)
            for j in range(params.substeps)]
    t = runs[0][0]
    return step_figures(axis, step_rad_s, t, np.mean([w for _, w in runs], axis=0))


def _crossing(t, y, level: float) -> float:
    i = int(np.argmax(y >= level))
    if y[i] < level:
        return math.nan
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (level - y[i - 1]) * (t[i] - t[i - 1]) / (y[i] - y[i - 1]))


def fit_first_order_delay(t, y, final: float) -> tuple[float, float]:
    """``(tau_s, delay_s)`` of ``y ~ final (1 - exp(-(t - delay) / tau))`` (``y`` a fraction of
    the step) by least squares over ``t`` <= 150 ms."""
    sel = t <= _FIT_WINDOW_S + 1e-12
    ts, ys = t[sel], y[sel]

    def residual(x):
        tau, delay = x
        return ys - final * np.where(ts > delay, 1.0 - np.exp(-(ts - delay) / tau), 0.0)

    t50 = _crossing(ts, ys, 0.5 * final)
    x0 = (max(1e-3, 0.5 * t50), max(0.0, 0.5 * t50))
    fit = least_squares(residual, x0, bounds=((1e-4, 0.0), (1.0, 0.2)))
    return float(fit.x[0]), float(fit.x[1])


def step_figures(axis, step, t, w) -> StepResponse:
    """The figures of the response ``w`` (rad/s) at ``t`` (s after the step) to a step of ``step``
    rad/s on ``axis``: what :func:`step_response` reports, for a measured response too."""
    y = w / step
    final = float(np.mean(y[int(0.75 * len(y)):]))
    tau, delay = fit_first_order_delay(t, y, final)
    return StepResponse(axis, step, t, w, *(_crossing(t, y, f * final) for f in (0.1, 0.5, 0.9)),
                        max(0.0, float(np.max(y)) - final), final, tau, delay)


def describe_rate_mode(params, world: WorldPreset, cfg: RateLoopConfig | None = None, nominal=None,
                       max_rotor_thrust_n: float | None = None, steps_rad_s=(1.0, 1.0, 0.1)) -> list[str]:
    """The lines ``--print-rate-response`` prints: the thrust map, then one line per axis
    (steps of ``steps_rad_s``: yaw's authority at hover is small, see docs/firmware_sim.md)."""
    cfg = cfg if cfg is not None else RateLoopConfig()
    nominal = nominal if nominal is not None else params
    n = nominal.vehicle
    fmax = max_rotor_thrust_n if max_rotor_thrust_n is not None else n.max_rotor_thrust_n
    e = cfg.thr_mdl_fac
    lines = [f"thrust map: F = 4 * {fmax:g} N * ((1 - e) t + e t^2), e = THR_MDL_FAC {e:g}; hover "
             f"collective MPC_THR_HOVER {hover_thrust(n.mass_kg, e, fmax):.4f} (file), "
             f"{true_hover_thrust(params, e, fmax):.4f} (true airframe); true thrust per newton "
             f"commanded {true_thrust_n(1.0, params, e, fmax) / collective_thrust_n(1.0, e, fmax):.4f}"]
    for axis in range(3):
        r = step_response(params, world, cfg, axis, steps_rad_s[axis], nominal, fmax)
        lines.append(
            f"rate response {AXES[axis]} ({world.name} world, {steps_rad_s[axis]:g} rad/s step, from the "
            f"receipt to the true rate, mean over receipt phases): 10/50/90 % at {1e3 * r.t10_s:.1f}/"
            f"{1e3 * r.t50_s:.1f}/{1e3 * r.t90_s:.1f} ms, overshoot {100 * r.overshoot:.1f} %, "
            f"final {r.final:.3f}; first order + delay: tau {1e3 * r.tau_s:.1f} ms, delay "
            f"{1e3 * r.delay_s:.1f} ms")
    return lines
