"""Fly a planned maneuver with the regulator on the design model (no I/O)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import dataclasses

from ..config.defaults import MAX_PREDICTION_S
from ..config.disturbance import DisturbanceParams
from ..config.regulation import AllocationParams, SpeedGovernorParams
from ..control.estimation.forecast import Forecaster
from ..control.estimation.lag_in_effect import RotorLagInEffect
from ..control.controllers.regulator import ManeuverRegulator
from ..maneuver.plan import Plan
from ..model.mixer import Mixer
from ..model.quadrotor import QuadrotorModel
from ..model.rotation import rpy_to_matrix
from .closed_loop import SimOptions, SimResult, simulate, window_force
from .estimate_noise import EstimateCorruptor, EstimateNoise
from .metrics import rotor_jitter_n, tracking_metrics
from .truth import true_errors

__all__ = ["ManeuverRun", "fly_on_design_model"]


@dataclass(frozen=True)
class ManeuverRun:
    result: SimResult
    s: np.ndarray
    """Arc length at each control step."""
    w: np.ndarray
    """Transverse coordinates at each control step (N, 11)."""
    in_tube: np.ndarray
    metrics: dict


def fly_on_design_model(plan: Plan, *, offset_m=(0.0, 0.0, 0.0), inertia_kg_m2=None,
                        rotor_noise_sd_n: float = 0.0, saturation_n: float | None = None,
                        seed: int | None = None, control_rate_hz: float = 1000.0,
                        dt_s: float = 0.001, extra_time_s: float = 5.0,
                        gust_force_n=None, gust_window_s=(0.0, 0.0),
                        rotor_time_constant_s: float = 0.0, measurement_delay_s: float = 0.0,
                        command_delay_s: float = 0.0, estimate_noise: EstimateNoise | None = None,
                        predict: bool = False, assumed_delay_s: float | None = None,
                        start_s_m: float = 0.0, allocation: AllocationParams | None = None,
                        speed_governor: SpeedGovernorParams | None = None, thrust_scale: float = 1.0,
                        max_prediction_s: float = MAX_PREDICTION_S, disturbance: DisturbanceParams | None = None,
                        true_metrics: bool = True) -> ManeuverRun:
    """Start at the nominal entry state plus ``offset_m`` and fly to the end of the path
    (with ``start_s_m``: at the nominal state at that arc length plus ``offset_m``).

    The plant may differ from the design (``inertia_kg_m2``); the controller always uses
    the plan's nominal design. ``gust_force_n`` (NED, N) pushes on the vehicle during
    ``gust_window_s`` = (t0, t1). Stops when s reaches the end, or after the nominal duration
    plus ``extra_time_s``.

    A realistic loop: the rotors lag by ``rotor_time_constant_s`` (the controller knows it:
    its feedforward leads by it, and lag-aware gains use it); the controller sees the state
    ``measurement_delay_s`` late, corrupted by ``estimate_noise`` (seeded by ``seed``), and
    its command reaches the rotors ``command_delay_s`` later. With ``predict`` it first
    predicts the state across ``assumed_delay_s`` (default: the true round trip) with
    :class:`~mavreg.control.estimation.forecast.Forecaster`, at most ``max_prediction_s`` ahead; with
    ``disturbance`` enabled its observer runs from the start and the regulator compensates
    its estimate, as in the daemon (needs ``predict``). The rotors give ``thrust_scale`` of
    their command (the controller is not told). ``allocation`` and ``speed_governor`` (the
    controller file's sections) go to the regulator (default: the paper's). ``true_metrics``
    False leaves out ``metrics["true"]`` (a quarter of a run's CPU).
    """
    vehicle = plan.vehicle
    period = 1.0 / control_rate_hz
    forecaster = _forecaster(plan, rotor_time_constant_s, period, predict, max_prediction_s, disturbance)
    lag = RotorLagInEffect(rotor_time_constant_s) if forecaster is None else forecaster.rotor_lag
    reg = ManeuverRegulator(plan, vehicle, period, lag, allocation=allocation, speed_governor=speed_governor)
    x0 = plan.nominal_state(start_s_m) if start_s_m else plan.entry_state
    x0[:3] += np.asarray(offset_m, dtype=float)
    reg.reset(x0, s_guess=start_s_m)
    steps = int(round(1.0 / (control_rate_hz * dt_s)))
    if steps < 1 or abs(steps * dt_s * control_rate_hz - 1.0) > 1e-9:
        raise ValueError(f"control rate {control_rate_hz} Hz is not a whole number of "
                         f"{dt_s * 1e3:g} ms physics steps")
    log_s, log_w, log_tube = [], [], []
    rng = np.random.default_rng(seed)
    corrupt = None if estimate_noise is None else EstimateCorruptor(estimate_noise, period, rng)
    horizon = measurement_delay_s + command_delay_s if assumed_delay_s is None else assumed_delay_s

    def controller(t, x):
        R = None
        if corrupt is not None:
            x, R = corrupt(x)
        if forecaster is not None:
            t_sample = t - measurement_delay_s
            fc = forecaster.update(t_sample, x, rpy_to_matrix(*x[3:6]) if R is None else R, horizon)
            out = reg.step(fc.x, fc.rotor_forces_n, forecaster.disturbance)
            command = forecaster.command(t_sample, out.rotor_forces_n)
        else:
            out = reg.step(x)
            command = out.rotor_forces_n
        log_s.append(out.s)
        log_w.append(out.w)
        log_tube.append(out.in_tube)
        return command

    duration = plan.duration_s + extra_time_s
    opts = SimOptions(initial_state=tuple(x0), dt_s=dt_s, control_period_steps=steps,
                      max_duration_s=duration, inertia_kg_m2=inertia_kg_m2,
                      rotor_noise_sd_n=rotor_noise_sd_n, seed=seed, saturation_n=saturation_n,
                      rotor_time_constant_s=rotor_time_constant_s, thrust_scale=thrust_scale,
                      measurement_delay_s=measurement_delay_s, command_delay_s=command_delay_s,
                      force_fn=None if gust_force_n is None else window_force(gust_force_n, *gust_window_s),
                      done=lambda t, x: reg.s >= plan.length_m - 1e-6,
                      attitude="so3" if plan.attitude_error == "so3" else "rpy")
    result = simulate(QuadrotorModel.from_vehicle(vehicle),
                      Mixer.from_vehicle(vehicle), controller, opts)
    return _run(plan, result, (log_s, log_w, log_tube), (steps, dt_s, control_rate_hz),
                saturation_n or vehicle.max_rotor_thrust_n, true_metrics)


def _forecaster(plan: Plan, rotor_time_constant_s: float, period_s: float,
                predict: bool, max_prediction_s: float, disturbance: DisturbanceParams | None):
    """The prediction across the delay (and the disturbance observer) of :func:`fly_on_design_model`,
    its rotors at the entry's forces; None without ``predict``."""
    observe = disturbance is not None and disturbance.enabled
    if observe and not predict:
        raise ValueError("the disturbance observer runs in the forecaster: it needs predict=True")
    if not predict:
        return None
    forecaster = Forecaster(dataclasses.replace(plan.vehicle, rotor_time_constant_s=rotor_time_constant_s),
                            period_s, max_horizon_s=max_prediction_s, disturbance=disturbance)
    forecaster.observing = observe
    forecaster.reset(Mixer.from_vehicle(plan.vehicle).inverse @ plan.u[0])
    return forecaster


def _run(plan: Plan, result: SimResult, logs, rate, max_rotor_thrust_n: float, true_metrics: bool) -> ManeuverRun:
    """The :class:`ManeuverRun` of a flown ``result``, the regulator's logs (s, w, in tube) and
    its ``rate`` (physics steps per control period, physics step, control rate in Hz)."""
    log_s, log_w, log_tube = logs
    steps, dt_s, control_rate_hz = rate
    s = np.clip(np.array(log_s), 0.0, plan.length_m)  # the extension before 0 counts as the first segment
    w = np.array(log_w).reshape(-1, 11)
    rotors = result.rotor_command_n[::steps][: len(s)]
    metrics = tracking_metrics(s, w, plan.segments, rotor_forces_n=rotors,
                               max_rotor_thrust_n=max_rotor_thrust_n, dt_s=steps * dt_s)
    if true_metrics:
        metrics["true"] = true_errors(plan, result.x[:, :3],
                                      rpy_to_matrix(*result.x[:, 3:6].T).transpose(2, 0, 1))
    metrics["rotor_jitter_n"] = rotor_jitter_n(rotors, control_rate_hz)
    metrics = {"stable": result.status.value != "diverged",
               "completed": result.status.value == "completed",
               "status": result.status.value, "reason": result.reason,
               "always_in_tube": bool(np.all(log_tube)), **metrics}
    return ManeuverRun(result, s, w, np.array(log_tube), metrics)

