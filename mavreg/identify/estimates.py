"""What the identification fits report: values with 95 % intervals, and the pieces of a
fit's report shared by both outputs (drag, the lag and its delay, the fit's quality).

Pure numpy; the fit dicts are :func:`mavreg.identify.fit.fit_columns`'s, ``o`` its
:class:`~mavreg.identify.fit.FitOptions`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Estimate", "interval", "drag_estimates", "lag_estimates", "fit_quality", "intervals_text"]


@dataclass(frozen=True)
class Estimate:
    """A value with its 95 % bootstrap interval; ``value`` None: not identified (``why``)."""

    value: float | None
    low: float | None = None
    high: float | None = None
    why: str = ""

    def as_dict(self) -> dict:
        if self.value is None:
            return {"value": None, "why": self.why}
        return {"value": self.value, "ci95": [self.low, self.high]}


def interval(value: float, samples: np.ndarray) -> Estimate:
    lo, hi = np.percentile(samples, [2.5, 97.5])
    return Estimate(float(value), float(min(lo, value)), float(max(hi, value)))


def drag_estimates(fit: dict, speed, o):
    """(drag x y z, drag_xy, parasitic, model name) of a :func:`translational_fit`."""
    cols, m, theta, th_r = fit["cols"], fit["m"], fit["theta"], fit["theta_r"]
    est = {c: interval(theta[i + m], th_r[:, i + m]) for i, c in enumerate(cols)
           if c == 3 or speed[c] >= o.min_drag_speed_m_s}
    slow = [Estimate(None, why=f"body {a} speed RMS {speed[k]:.2f} m/s < {o.min_drag_speed_m_s:g} m/s")
            for k, a in enumerate("xyz")]
    drag = tuple(est.get(k, slow[k]) for k in range(3))
    if 0 in est and 1 in est:
        i, j = cols.index(0) + m, cols.index(1) + m
        vx, vy = np.var(th_r[:, i]), np.var(th_r[:, j])
        wx = vy / (vx + vy) if vx + vy > 0 else 0.5
        drag_xy = interval(wx * theta[i] + (1 - wx) * theta[j], wx * th_r[:, i] + (1 - wx) * th_r[:, j])
    else:
        drag_xy = next((drag[k] for k in (0, 1) if k in est),
                       Estimate(None, why=f"{slow[0].why}, {slow[1].why}"))
    if 3 in cols:
        return drag, drag_xy, est[3], "linear body drag + parasitic |v| v"
    why = ("not fitted (--parasitic no)" if o.parasitic == "no" else
           "no drag axis is excited" if not any(k in est for k in range(3))
           else "not significant: its 95 % interval includes 0")
    model = "linear body drag" if any(k in est for k in range(3)) else "no drag (too slow)"
    return drag, drag_xy, Estimate(None, why=why), model


def lag_estimates(fit: dict, o, what: str = "rotor lag") -> tuple[Estimate, Estimate]:
    """(tau, D) of a fit: not identified when tau's interval runs into the grid's edge or is
    wider than tau (or 10 ms); D given, searched with tau, or not identified with it."""
    tau = interval(fit["tau"], fit["tau_r"])
    if fit["edge_tau"] > 0.025 or fit["edge_delay"] > 0.025 or tau.high - tau.low > max(tau.value, 0.01):
        tau = Estimate(None, why=f"the flight does not excite the {what} (95 % interval "
                                 f"{1e3 * tau.low:.0f}-{1e3 * tau.high:.0f} ms or wider"
                                 f"{', delay not pinned' if fit['edge_delay'] > 0.025 else ''})")
    if o.delay_s is not None:
        return tau, Estimate(o.delay_s, o.delay_s, o.delay_s, why="given")
    if tau.value is None:
        return tau, Estimate(None, why=f"searched with the {what}, which the flight does not excite")
    return tau, interval(fit["delay"], fit["delay_r"])


def fit_quality(y: np.ndarray, resid: np.ndarray) -> tuple[float, float]:
    """(residual RMS, R^2) of a fit's rows."""
    rss = float(np.sum(resid ** 2))
    tss = float(np.sum((y - y.mean(axis=0)) ** 2))
    return float(np.sqrt(rss / resid.size)), (1.0 - rss / tss if tss > 0 else 0.0)


def intervals_text(bs, h: float, o) -> str:
    return (f"moving-block bootstrap, {o.replicates} replicates, blocks of {bs.block_rows * h:.2f} s "
            f"({bs.n_blocks} per replicate), every parameter re-estimated")
