r"""Time-varying LQR on the full state, indexed by time: the classical trajectory tracker.

Along the timed nominal :math:`\bar x(t), \bar u(t)` (:class:`~.timed.TimedNominal`) the error
:math:`e = x - \bar x(t)` (angle differences wrapped to :math:`(-\pi, \pi]`) obeys, to first
order,

.. math:: \dot e = A(t)\, e + B(t)\, (u - \bar u(t)),\qquad
          A = \frac{\partial f}{\partial x}\Big|_{\bar x, \bar u},\quad
          B = \frac{\partial f}{\partial u}\Big|_{\bar x, \bar u},

with f the design model (:mod:`mavreg.model.quadrotor`), differentiated by complex step
(:func:`mavreg.model.linearize.complex_step_jacobian`, exact to machine precision). The cost
:math:`\int e^T Q e + (u - \bar u)^T R (u - \bar u)\, dt` is minimised by
:math:`u = \bar u(t) - K(t) e` with :math:`K = R^{-1} B^T P` and

.. math:: -\dot P = A^T P + P A - P B R^{-1} B^T P + Q,

integrated backward in time by RK4 on the clock's grid (1 ms; A and B also at the interval
midpoints) from :math:`P(T)`, the algebraic solution at the last node (the run-out's straight
flight at constant speed). It is the s-domain machinery of :mod:`mavreg.control.design.riccati`
(:func:`~mavreg.control.design.riccati.sweep_backward`) with time as the independent variable.

**Weights** (:meth:`TvlqrWeights.from_controller`): the maneuver regulator's, of the same
controller file (``paper_lqr.yaml``: the paper's), on the same physical quantities. The
regulator weighs the two offsets across the path (100, 100); the tracker's position error
has three components, each weighed as the larger of the two (100): the along-track error
gets the weight of the transverse ones, which is what makes it a tracker. Attitude (9),
body velocity (10), body rates (3) and the inputs (0.1, 0.1, 1, 0.1) are the regulator's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.controller import ControllerParams
from ..control.design.riccati import care, sweep_backward
from ..model.linearize import complex_step_jacobian
from ..model.quadrotor import NX
from ..model.rotation import wrap_angle
from .common import Allocator, TrackerOutput
from .timed import TimedNominal

__all__ = ["TvlqrWeights", "TimeVaryingLqr", "full_state_jacobians"]


@dataclass(frozen=True)
class TvlqrWeights:
    """Diagonal weights on the full state's error (12) and the input's deviation (4)."""

    q: tuple[float, ...]
    """(p1, p2, p3, roll, pitch, yaw, v1, v2, v3, p, q, r) of the body-frame state."""
    r: tuple[float, ...]
    """(f, g1, g2, g3)."""

    def __post_init__(self):
        if len(self.q) != NX or len(self.r) != 4:
            raise ValueError(f"q must have {NX} weights and r 4, got {len(self.q)} and {len(self.r)}")
        if min(self.q) < 0.0 or min(self.r) <= 0.0:
            raise ValueError("weights: q must be >= 0 and r > 0")

    @classmethod
    def from_controller(cls, controller: ControllerParams) -> "TvlqrWeights":
        """The regulator's weights on the full state: each position axis weighed as the larger
        transverse one (see the module docstring)."""
        qp = float(max(controller.q_position))
        return cls(q=(qp, qp, qp, *controller.q_attitude, *controller.q_velocity, *controller.q_rate),
                   r=tuple(float(v) for v in controller.r_input))


def full_state_jacobians(model, x, u) -> tuple[np.ndarray, np.ndarray]:
    """A = df/dx and B = df/du of the design model at a batch of states x (N, 12) and inputs
    u (N, 4), by complex step; (N, 12, 12) and (N, 12, 4)."""
    x = np.asarray(x, dtype=float)
    u = np.asarray(u, dtype=float)
    A = complex_step_jacobian(lambda xc: model.f(xc.T, u.T.astype(complex)).T, x)
    B = complex_step_jacobian(lambda uc: model.f(x.T.astype(complex), uc.T).T, u)
    return A, B


class TimeVaryingLqr:
    """:math:`u = \\bar u(t) - K(t) (x - \\bar x(t))` on the timed nominal of a plan.

    Parameters
    ----------
    timed : TimedNominal
        The reference; the gains are computed on its time grid.
    weights : TvlqrWeights
    lead_s : float
        The feedforward is taken this much ahead (half the control period of a zero-order
        hold, as the regulator does).
    """

    def __init__(self, timed: TimedNominal, weights: TvlqrWeights, lead_s: float = 0.0):
        self.timed = timed
        self.weights = weights
        self.lead_s = float(lead_s)
        self.allocator = Allocator(timed.plan.vehicle)
        h = timed.step_s
        t = timed.t_grid
        nodes = [self._nominal(ti) for ti in t]
        mids = [self._nominal(ti + 0.5 * h) for ti in t[:-1]]
        model = timed.model
        A, B = full_state_jacobians(model, [x for x, _ in nodes], [u for _, u in nodes])
        Am, Bm = full_state_jacobians(model, [x for x, _ in mids], [u for _, u in mids])
        Q, R = np.diag(weights.q), np.diag(weights.r)
        P_T, _ = care(A[-1], B[-1], Q, R)
        self.P, self.K = sweep_backward(A, B, Am, Bm, h, Q, R, P_T, step_check="warn")
        self.t_grid = t
        self.P_terminal = P_T

    def _nominal(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        s = self.timed.s_at(t)
        return self.timed.state_at_s(s), self.timed.input_at_s(s)

    def gain(self, t: float) -> np.ndarray:
        """K(t) (4, 12), linear between the grid's nodes (the last one after it)."""
        h = self.timed.step_s
        n = len(self.t_grid)
        tc = min(max(float(t), 0.0), float(self.t_grid[-1]))
        i = min(int(tc / h), n - 2)
        a = (tc - self.t_grid[i]) / h
        return self.K[i] + a * (self.K[i + 1] - self.K[i])

    def step(self, t: float, x) -> TrackerOutput:
        """The command at maneuver time ``t`` for state ``x`` (12,)."""
        x = np.asarray(x, dtype=float)
        s = self.timed.s_at(float(t))
        e = x - self.timed.state_at_s(s)
        e[3:6] = wrap_angle(e[3:6])
        ubar = self.timed.input_at_s(self.timed.s_at(float(t) + self.lead_s) if self.lead_s else s)
        u = ubar - self.gain(t) @ e
        return TrackerOutput(float(t), float(s), u, self.allocator.rotors(u))
