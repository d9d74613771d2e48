r"""Calibrate the rates output: a stock autopilot's thrust map and rate loop, from one flight.

Pure numpy/scipy, like :mod:`mavreg.identify.fit`, whose grid, least squares and
moving-block bootstrap it reuses. The flight is one of ``output: rates``: the daemon's
SET_ATTITUDE_TARGET body rates :math:`\omega_c` and normalized thrust t, the vehicle's
attitude, velocity and body rates :math:`\omega`.

**Thrust map.** The collective is :math:`F = F_{max}((1 - e)\,t + e\,t^2)`
(:class:`mavreg.model.rate_interface.ThrustMap`), delayed by D and lagged by the autopilot's
motors (:math:`\tau_f`), so the translational model of :mod:`mavreg.identify.fit` holds with
two thrust columns, the lagged t and the lagged :math:`t^2`, in place of the rotor sum:

.. math::
    m\dot v = c_1\,\bar t\,(-R e_3) + c_2\,\overline{t^2}\,(-R e_3) + m g e_3 - \text{drag},

:math:`c_1 = F_{max}(1 - e)`, :math:`c_2 = F_{max} e` (N). For each :math:`(\tau_f, D)` it
is linear least squares; then :math:`F_{max} = c_1 + c_2`, :math:`e = c_2 / F_{max}` and the
hover thrust :math:`t_h` is the root of :math:`c_2 t_h^2 + c_1 t_h = m g` (m the file's
mass). The bootstrap re-estimates :math:`c_1, c_2` on every replicate; :math:`t_h` and e
are derived per replicate, so their intervals are the map's.

**Rate loop.** Per axis, :math:`\dot\omega = (\omega_c(t - D) - \omega)/\tau_\omega`,
compared as output error: the integral of the measured rate over each sample interval
against the exact integral of the delayed, lagged command (:func:`lagged_integrals`, the
rotor lag's discretization), plus an offset (a gyro bias). The gain is the model's, 1: a
free gain would absorb the small loss of amplitude that, besides the phase, tells a lag
from a delay, and a flight of smooth rates would then pin only their sum. For each
:math:`(\tau_\omega, D)` the offset is linear; :math:`(\tau_\omega, D)` minimize the residual
over a grid, and the bootstrap gives every interval. The gain k fitted freely at that
:math:`(\tau_\omega, D)` is reported: near 1 says the model fits. The delay D runs from the sample the command answered to the response, so the rate
loop's own delay is :math:`d = D - D_{link}` with the link's part (TIMESYNC plus the vehicle
file's estimate latency) given by the caller.

**Which samples.** A flight with the identification excitation (``mavreg fly
--identify-excitation``: rate doublets in the hold, :mod:`mavreg.daemon.flight.excitation`) has the
rate loop fitted on the doublets' window only (:func:`rate_rows`; ``rate_window`` 'all': the
whole flight). A maneuver's rates are large and smooth: where the loop is not first order
they weigh a split of lag and delay of their own into the fit, which the steps pin otherwise.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..config.vehicle import G
from .estimates import Estimate, drag_estimates, fit_quality, interval, intervals_text, lag_estimates
from .fit import FitOptions, ColumnModel, checked_options, fit_columns, translational_fit
from .regressors import FlightSeries, IdentifyError, Regressors, lagged_integrals

__all__ = ["RateAxis", "RateIdentification", "identify_rates", "thrust_channels", "rate_rows", "AXES"]

AXES = {"roll": (0,), "pitch": (1,), "yaw": (2,), "roll_pitch": (0, 1)}
"""The rate fits: each axis alone, and roll with pitch sharing one time constant and delay
(the value written to the vehicle file)."""

_RATE_GRID_S = (0.01, 0.004)
"""The rate fits' coarse (tau, D) grid: the residual is smooth in both (output error)."""

_MIN_RATE_RMS_RAD_S = 0.05
"""An axis whose commanded rate varies less than this (RMS about its mean) is not fitted."""
_MIN_EXCITED_RMS_RAD_S = 0.02
"""The same on the identification excitation's window, whose yaw pulses are small on
purpose (0.1 rad/s: a larger yaw step meets the yaw torque's limit) but are steps."""


@dataclass(frozen=True)
class RateAxis:
    """The rate loop about one axis (or roll and pitch together)."""

    time_constant_s: Estimate
    delay_s: Estimate
    """D: from the sample the command answered to the response."""
    loop_delay_s: Estimate
    """d = D less the link's part: the rate loop's own delay (``rate_delay_s``), at least 0."""
    free_gain: float
    """The gain k of k w_cmd that least squares gives at (tau, D): the model says 1."""
    residual_rms_rad_s: float
    r_squared: float
    command_rms_rad_s: float

    def as_dict(self) -> dict:
        return {"time_constant_s": self.time_constant_s.as_dict(), "delay_s": self.delay_s.as_dict(),
                "loop_delay_s": self.loop_delay_s.as_dict(), "free_gain": _finite(self.free_gain),
                "residual_rms_rad_s": _finite(self.residual_rms_rad_s), "r_squared": _finite(self.r_squared),
                "command_rms_rad_s": self.command_rms_rad_s}


def _finite(x: float) -> float | None:
    """x, or None for the NaN of an axis not fitted (strict JSON has no NaN)."""
    return float(x) if np.isfinite(x) else None


@dataclass(frozen=True)
class RateIdentification:
    """What :func:`identify_rates` found; :meth:`as_dict` is the JSON form."""

    hover_thrust: Estimate
    thrust_expo: Estimate
    max_thrust_n: Estimate
    collective_time_constant_s: Estimate
    """tau_f: the collective's first-order lag (the vehicle file's ``rotor_time_constant_s``)."""
    collective_delay_s: Estimate
    drag_n_s_per_m: tuple[Estimate, Estimate, Estimate]
    drag_xy_n_s_per_m: Estimate
    parasitic_n_s2_per_m2: Estimate
    model: str
    residual_rms_m_s2: float
    r_squared: float
    thrust_range: tuple[float, float]
    """5th and 95th percentile of the normalized thrust over the samples fitted."""
    rate_axes: dict
    """``AXES`` name -> :class:`RateAxis`."""
    link_delay_part_s: float
    samples: int
    duration_s: float
    rms_body_speed_m_s: tuple[float, float, float]
    intervals: str
    link_delay_s: float | None
    output: str = "rates"
    rate_window: str = "the whole flight"
    """The samples the rate loop was fitted on (:func:`rate_rows`)."""

    def as_dict(self) -> dict:
        return {
            "output": self.output, "model": self.model,
            "hover_thrust": self.hover_thrust.as_dict(), "thrust_expo": self.thrust_expo.as_dict(),
            "max_thrust_n": self.max_thrust_n.as_dict(),
            "collective_time_constant_s": self.collective_time_constant_s.as_dict(),
            "collective_delay_s": self.collective_delay_s.as_dict(),
            "drag_n_s_per_m": {k: e.as_dict() for k, e in zip("xyz", self.drag_n_s_per_m)},
            "drag_xy_n_s_per_m": self.drag_xy_n_s_per_m.as_dict(),
            "parasitic_drag_n_s2_per_m2": self.parasitic_n_s2_per_m2.as_dict(),
            "residual_rms_m_s2": self.residual_rms_m_s2, "r_squared": self.r_squared,
            "thrust_range": list(self.thrust_range),
            "rate_loop": {k: a.as_dict() for k, a in self.rate_axes.items()}, "rate_window": self.rate_window,
            "link_delay_part_s": self.link_delay_part_s, "link_delay_timesync_s": self.link_delay_s,
            "samples": self.samples, "duration_s": self.duration_s,
            "rms_body_speed_m_s": list(self.rms_body_speed_m_s), "intervals": self.intervals,
        }


def thrust_channels(series: FlightSeries) -> np.ndarray:
    """(K, 2): the normalized thrust t of each rates command (clipped to [0, 1] as the
    autopilot clips it) and t^2: the thrust map's two columns."""
    u = np.asarray(series.command_controls, float).reshape(np.size(series.command_t_s), -1)
    if u.shape[1] != 4:
        raise IdentifyError(f"rates commands need 4 values (3 rates, thrust), got {u.shape[1]}")
    t = np.clip(u[:, 3], 0.0, 1.0)
    return np.stack([t, t * t], axis=1)


class _RateRows:
    """One rate fit as :func:`mavreg.identify.fit.fit_columns` takes it: ``y`` (rows, a) the
    measured rate integrated over the interval ending at each row, ``fixed`` (rows, a, a) an
    offset per axis, and one column: the delayed, lagged command's integral."""

    def __init__(self, P: Regressors, command: np.ndarray, axes: tuple, rows: np.ndarray | None = None):
        self.h, self.rows, self.axes = P.h, P.rows if rows is None else rows, axes
        self.cmd = command[:, list(axes)]
        w = P.rates[:, list(axes)]
        self.y = P.h / 2 * (w[self.rows - 1] + w[self.rows])
        self.fixed = np.zeros((self.rows.size, len(axes), len(axes)))
        for a in range(len(axes)):
            self.fixed[:, a, a] = P.h

    def thrust_columns(self, tau_s: float, delay_s: float) -> np.ndarray:
        cols = [lagged_integrals(self.cmd[:, a], self.h, tau_s, delay_s)[self.rows - 1]
                for a in range(len(self.axes))]
        return np.stack(cols, axis=1)[:, :, None]


def identify_rates(series: FlightSeries, mass_kg: float, options: FitOptions | None = None,
                   link_delay_part_s: float = 0.0) -> RateIdentification:
    """Fit the thrust map, the collective's lag and the rate loop to a flight of the rates
    output (module docstring).

    Parameters
    ----------
    series : FlightSeries
        ``output`` rates, with ``body_rates_rad_s``.
    mass_kg : float
        The vehicle file's mass: the hover thrust is the thrust that holds it.
    options : FitOptions, optional
        ``delay_s`` is the collective's delay (None: searched with its lag, as the rotor
        output's). The rate loop's delay is always searched, up to ``rate_delay_max_s``, its
        lag up to ``rate_tau_max_s``.
    link_delay_part_s : float
        The part of the sample-to-response delay that is the link's, subtracted to give the
        rate loop's own delay d.

    Raises
    ------
    IdentifyError
        One line: not a rates flight, no body rates, too little usable data, or a thrust map
        that does not hold the mass.
    """
    o = checked_options(options)
    if series.output != "rates":
        raise IdentifyError(f"this flight's commands are {series.output}, not body rates and thrust")
    if series.body_rates_rad_s is None:
        raise IdentifyError("the flight has no measured body rates (ATTITUDE_QUATERNION rollspeed ...)")
    channels = thrust_channels(series)
    P = Regressors(series, mass_kg, channels, o)
    command, _ = P.hold(series.command_t_s, np.asarray(series.command_controls, float)[:, :3], o.command_timeout_s)
    if not np.any(P.rates[P.rows]):
        raise IdentifyError("the vehicle reports no body rates (ATTITUDE_QUATERNION and ATTITUDE rollspeed, "
                            "pitchspeed, yawspeed all 0): the rate loop cannot be measured")
    ro = replace(o, tau_max_s=o.rate_tau_max_s, delay_max_s=o.rate_delay_max_s, delay_s=None,
                 grid_steps_s=_RATE_GRID_S, delay_needs_margin=True)
    rows, window = rate_rows(P, series.excitation_windows_s, o.rate_window)
    least = _MIN_EXCITED_RMS_RAD_S if window.startswith("the identification") else _MIN_RATE_RMS_RAD_S
    axes = {name: _rate_axis(P, command, idx, ro, link_delay_part_s, rows, least) for name, idx in AXES.items()}
    fit, speed = translational_fit(P, o)
    hover, expo, fmax = _thrust_map(fit, mass_kg)
    tau_f, delay_f = lag_estimates(fit, o, what="collective's lag")
    drag, drag_xy, parasitic, model = drag_estimates(fit, speed, o)
    rms, r2 = fit_quality(P.y, fit["resid"])
    used = P.held[P.rows, 0]                    # the thrust in force at the rows fitted
    return RateIdentification(
        hover_thrust=hover, thrust_expo=expo, max_thrust_n=fmax, collective_time_constant_s=tau_f,
        collective_delay_s=delay_f, drag_n_s_per_m=drag, drag_xy_n_s_per_m=drag_xy,
        parasitic_n_s2_per_m2=parasitic, model=model, residual_rms_m_s2=rms, r_squared=r2,
        thrust_range=tuple(float(x) for x in np.percentile(used, [5, 95])),
        rate_axes=axes, link_delay_part_s=float(link_delay_part_s), samples=int(P.rows.size),
        duration_s=float(P.rows.size * P.h), rms_body_speed_m_s=speed,
        intervals=intervals_text(fit["bs"], P.h, o), link_delay_s=series.link_delay_s, rate_window=window)


_AFTER_EXCITATION_S = 0.5
"""The rate fit keeps this much after the excitation's end: its last doublet's response."""


def rate_rows(P: Regressors, windows: tuple, how: str) -> tuple[np.ndarray, str]:
    """(the rows the rate loop is fitted on, a phrase saying which): with ``how`` 'auto' and
    the identification excitation in the flight, the usable rows inside its windows (and
    ``_AFTER_EXCITATION_S`` after), where the rate steps are; else every usable row."""
    if how == "auto" and windows:
        t = P.t0 + P.rows * P.h
        inside = np.zeros(P.rows.size, bool)
        for start, end in windows:
            inside |= (t >= start) & (t <= end + _AFTER_EXCITATION_S)
        if inside.sum() * P.h >= 2.0:
            span = ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in windows)
            return P.rows[inside], f"the identification excitation ({span}, {inside.sum() * P.h:.1f} s)"
    return P.rows, "the whole flight"


def _hover(c1, c2, weight_n):
    """The root t in (0, 1] of c2 t^2 + c1 t = m g (NaN where there is none)."""
    c1, c2 = np.asarray(c1, float), np.asarray(c2, float)
    disc = c1 * c1 + 4.0 * c2 * weight_n
    den = c1 + np.sqrt(np.where(disc >= 0, disc, np.nan))
    t = 2.0 * weight_n / np.where(den > 0, den, np.nan)
    return np.where((t > 0) & (t <= 1), t, np.nan)


def _thrust_map(fit: dict, mass_kg: float) -> tuple[Estimate, Estimate, Estimate]:
    """(t_h, e, F_max) from the thrust columns' coefficients and their replicates."""
    (c1, c2), rep = fit["theta"][:2], fit["theta_r"][:, :2]
    weight = mass_kg * G
    th = float(_hover(c1, c2, weight))
    if not np.isfinite(th) or c1 + c2 <= 0:
        raise IdentifyError(f"the fitted thrust map (F_max (1 - e) = {c1:.2f} N, F_max e = {c2:.2f} N) "
                            f"does not hold {mass_kg:g} kg at a thrust in (0, 1]: is it the vehicle "
                            "file the flight was flown with?")
    th_r = _hover(rep[:, 0], rep[:, 1], weight)
    th_r = np.where(np.isfinite(th_r), th_r, np.where(rep.sum(axis=1) > 0, 1.0, 0.0))   # off the map: an edge
    fmax_r = rep.sum(axis=1)
    e_r = rep[:, 1] / np.where(fmax_r != 0, fmax_r, np.nan)
    return (interval(th, th_r), interval(float(c2 / (c1 + c2)), e_r[np.isfinite(e_r)]),
            interval(float(c1 + c2), fmax_r))


def _rate_axis(P: Regressors, command: np.ndarray, axes: tuple, o: FitOptions, link_part_s: float,
               rows: np.ndarray, least_rms_rad_s: float = _MIN_RATE_RMS_RAD_S) -> RateAxis:
    """The rate loop about ``axes`` (one, or several sharing tau and D), on ``rows``."""
    cmd = command[rows][:, list(axes)]
    spread = float(np.sqrt(np.mean((cmd - cmd.mean(axis=0)) ** 2)))
    if spread < least_rms_rad_s:
        why = f"commanded rate RMS {spread:.3f} rad/s < {least_rms_rad_s:g}: the flight does not turn about it"
        none = Estimate(None, why=why)
        return RateAxis(none, none, none, float("nan"), float("nan"), float("nan"), spread)
    R = _RateRows(P, command, axes, rows)
    cols = list(range(len(axes)))
    fit = fit_columns(R, cols, o, known=np.ones(1))
    tau, delay = lag_estimates(fit, o, what="rate loop")
    if delay.value is None:
        loop = delay
    else:
        loop = Estimate(max(0.0, delay.value - link_part_s), max(0.0, delay.low - link_part_s),
                        max(0.0, delay.high - link_part_s))
    rms, r2 = fit_quality(R.y / P.h, fit["resid"] / P.h)
    free = float(ColumnModel(R, cols).solve(fit["tau"], fit["delay"])[0][0])
    return RateAxis(tau, delay, loop, free, rms, r2, spread)
