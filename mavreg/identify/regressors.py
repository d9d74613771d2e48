r"""The flight as regressors of the calibration model (:mod:`mavreg.identify.fit`); pure numpy.

The samples go on a uniform grid (gaps up to ``max_gap_s`` interpolated, the attitude through
sign-continuous quaternions), the usable samples are found (armed and OFFBOARD, above the
ground, the command stream alive, the whole filter window inside), and each term of the model
is integrated over every sample interval and filtered with the kernel :math:`E` of the
Savitzky-Golay derivative of the velocity (see :mod:`mavreg.identify.fit`). The thrust columns
(one per command channel: the rotor sum, or the rates output's t and t^2) depend on
:math:`(\tau, D)` and are rebuilt on demand (:meth:`Regressors.thrust_columns`); the drag
columns are built once (with a thrust-dependent rotor-plane drag, ``FitOptions.rotor_drag_thrust_exponent``,
the body x and y columns carry its factor at the measured specific force).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter, savgol_coeffs, savgol_filter

from ..config.vehicle import G
from ..model.drag import rotor_plane_scale
from ..model.rotation import quats_to_matrices

__all__ = ["FlightSeries", "IdentifyError", "Regressors", "lagged_integrals", "rotor_channels", "G"]
GAP_PERIODS = 3
"""By default a telemetry gap of up to this many sample periods (or 10 ms) is interpolated."""



class IdentifyError(ValueError):
    """The flight cannot calibrate the vehicle (no usable data, too short); one line."""


@dataclass(frozen=True)
class FlightSeries:
    """A flight as the fit needs it (numbers only; :func:`mavreg.identify.flightlog.read_flight`)."""

    t_s: np.ndarray
    """(N,) sample times on the vehicle clock, increasing."""
    position_ned_m: np.ndarray
    velocity_ned_m_s: np.ndarray
    quaternion_wxyz: np.ndarray
    """(N, 4) attitude, body FRD to NED, scalar first."""
    controlled: np.ndarray
    """(N,) bool: armed and in OFFBOARD (the vehicle obeys the commands)."""
    command_t_s: np.ndarray
    """(K,) vehicle time of the sample each command answered, in the order sent."""
    command_controls: np.ndarray
    """(K, 4) the commands as sent: ``output`` rotors, each rotor's force as a fraction of the
    maximum rotor thrust; ``output`` rates, the body roll, pitch and yaw rates (rad/s, FRD)
    and the normalized collective thrust in [0, 1]."""
    link_delay_s: float | None = None
    """Sample-to-actuation delay measured by TIMESYNC, if the flight has it."""
    output: str = "rotors"
    """What the commands are: ``rotors`` (SET_ACTUATOR_CONTROL_TARGET) or ``rates``
    (SET_ATTITUDE_TARGET body rates and thrust)."""
    body_rates_rad_s: np.ndarray | None = None
    """(N, 3) the measured body rates p, q, r (rad/s, FRD) of each sample, if known."""
    excitation_windows_s: tuple = ()
    """((start, end), ...) vehicle times of the identification flight's rate doublets
    (the daemon's ``mavreg excitation: start:`` and ``end:`` STATUSTEXTs; none: empty)."""


def rotor_channels(s: FlightSeries, max_rotor_thrust_n: float) -> np.ndarray:
    """(K, 1) the summed rotor command (N) of each command, each rotor clipped to [0, 1] of
    its maximum as the vehicle clips it: the thrust channel of the rotor output."""
    u = np.asarray(s.command_controls, float).reshape(np.size(s.command_t_s), -1)
    return (np.clip(u, 0.0, 1.0).sum(axis=1) * max_rotor_thrust_n)[:, None]


class Regressors:
    """The flight on a uniform grid: acceleration rows ``y`` (rows, 3) less gravity, the drag
    columns ``fixed`` (rows, 3, 4: c_x, c_y, c_z, c_p) and the thrust columns on demand.

    Parameters
    ----------
    s : FlightSeries
    mass_kg : float
    channels : ndarray (K, m)
        Per command, the m inputs whose lagged, delayed values times the thrust direction
        over the mass are the thrust columns: the summed rotor force (N,
        :func:`rotor_channels`), or the normalized thrust t and t^2 of the rates output.
    o : mavreg.identify.fit.FitOptions
        Its ``window``, ``polyorder``, ``min_height_m``, ``max_gap_s``, ``command_timeout_s``
        and ``min_duration_s``.

    Raises
    ------
    IdentifyError
        Bad shapes, too few samples, no command on the telemetry's clock, or less than
        ``min_duration_s`` of usable flight.
    """

    def __init__(self, s: FlightSeries, mass_kg: float, channels: np.ndarray, o):
        t, p, v, q, ctrl, kept = _clean(s)
        if t.size < o.window + 2:
            raise IdentifyError(f"only {t.size} usable telemetry samples; a calibration needs seconds of flight")
        h = float(np.median(np.diff(t)))
        idx = np.rint((t - t[0]) / h).astype(int)
        keep = np.concatenate([[True], np.diff(idx) > 0])
        idx, t, p, v, q, ctrl = idx[keep], t[keep], p[keep], v[keep], _continuous(q[keep]), ctrl[keep]
        n = int(idx[-1]) + 1
        self.h, self.n, self.mass = h, n, mass_kg
        grid = np.arange(n)

        def on_grid(a):
            return np.stack([np.interp(grid, idx, a[:, k]) for k in range(a.shape[1])], axis=1)
        v, pos, R = on_grid(v), on_grid(p), quats_to_matrices(on_grid(q))
        self.rates = None if s.body_rates_rad_s is None else on_grid(_body_rates(s, kept)[keep])
        """(n, 3) the measured body rates on the grid, if the flight has them."""
        # good: measured or inside a short gap, controlled, airborne, commands streaming
        k = np.searchsorted(idx, grid, side="right") - 1
        gap = np.append(np.diff(idx), 1)[k]
        max_gap_s = max(0.01, GAP_PERIODS * h) if o.max_gap_s is None else o.max_gap_s
        near = (grid == idx[k]) | (gap * h <= max_gap_s + 1e-9)
        airborne = pos[:, 2] < _ground_z(p[:, 2], ctrl) - o.min_height_m
        self.t0 = float(t[0])
        self.held, alive = self.hold(s.command_t_s, channels, o.command_timeout_s)
        good = near & ctrl[k] & airborne & alive
        # rows j whose whole window j-M-1 .. j+M is good, M = window // 2
        W = o.window
        self.M = M = W // 2
        self.d = savgol_coeffs(W, o.polyorder, deriv=1, delta=h, use="dot")
        self.E = np.cumsum(self.d[::-1])[::-1]
        span = np.convolve(good.astype(int), np.ones(W + 1, int), mode="valid") == W + 1
        rows = np.flatnonzero(span) + M + 1             # span[i] covers i .. i + W
        self.rows = rows[rows <= n - 1 - M]
        if self.rows.size * h < o.min_duration_s:
            raise IdentifyError(
                f"only {self.rows.size * h:.2f} s of usable flight (armed, OFFBOARD, {o.min_height_m:g} m "
                f"above the ground, commanded); a calibration needs at least {o.min_duration_s:g} s")
        self.dir = -(R[:-1, :, 2] + R[1:, :, 2]) / 2.0          # mean thrust direction per interval
        vb = np.einsum("nji,nj->ni", R, v)                        # R^T v
        self.vbody_rows = vb[self.rows]
        self.y = self._deriv(v) - np.array([0.0, 0.0, G])
        cols = [-R[:, :, k] * vb[:, k:k + 1] / mass_kg for k in range(3)]
        e = float(getattr(o, "rotor_drag_thrust_exponent", 0.0))
        if e:                        # c_x, c_y at the thrust flown: T / m from the specific force
            acc = savgol_filter(v, W, o.polyorder, deriv=1, delta=h, axis=0)
            scale = rotor_plane_scale(np.linalg.norm(acc - np.array([0.0, 0.0, G]), axis=1), G, e)[:, None]
            cols[0], cols[1] = cols[0] * scale, cols[1] * scale
        cols.append(-np.linalg.norm(v, axis=1)[:, None] * v / mass_kg)
        self.fixed = np.stack([self._filtered(h / 2 * (c[:-1] + c[1:])) for c in cols], axis=-1)

    def hold(self, command_t_s, values, timeout_s: float):
        """Commands (K, m) on the grid, each held from its slot until the next one (the last
        sent wins a slot; zero before the first), and 'alive' (n,): a command in the last
        ``timeout_s``. IdentifyError when none is on the telemetry's clock."""
        ct = np.asarray(command_t_s, float).ravel()
        u = np.asarray(values, float).reshape(ct.size, -1)
        ok = np.isfinite(ct) & np.all(np.isfinite(u), axis=1)
        slot = np.rint((ct[ok] - self.t0) / self.h).astype(int)
        order = np.flatnonzero(ok)
        inside = (slot >= 0) & (slot < self.n)
        if not inside.any():
            raise IdentifyError("no command could be placed on the telemetry's clock")
        last = np.full(self.n, -1)
        np.maximum.at(last, slot[inside], order[inside])      # the last one sent wins a slot
        which = np.maximum.accumulate(last)                   # the last sent among those due
        held = np.where((which >= 0)[:, None], u[np.maximum(which, 0)], 0.0)
        grid = np.arange(self.n)
        latest = np.maximum.accumulate(np.where(last >= 0, grid, -1))
        alive = (latest >= 0) & ((grid - latest) * self.h <= timeout_s + 1e-9)
        return held, alive

    def _deriv(self, v: np.ndarray) -> np.ndarray:
        """The Savitzky-Golay derivative of v (n, 3) at the rows: (rows, 3)."""
        return _correlate(v, self.d)[self.rows - self.M]

    def _filtered(self, g: np.ndarray) -> np.ndarray:
        """Interval integrals g (n-1, 3) filtered with E at the rows: (rows, 3)."""
        return _correlate(g, self.E)[self.rows - self.M - 1]

    def thrust_columns(self, tau_s: float, delay_s: float) -> np.ndarray:
        """(rows, 3, m): per channel, the filtered integral of (lagged, delayed channel)
        (-R e3) / m."""
        cols = [lagged_integrals(self.held[:, c], self.h, tau_s, delay_s) for c in range(self.held.shape[1])]
        return np.stack([self._filtered(F[:, None] * self.dir / self.mass) for F in cols], axis=-1)


def _correlate(a: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """out[i] = sum_k kernel[k] a[i + k] per column ('valid'). np.correlate, not BLAS: a
    threaded BLAS on a loaded machine made this call ten times slower."""
    return np.stack([np.correlate(a[:, c], kernel, mode="valid") for c in range(a.shape[1])], axis=1)


def _clean(s: FlightSeries):
    """Finite samples of increasing time with a usable quaternion, and the indices of those
    kept; IdentifyError on bad shapes."""
    t = np.asarray(s.t_s, float).ravel()
    arrays = []
    for name, a, w in (("position_ned_m", s.position_ned_m, 3), ("velocity_ned_m_s", s.velocity_ned_m_s, 3),
                       ("quaternion_wxyz", s.quaternion_wxyz, 4)):
        a = np.asarray(a, float)
        if a.shape != (t.size, w):
            raise IdentifyError(f"{name} has shape {a.shape}, expected ({t.size}, {w})")
        arrays.append(a)
    ctrl = np.asarray(s.controlled, bool).ravel()
    if ctrl.size != t.size:
        raise IdentifyError(f"controlled has {ctrl.size} values for {t.size} samples")
    p, v, q = arrays
    ok = (np.isfinite(t) & np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(v), axis=1)
          & np.all(np.isfinite(q), axis=1) & (np.linalg.norm(np.nan_to_num(q), axis=1) > 0.5))
    kept = np.flatnonzero(ok)
    if kept.size:
        tk = t[kept]
        kept = kept[np.concatenate([[True], tk[1:] > np.maximum.accumulate(tk)[:-1]])]
    return t[kept], p[kept], v[kept], q[kept], ctrl[kept], kept


def _body_rates(s: FlightSeries, kept: np.ndarray) -> np.ndarray:
    """The body rates of the samples ``kept`` (indices; non-finite: 0)."""
    n = np.asarray(s.t_s).size
    w = np.asarray(s.body_rates_rad_s, float)
    if w.shape != (n, 3):
        raise IdentifyError(f"body_rates_rad_s has shape {w.shape}, expected ({n}, 3)")
    return np.nan_to_num(w[kept])


def _ground_z(z: np.ndarray, controlled: np.ndarray) -> float:
    """The ground's z: the median of the samples before the vehicle first obeyed the commands
    (on the ground, disarmed), else of those after it last did; +inf (all airborne) if none."""
    on = np.flatnonzero(controlled)
    if on.size == 0:
        return float(np.median(z))
    before, after = z[:on[0]], z[on[-1] + 1:]
    if before.size:
        return float(np.median(before))
    return float(np.median(after)) if after.size else np.inf


def _continuous(q: np.ndarray) -> np.ndarray:
    """Quaternions with the sign flipped where needed so that neighbours agree (q ~ -q)."""
    flip = np.sum(q[1:] * q[:-1], axis=1) < 0
    sign = np.concatenate([[1.0], np.where(np.cumsum(flip) % 2 == 1, -1.0, 1.0)])
    return q * sign[:, None]


def lagged_integrals(c: np.ndarray, h: float, tau_s: float, delay_s: float) -> np.ndarray:
    r"""Exact integrals over each sample interval of a delayed, lagged piecewise-constant input.

    ``c[k]`` acts from :math:`t_k + D` to :math:`t_{k+1} + D` (zero before ``c[0]``); the output
    obeys :math:`\tau\dot f = c(t - D) - f`, :math:`f(t_0) = 0`. With :math:`D = nh + \delta`,
    over :math:`[t_i, t_{i+1}]` the input is :math:`c_{i-n-1}` for :math:`\delta`, then
    :math:`c_{i-n}`, so :math:`f_{i+1} = A f_i + (B - A) c_{i-n-1} + (1 - B) c_{i-n}` with
    :math:`A = e^{-h/\tau}`, :math:`B = e^{-(h-\delta)/\tau}`, and the integral is
    :math:`\int f = \delta c_{i-n-1} + (h-\delta) c_{i-n} - \tau (f_{i+1} - f_i)`.

    Returns
    -------
    ndarray (len(c) - 1,)
    """
    n_int = int(np.floor(delay_s / h + 1e-9))
    delta = max(0.0, delay_s - n_int * h)
    m = c.size - 1
    pad = np.concatenate([np.zeros(n_int + 1), c])
    cp = pad[1:1 + m]               # c_{i-n}
    cpp = pad[:m]                   # c_{i-n-1}
    held = delta * cpp + (h - delta) * cp
    if tau_s <= 0.0:
        return held
    A = np.exp(-h / tau_s)
    B = np.exp(-(h - delta) / tau_s)
    f_next = lfilter([1.0], [1.0, -A], (B - A) * cpp + (1.0 - B) * cp)
    f = np.concatenate([[0.0], f_next[:-1]])
    return held - tau_s * (f_next - f)
