r"""Calibrate a vehicle from one flight: thrust scale, body drag, rotor time constant, delay.

Pure numpy/scipy: arrays in, numbers out (:mod:`mavreg.identify.flightlog` reads the files).

**Model.** Translational dynamics in NED with the measured attitude :math:`R` (body to NED)
and velocity :math:`v`:

.. math::
    m\dot v = s_T \Big(\sum_i f_i\Big)(-R e_3) + m g e_3 - R\,\mathrm{diag}(c_x, c_y, c_z)R^T v
              \;[-\,c_p |v| v],

:math:`f_i` the rotor commands (``controls`` times the maximum rotor thrust) delayed by
:math:`D` (sample time to the rotors, on the vehicle clock) and passed through a first-order
lag :math:`\tau\dot f = c - f`, discretized exactly for a piecewise-constant input that
switches anywhere inside a sample interval; :math:`s_T` is the thrust scale (actual thrust
per unit commanded). The drag is the emulator's body-frame linear drag with no wind; the
quadratic parasitic term is kept only when the flight shows it (its 95 % interval excludes 0).

**Equation error without differentiating the model.** The acceleration is the
Savitzky-Golay derivative :math:`y_j = \sum_k d_k v_{j+k}` of the velocity. Since
:math:`\sum_k d_k = 0`, :math:`y_j = \sum_m E_m \Delta v_{j+m}` with :math:`E_m =
\sum_{k\ge m} d_k`, and :math:`\Delta v_i = \int_{t_{i-1}}^{t_i} \dot v\,dt` exactly. So each
regressor is integrated over every sample interval (the lagged thrust exactly, the others by
the trapezoid rule) and filtered with the same kernel :math:`E`: both sides of the equation
see the same linear filter, with no lag or bias between them.

**Fit.** For fixed :math:`(\tau, D)` the model is linear in :math:`\theta = (s_T, c_x, c_y,
c_z[, c_p])`: least squares over all three axes of every usable sample (armed, OFFBOARD,
airborne, command stream alive, whole filter window inside). :math:`(\tau, D)` minimize the
residual over a grid, then :math:`\tau` is refined by a bounded 1-D search on a fine grid of
:math:`D`. Only the thrust column depends on :math:`(\tau, D)`; the rest is projected out once
(Frisch-Waugh).

**Intervals.** The residuals are correlated in time (estimator errors, the filter), so the
LS covariance is far too narrow. 95 % intervals come from a moving-block bootstrap: blocks of
consecutive samples (at least ``block_s``, 1 s; three integrated autocorrelation times of
the residuals' scores if longer) drawn with replacement, every parameter, :math:`\tau` and
:math:`D` included, re-estimated on each replicate (on a local :math:`(\tau, D)` grid around
the estimate with a parabolic vertex between grid points, from per-chunk sums of the normal
equations). A parameter whose interval runs into the edge of that grid or is wider than
itself (``tau``) is reported as not identified, as is a drag axis the flight did not move
along (RMS body speed under ``min_drag_speed_m_s``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from .bootstrap import BlockBootstrap, block_length_rows
from .estimates import Estimate, drag_estimates, fit_quality, interval, intervals_text, lag_estimates
from .regressors import FlightSeries, IdentifyError, Regressors, lagged_integrals, rotor_channels

__all__ = ["FlightSeries", "FitOptions", "Estimate", "Identification", "IdentifyError", "identify",
           "lagged_integrals"]

_MIN_FIT_SPEED_M_S = 0.05
"""A drag axis slower than this (RMS) is left out of the fit (its column would be all noise)."""


@dataclass(frozen=True)
class FitOptions:
    """Settings of :func:`identify` (defaults suit 500 Hz telemetry)."""

    min_height_m: float = 0.3
    """Samples closer to the ground than this are left out (the ground: the median height of
    the samples before the vehicle first obeyed the commands)."""
    window: int = 21
    """Savitzky-Golay window (samples, odd)."""
    polyorder: int = 3
    tau_max_s: float = 0.1
    delay_max_s: float = 0.08
    delay_s: float | None = None
    """A known sample-to-rotor delay; None: estimated jointly with tau."""
    parasitic: str = "auto"
    """'auto' (kept when significant), 'yes' or 'no'."""
    replicates: int = 300
    seed: int = 0
    min_duration_s: float = 3.0
    min_drag_speed_m_s: float = 0.5
    """Body-axis RMS speed below which that axis' drag is reported as not identified (it is
    still fitted, above 0.05 m/s, so that its force is not blamed on the other terms)."""
    block_s: float = 1.0
    """Shortest bootstrap block; longer when the residuals' scores remember longer."""
    max_gap_s: float | None = None
    """Telemetry gaps up to this are interpolated; longer ones cut the data. None: 10 ms, or
    :data:`~mavreg.identify.regressors.GAP_PERIODS` telemetry periods where that is longer
    (PX4 asked for 200 Hz sends every 8 ms with gaps of 16-24 ms in one sample of twenty: at
    10 ms those cut a flight's 48.6 s of usable data to 5.7 s)."""
    command_timeout_s: float = 0.1
    """Samples this long after the last command are left out (the stream stopped)."""
    grid_steps_s: tuple[float, float] = (0.005, 0.002)
    """Steps of the coarse (tau, D) grid the search starts from."""
    delay_needs_margin: bool = False
    """A delay at 0 is the edge of the search, not a value (the rate loop: a response no later
    than its sample is a lag and delay traded for each other, not a measurement)."""
    rate_tau_max_s: float = 0.15
    """Rates output: the longest rate-loop time constant searched."""
    rate_delay_max_s: float = 0.1
    """Rates output: the longest sample-to-rate-response delay searched."""
    rate_window: str = "auto"
    """Rates output: the samples the rate loop is fitted on. 'auto': the identification
    excitation's doublets when the flight has them (and 0.5 s after), else all; 'all'."""
    rotor_drag_thrust_exponent: float = 0.0
    """e of the rotor-plane drag c_xy (T / m g)^e (the vehicle file's): the body x and y drag
    columns are scaled by it, T taken as the mass times the measured specific force, so that
    c_x, c_y come out as the coefficients in hover. 0: a constant coefficient."""


@dataclass(frozen=True)
class Identification:
    """What :func:`identify` found; see :meth:`as_dict` for the JSON form."""

    thrust_scale: Estimate
    drag_n_s_per_m: tuple[Estimate, Estimate, Estimate]
    drag_xy_n_s_per_m: Estimate
    """c_x and c_y combined (inverse-variance mean): the vehicle file's c_xy."""
    parasitic_n_s2_per_m2: Estimate
    rotor_time_constant_s: Estimate
    delay_s: Estimate
    model: str
    residual_rms_m_s2: float
    r_squared: float
    samples: int
    duration_s: float
    rms_body_speed_m_s: tuple[float, float, float]
    intervals: str
    link_delay_s: float | None

    def as_dict(self) -> dict:
        return {
            "model": self.model, "thrust_scale": self.thrust_scale.as_dict(),
            "drag_n_s_per_m": {k: e.as_dict() for k, e in zip("xyz", self.drag_n_s_per_m)},
            "drag_xy_n_s_per_m": self.drag_xy_n_s_per_m.as_dict(),
            "parasitic_drag_n_s2_per_m2": self.parasitic_n_s2_per_m2.as_dict(),
            "rotor_time_constant_s": self.rotor_time_constant_s.as_dict(),
            "delay_s": self.delay_s.as_dict(), "link_delay_timesync_s": self.link_delay_s,
            "residual_rms_m_s2": self.residual_rms_m_s2, "r_squared": self.r_squared,
            "samples": self.samples, "duration_s": self.duration_s,
            "rms_body_speed_m_s": list(self.rms_body_speed_m_s), "intervals": self.intervals,
        }


class ColumnModel:
    """Least squares of one column set for any (tau, D): the fixed columns projected out once.

    ``P`` gives ``y`` (rows, a), ``fixed`` (rows, a, all fixed columns), ``rows``, ``h`` and
    ``thrust_columns(tau, D)`` (rows, a, m): the m columns that depend on (tau, D) come
    first in theta. ``known`` (m,): their coefficients are these, not fitted."""

    def __init__(self, P, cols: list[int], known: np.ndarray | None = None):
        self.P, self.cols = P, list(cols)
        self.known = None if known is None else np.asarray(known, float)
        self.Z = P.fixed[:, :, self.cols]                       # (rows, a, k)
        Zf = self.Z.reshape(-1, len(self.cols))
        self.Q = np.linalg.qr(Zf)[0] if self.cols else np.zeros((Zf.shape[0], 0))
        y = P.y.reshape(-1)
        self.yt = y - self.Q @ (self.Q.T @ y)
        self.yy = float(np.dot(self.yt, self.yt))

    def rss(self, tau_s: float, delay_s: float) -> float:
        """Residual sum of squares at (tau, D); with Q orthonormal and yt orthogonal to it,
        X'X less its projection, and (X - QQ'X)'yt = X'yt (einsum: no threaded BLAS)."""
        X = self.P.thrust_columns(tau_s, delay_s)
        if self.known is not None:
            e = (self.P.y - X @ self.known).reshape(-1)
            qe = np.einsum("ij,i->j", self.Q, e)
            return float(np.einsum("i,i->", e, e) - np.einsum("j,j->", qe, qe))
        xs = [np.ascontiguousarray(X[..., c]).reshape(-1) for c in range(X.shape[-1])]
        qx = [np.einsum("ij,i->j", self.Q, x) for x in xs]
        xx = np.array([[np.einsum("i,i->", a, b) - np.einsum("j,j->", qa, qb) for b, qb in zip(xs, qx)]
                       for a, qa in zip(xs, qx)])
        xy = np.array([np.einsum("i,i->", x, self.yt) for x in xs])
        if xx.shape == (1, 1):
            return self.yy - xy[0] * xy[0] / xx[0, 0] if xx[0, 0] > 0 else self.yy
        try:
            fit = float(xy @ np.linalg.solve(xx, xy))
        except np.linalg.LinAlgError:
            return self.yy
        return self.yy - fit if np.isfinite(fit) and fit > 0 else self.yy

    def solve(self, tau_s: float, delay_s: float) -> tuple[np.ndarray, np.ndarray]:
        """theta (the thrust columns', then the fixed columns' coefficients) and residuals (rows, a)."""
        X = self.design(tau_s, delay_s)
        if self.known is None:
            theta = np.linalg.lstsq(X.reshape(-1, X.shape[-1]), self.P.y.reshape(-1), rcond=None)[0]
        else:
            m = self.known.size
            e = self.P.y - X[:, :, :m] @ self.known
            rest = np.linalg.lstsq(self.Z.reshape(-1, len(self.cols)), e.reshape(-1), rcond=None)[0]
            theta = np.concatenate([self.known, rest])
        return theta, self.P.y - X @ theta

    def design(self, tau_s: float, delay_s: float) -> np.ndarray:
        return np.concatenate([self.P.thrust_columns(tau_s, delay_s), self.Z], axis=2)


def _search(model: ColumnModel, o: FitOptions) -> tuple[float, float]:
    """(tau, D) of least residual: a coarse grid (steps ``o.grid_steps_s``), then tau by bounded
    search (1.5 steps either side) on a D grid of an eighth of its step (one step either side),
    moved along while the best D is at its end (a valley where lag and delay trade)."""
    ts, ds = o.grid_steps_s
    taus = np.arange(0.0, o.tau_max_s + 1e-9, ts)
    delays = (np.array([o.delay_s]) if o.delay_s is not None
              else np.arange(0.0, o.delay_max_s + 1e-9, ds))
    rss = np.array([[model.rss(ta, d) for d in delays] for ta in taus])
    i, j = np.unravel_index(np.argmin(rss), rss.shape)
    best = (rss[i, j], float(taus[i]), float(delays[j]))
    for _ in range(8):
        start = best
        tau0, d0 = best[1], best[2]
        fine = ([d0] if o.delay_s is not None
                else np.unique(np.clip(d0 + np.arange(-ds, ds * 1.005, ds / 8), 0.0, o.delay_max_s)))
        lo, hi = max(0.0, tau0 - 1.5 * ts), min(o.tau_max_s, tau0 + 1.5 * ts)
        for d in fine:
            r = minimize_scalar(lambda ta: model.rss(ta, d), bounds=(lo, hi), method="bounded",
                                options={"xatol": 1e-4})
            f, ta = min([(float(r.fun), float(r.x)), (model.rss(lo, d), lo)])
            if f < best[0]:
                best = (f, ta, float(d))
        d_inside = len(fine) < 3 or fine[0] < best[2] < fine[-1] or best[2] in (0.0, o.delay_max_s)
        t_inside = lo < best[1] < hi or best[1] in (0.0, o.tau_max_s)
        if best == start or (d_inside and t_inside):
            break
    return best[1], best[2]


def _bootstrap(model: ColumnModel, tau: float, delay: float, o: FitOptions, resid: np.ndarray, zoom: float = 1.0):
    """Replicates of (theta, tau, D) on a local (tau, D) grid (tau +- 12 ms, D +- 5 ms, times
    ``zoom``); returns them, the shares of replicates at an edge of the grid, the bootstrap."""
    P = model.P
    taus = np.unique(np.clip(tau + 0.001 * zoom * np.arange(-12, 13), 0.0, o.tau_max_s))
    delays = (np.array([delay]) if o.delay_s is not None
              else np.unique(np.clip(delay + 0.0005 * zoom * np.arange(-10, 11), 0.0, o.delay_max_s)))
    scores = np.einsum("rai,ra->ri", model.design(tau, delay), resid)
    block = block_length_rows(scores, factor=3.0, min_rows=int(round(o.block_s / P.h)))
    bs = BlockBootstrap(P.rows.size, max(1, int(round(0.1 / P.h))), block, o.replicates, o.seed)
    Z, y = model.Z, P.y
    k = Z.shape[2]
    zz = bs.replicate_sums(bs.chunk_sums(np.einsum("rai,raj->rij", Z, Z)))      # (R, k, k)
    zy = bs.replicate_sums(bs.chunk_sums(np.einsum("rai,ra->ri", Z, y)))        # (R, k)
    yy = bs.replicate_sums(bs.chunk_sums(np.einsum("ra,ra->r", y, y)))          # (R,)
    grid = [(ta, d) for ta in taus for d in delays]
    cross = []                                    # per grid point, chunk sums of X'X, X'Z, X'y
    for ta, d in grid:
        X = P.thrust_columns(ta, d)
        xs = [np.ascontiguousarray(X[..., c]) for c in range(X.shape[2])]
        feats = [np.einsum("ra,ra->r", a, b) for a in xs for b in xs]
        feats += [np.einsum("ra,rai->ri", a, Z) for a in xs] + [np.einsum("ra,ra->r", a, y) for a in xs]
        cross.append(bs.chunk_sums(np.column_stack(feats)))
    m = X.shape[2]
    cr = bs.replicate_sums(np.stack(cross, axis=1))                    # (R, G, m m + m k + m)
    Rn, Gn = cr.shape[0], cr.shape[1]
    xx = cr[:, :, :m * m].reshape(Rn, Gn, m, m)
    xz = cr[:, :, m * m:m * m + m * k].reshape(Rn, Gn, m, k)
    xy = cr[:, :, m * m + m * k:]
    if model.known is None:
        theta, rss = _replicate_solve(xx, xz, xy, zz, zy, yy)
    else:
        gk = model.known
        ee = yy[:, None] - 2 * xy @ gk + np.einsum("rgmn,m,n->rg", xx, gk, gk)       # |y - X g|^2
        theta_z, fit = _normal_solve(np.broadcast_to(zz[:, None], (Rn, Gn, k, k)),
                                     zy[:, None] - np.einsum("rgmk,m->rgk", xz, gk))
        theta = np.concatenate([np.broadcast_to(gk, (Rn, Gn, m)), theta_z], axis=2)
        rss = ee - fit
    g = np.argmin(rss, axis=1)
    surf = rss.reshape(Rn, taus.size, delays.size)
    i, j = np.divmod(g, delays.size)
    t_r = taus[i] + _vertex(surf, i, j, 1, taus)
    d_r = delays[j] + _vertex(surf, i, j, 2, delays)
    edge_tau = np.mean(((i == 0) & (taus[0] > 0)) | ((i == taus.size - 1) & (taus[-1] < o.tau_max_s)))
    edge_d = np.mean(((j == 0) & ((delays[0] > 0) | o.delay_needs_margin)) | ((j == delays.size - 1) & (delays[-1] < o.delay_max_s))) \
        if o.delay_s is None else 0.0
    return theta[np.arange(Rn), g], t_r, d_r, float(edge_tau), float(edge_d), bs


def _replicate_solve(xx, xz, xy, zz, zy, yy):
    """Every replicate's and grid point's least squares from its sums: (theta, rss)."""
    Rn, Gn, m, k = xz.shape
    A = np.empty((Rn, Gn, m + k, m + k))
    A[:, :, :m, :m] = xx
    A[:, :, :m, m:] = xz
    A[:, :, m:, :m] = np.swapaxes(xz, 2, 3)
    A[:, :, m:, m:] = zz[:, None]
    b = np.concatenate([xy, np.broadcast_to(zy[:, None], (Rn, Gn, k))], axis=2)
    theta, fit = _normal_solve(A, b)
    return theta, yy[:, None] - fit


def _normal_solve(A, b):
    """theta = A^-1 b and theta'b for stacks of normal equations (regularized a hair: no
    singular replicate)."""
    n = A.shape[-1]
    if n == 0:
        return np.zeros(b.shape), np.zeros(b.shape[:-1])
    A = A + 1e-12 * np.trace(A, axis1=-2, axis2=-1)[..., None, None] * np.eye(n)
    theta = np.linalg.solve(A, b[..., None])[..., 0]
    return theta, np.einsum("...i,...i->...", theta, b)


def _vertex(surf: np.ndarray, i: np.ndarray, j: np.ndarray, axis: int, values: np.ndarray) -> np.ndarray:
    """Sub-grid offset of each replicate's minimum along one axis (parabola through 3 points)."""
    k = i if axis == 1 else j
    n = values.size
    if n < 3:
        return np.zeros(k.size)
    c = np.clip(k, 1, n - 2)
    r = np.arange(k.size)
    at = (lambda m: surf[r, m, j]) if axis == 1 else (lambda m: surf[r, i, m])
    lo, mid, hi = at(c - 1), at(c), at(c + 1)
    curv = lo - 2 * mid + hi
    off = np.where(curv > 0, 0.5 * (lo - hi) / np.where(curv > 0, curv, 1.0), 0.0)
    off = np.clip(off + (c - k), -0.5, 0.5) * ((k > 0) & (k < n - 1))
    return off * (values[1] - values[0])


def fit_columns(P, cols: list[int], o: FitOptions, known: np.ndarray | None = None) -> dict:
    """Search (tau, D), solve, bootstrap: the fit of one column set (theta: the m thrust
    columns' coefficients, ``known`` if given, then ``cols``')."""
    model = ColumnModel(P, cols, known)
    tau, delay = _search(model, o)
    theta, resid = model.solve(tau, delay)
    for zoom in (1.0, 2.0, 4.0):               # widen the local grid until the replicates fit in
        th_r, t_r, d_r, edge_tau, edge_d, bs = _bootstrap(model, tau, delay, o, resid, zoom)
        if max(edge_tau, edge_d) <= 0.025:
            break
    return {"cols": cols, "m": theta.size - len(cols), "tau": tau, "delay": delay, "theta": theta,
            "resid": resid, "theta_r": th_r, "tau_r": t_r, "delay_r": d_r, "edge_tau": edge_tau,
            "edge_delay": edge_d, "bs": bs}


def checked_options(options: FitOptions | None) -> FitOptions:
    """The options (defaults if None); IdentifyError (one line) on a bad filter or parasitic."""
    o = options if options is not None else FitOptions()
    if o.window < 5 or o.window % 2 == 0 or not 1 <= o.polyorder < o.window - 1:
        raise IdentifyError(f"the filter window must be odd and at least 5 (got {o.window}), "
                            f"its polynomial order 1..window-2 (got {o.polyorder})")
    if o.parasitic not in ("auto", "yes", "no"):
        raise IdentifyError(f"parasitic must be auto, yes or no, got {o.parasitic!r}")
    if o.rate_window not in ("auto", "all"):
        raise IdentifyError(f"rate window must be auto or all, got {o.rate_window!r}")
    return o


def translational_fit(P: Regressors, o: FitOptions) -> tuple[dict, tuple]:
    """The thrust columns with the drag the flight excites (the parasitic term kept when
    significant, by ``o.parasitic``): (:func:`fit_columns`'s dict, RMS body speed x y z)."""
    speed = tuple(float(s) for s in np.sqrt(np.mean(P.vbody_rows ** 2, axis=0)))
    axes = [k for k in range(3) if speed[k] >= _MIN_FIT_SPEED_M_S]
    excited = any(speed[k] >= o.min_drag_speed_m_s for k in axes)
    cols = axes + ([3] if excited and o.parasitic != "no" else [])
    fit = fit_columns(P, cols, o)
    if 3 in cols and o.parasitic == "auto" and np.percentile(fit["theta_r"][:, -1], 2.5) <= 0.0:
        fit = fit_columns(P, axes, o)
    return fit, speed


def identify(series: FlightSeries, mass_kg: float, max_rotor_thrust_n: float,
             options: FitOptions | None = None) -> Identification:
    """Fit thrust scale, drag, rotor time constant and delay to one flight (module docstring).

    Parameters
    ----------
    series : FlightSeries
        A flight of the rotor output (:func:`mavreg.identify.rate_fit.identify_rates` fits
        one of the rates output).
    mass_kg, max_rotor_thrust_n : float
        The vehicle file's values: the commands are fractions of the maximum rotor thrust and
        the forces are divided by the mass (a wrong mass shows as a thrust scale).
    options : FitOptions, optional

    Raises
    ------
    IdentifyError
        One line, when the flight has too little usable data.
    """
    o = checked_options(options)
    if series.output != "rotors":
        raise IdentifyError(f"this flight's commands are {series.output}, not rotor forces")
    P = Regressors(series, mass_kg, rotor_channels(series, max_rotor_thrust_n), o)
    fit, speed = translational_fit(P, o)
    th = fit["theta"][0], fit["theta_r"][:, 0]
    drag, drag_xy, parasitic, model = drag_estimates(fit, speed, o)
    tau, delay = lag_estimates(fit, o)
    rms, r2 = fit_quality(P.y, fit["resid"])
    return Identification(
        thrust_scale=interval(*th), drag_n_s_per_m=drag, drag_xy_n_s_per_m=drag_xy,
        parasitic_n_s2_per_m2=parasitic, rotor_time_constant_s=tau, delay_s=delay, model=model,
        residual_rms_m_s2=rms, r_squared=r2, samples=int(P.rows.size), duration_s=float(P.rows.size * P.h),
        rms_body_speed_m_s=speed, intervals=intervals_text(fit["bs"], P.h, o), link_delay_s=series.link_delay_s)
