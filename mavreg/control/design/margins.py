r"""Gain and delay margins of a linear state-feedback loop broken at the plant input.

The loop is :math:`\dot x = A x + B u`, :math:`u = -K x` (``A`` (n, n), ``B`` (n, m),
``K`` (m, n)), with the nominal closed loop :math:`A - BK` Hurwitz. ``x`` may hold controller
states too (a filter the controller runs on its own commands, :func:`lag_model_loop`): only
the plant's input ``u`` is perturbed, the controller's copy of its command is not. Broken
there, the loop transfer matrix is

.. math::
    L(s) = K (sI - A)^{-1} B, \qquad \det(sI - A + g\,e^{-s\tau} BK)
    = \det(sI - A)\,\det(I + g\,e^{-s\tau} L(s)).

**Gain margin.** The interval :math:`(g_{lo}, g_{hi}) \ni 1` of a common gain on every input
channel, :math:`u \to g u`, for which :math:`A - gBK` stays Hurwitz. Its edges are found on
a log grid of g (the first unstable g on either side of 1) refined by bisection on the
spectral abscissa :math:`\max \mathrm{Re}\,\lambda(A - gBK)`. ``g_lo = 0`` means stable down
to (not including) zero gain, ``g_hi = inf`` stable up to ``G_MAX`` (100).

**Delay margin.** The smallest common delay :math:`\tau` on every input channel,
:math:`\dot x = Ax - BKx(t - \tau)`, that puts a root on the imaginary axis. A root at
:math:`j\omega` needs an eigenvalue :math:`\mu(\omega)` of :math:`L(j\omega)` with
:math:`\mu e^{-j\omega\tau} = -1`, i.e.

.. math::
    |\mu(\omega)| = 1, \qquad \tau = \frac{(\arg\mu - \pi) \bmod 2\pi}{\omega},

and since L is strictly proper no root comes from infinity: the roots move continuously
with :math:`\tau` from the (stable) delay-free ones, so the margin is the least such
:math:`\tau` over every unit-modulus crossing. This is exact for a common delay (not a Padé
approximation). The crossings are bracketed on the grid ``OMEGA_RAD_S`` (0.01 to 10^4
rad/s, 240 points) on the sorted moduli of the eigenvalues of L (continuous in
:math:`\omega` whatever the eigenvalues' order) and refined by the Illinois variant of
regula falsi in :math:`\log\omega`. Check: the scalar :math:`\dot x = -kx(t-\tau)` gives
:math:`\pi/(2k)` (``tests/unit/test_margins.py``).

L is evaluated through the closed loop, which is Hurwitz and diagonalizable where the open
loop is not (a hover's integrators are Jordan blocks at 0): with
:math:`A_c = A - BK = V\Lambda V^{-1}` and :math:`T = K(sI - A_c)^{-1}B`, Woodbury's
identity gives :math:`L = T(I - T)^{-1}`, whose eigenvalues are :math:`t/(1 - t)` for the
eigenvalues t of T. Where V is ill-conditioned, :math:`(sI - A)^{-1}B` is solved directly.

Pure: numbers in, numbers out. Stacks of loops (leading axis N) are handled at once.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["G_MAX", "G_MIN", "OMEGA_RAD_S", "FastLoopError", "LoopMargins", "ScheduleMargins",
           "spectral_abscissa", "gain_margins", "delay_margins", "loop_margins", "lag_model_loop", "rotor_loop",
           "node_margins", "schedule_margins"]

G_MAX = 100.0
"""Largest gain tried: stable up to it counts as an infinite upper gain margin."""
G_MIN = 1e-3
"""Smallest gain tried: stable down to it counts as a lower gain margin of 0."""
OMEGA_RAD_S = np.logspace(-2.0, 4.0, 240)
"""Frequency grid on which unit-modulus crossings of L's eigenvalues are bracketed."""
_GRID = 14
_BISECT = 14
_REFINE = 30
_COND_MAX = 1e9


class FastLoopError(ValueError):
    """A loop whose gain is still 1 or more at the top of the frequency grid (10^4 rad/s): its
    delay margin is under 2 pi / 10^4 s = 0.6 ms, less than any control period. Not a failure of
    the grid: the weights ask the rotors for a bandwidth no vehicle has (a 10 g airframe with
    the paper's weights, or torque weights of 1e-6)."""


@dataclass(frozen=True)
class LoopMargins:
    """Margins of one loop (units in the names; ``inf``: none within the search)."""

    delay_margin_s: float
    crossover_rad_s: float
    """Frequency of the root that reaches the imaginary axis at the delay margin."""
    gain_margin_low: float
    gain_margin_high: float
    stable: bool
    """Whether the nominal closed loop is Hurwitz (else every margin is NaN)."""

    def as_dict(self) -> dict:
        return {"delay_margin_ms": _ms(self.delay_margin_s), "crossover_rad_s": _num(self.crossover_rad_s),
                "gain_margin": [_num(self.gain_margin_low), _num(self.gain_margin_high)],
                "stable": self.stable}


@dataclass(frozen=True)
class ScheduleMargins:
    """The worst margins over the nodes of a gain schedule (frozen-time loops)."""

    delay_margin_s: float
    worst_s_m: float
    """Where the delay margin is least."""
    gain_margin_low: float
    """The largest lower edge over the nodes."""
    gain_margin_low_s_m: float
    gain_margin_high: float
    """The smallest upper edge over the nodes."""
    gain_margin_high_s_m: float
    nodes: int
    """How many schedule nodes were analysed."""
    unstable_s_m: tuple[tuple[float, float], ...] = ()
    """Stretches of s whose frozen-time closed loop is not Hurwitz (left out of the minima)."""

    def as_dict(self) -> dict:
        return {"delay_margin_ms": _ms(self.delay_margin_s), "worst_s_m": _num(self.worst_s_m),
                "gain_margin": [_num(self.gain_margin_low), _num(self.gain_margin_high)],
                "gain_margin_s_m": [_num(self.gain_margin_low_s_m), _num(self.gain_margin_high_s_m)],
                "nodes": self.nodes, "frozen_unstable_s_m": [list(p) for p in self.unstable_s_m]}


def _num(x: float):
    """JSON-safe: inf and NaN as strings."""
    return x if math.isfinite(x) else str(x)


def _ms(x: float):
    return _num(x * 1e3)


def spectral_abscissa(A, B, K, g=1.0, slow_rad_s: float = 0.0) -> np.ndarray:
    """max Re eig(A - g B K) over the eigenvalues of modulus ``slow_rad_s`` or more (the
    slower ones are not judged: -inf if none is left); stacks give a stack (g a scalar or one
    per loop)."""
    A, B, K = (np.asarray(a, dtype=float) for a in (A, B, K))
    g = np.asarray(g, dtype=float)[..., None, None]
    lam = np.linalg.eigvals(A - g * (B @ K))
    return np.where(np.abs(lam) >= slow_rad_s, lam.real, -np.inf).max(axis=-1)


def _first_unstable(A, B, K, gains: np.ndarray, slow: float) -> np.ndarray:
    """Index into ``gains`` (walked in order) of the first unstable gain per loop; len(gains)
    where every one is stable."""
    first = np.full(A.shape[0], len(gains))
    for i, g in enumerate(gains):
        live = first == len(gains)
        if not live.any():
            break
        bad = spectral_abscissa(A[live], B[live], K[live], g, slow) >= 0.0
        first[np.flatnonzero(live)[bad]] = i
    return first


def _edge(A, B, K, g_far: float, slow: float) -> np.ndarray:
    """The gain edge on the side of ``g_far`` (bracketed on a log grid, then bisected in log
    g); ``g_far`` stable counts as no edge (inf above, 0 below)."""
    grid = np.geomspace(1.0, g_far, _GRID + 1)[1:]
    first = _first_unstable(A, B, K, grid, slow)
    out = np.full(len(A), math.inf if g_far > 1 else 0.0)
    hit = first < len(grid)
    if not hit.any():
        return out
    lo = np.log(np.where(first[hit] > 0, grid[np.maximum(first[hit] - 1, 0)], 1.0))
    hi = np.log(grid[first[hit]])
    Ah, Bh, Kh = A[hit], B[hit], K[hit]
    for _ in range(_BISECT):
        mid = (lo + hi) / 2
        bad = spectral_abscissa(Ah, Bh, Kh, np.exp(mid), slow) >= 0.0
        hi = np.where(bad, mid, hi)
        lo = np.where(bad, lo, mid)
    out[hit] = np.exp(hi)
    return out


def gain_margins(A, B, K, slow_rad_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(g_lo, g_hi) of each loop of a stack (N, ...); NaN where the nominal is unstable.

    The edge is reported on its unstable side, to a relative 1e-4 or better. Modes slower
    than ``slow_rad_s`` are not judged (:func:`spectral_abscissa`)."""
    A, B, K = _stack(A, B, K)
    stable = spectral_abscissa(A, B, K, 1.0, slow_rad_s) < 0.0
    lo = np.full(len(A), math.nan)
    hi = np.full(len(A), math.nan)
    if stable.any():
        lo[stable] = _edge(A[stable], B[stable], K[stable], G_MIN, slow_rad_s)
        hi[stable] = _edge(A[stable], B[stable], K[stable], G_MAX, slow_rad_s)
    return lo, hi


def _stack(A, B, K):
    A, B, K = (np.asarray(a, dtype=float) for a in (A, B, K))
    if A.ndim == 2:
        A, B, K = A[None], B[None], K[None]
    return A, B, K


class _Response:
    """Eigenvalues of L(j omega) for a stack of loops, at any frequencies."""

    def __init__(self, A, B, K):
        self.A, self.B, self.K = A, B, K
        lam, V = np.linalg.eig(A - B @ K)
        self.direct = np.linalg.cond(V) > _COND_MAX
        self.lam = lam
        self.KV = K @ V
        self.VB = np.linalg.solve(np.where(self.direct[:, None, None], np.eye(A.shape[-1]), V),
                                  B.astype(complex))

    def eigs(self, rows: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """Eigenvalues (..., m) of L(j omega) for loops ``rows`` (C,) at ``omega`` (C, W)."""
        s = 1j * omega
        T = np.einsum("cik,cwk,ckj->cwij", self.KV[rows], 1.0 / (s[..., None] - self.lam[rows][:, None, :]),
                      self.VB[rows])
        t = np.linalg.eigvals(T)
        mu = t / (1.0 - t)
        n = self.A.shape[-1]
        for c in np.flatnonzero(self.direct[rows]):
            r = rows[c]
            M = s[c][:, None, None] * np.eye(n) - self.A[r]
            Bc = np.broadcast_to(self.B[r].astype(complex), (len(s[c]),) + self.B[r].shape)
            mu[c] = np.linalg.eigvals(self.K[r] @ np.linalg.solve(M, Bc))
        return mu


def _moduli(resp: _Response, rows, omega) -> np.ndarray:
    return np.sort(np.abs(resp.eigs(rows, omega)), axis=-1)


def delay_margins(A, B, K, omega=OMEGA_RAD_S, slow_rad_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(delay margin s, crossover rad/s) of each loop of a stack (N, ...).

    ``inf`` (and NaN) where no eigenvalue of L reaches unit modulus on the grid; NaN where the
    nominal is unstable. Raises :class:`FastLoopError` if L is not below unit modulus at the
    grid's top.
    With ``slow_rad_s``: modes slower than it are not judged, nor crossings below it.
    """
    A, B, K = _stack(A, B, K)
    N = len(A)
    tau = np.full(N, math.inf)
    wc = np.full(N, math.nan)
    unstable = spectral_abscissa(A, B, K, 1.0, slow_rad_s) >= 0.0
    resp = _Response(A, B, K)
    rows = np.arange(N)
    omega = np.asarray(omega, dtype=float)
    f = _moduli(resp, rows, np.broadcast_to(omega, (N, len(omega)))) - 1.0     # (N, W, m)
    if np.any(f[~unstable, -1] >= 0.0):
        raise FastLoopError(f"the loop gain is still 1 or more at {omega[-1]:g} rad/s")
    node, k, j = np.nonzero((f[:, :-1] < 0.0) != (f[:, 1:] < 0.0))
    keep = ~unstable[node]
    node, k, j = node[keep], k[keep], j[keep]
    if len(node):
        w_star = _refine(resp, node, j, np.log(omega[k]), np.log(omega[k + 1]), f[node, k, j],
                         f[node, k + 1, j])
        mu = resp.eigs(node, w_star[:, None])[:, 0]                           # (C, m)
        pick = np.argmin(np.abs(np.abs(mu) - 1.0), axis=1)
        phase = np.angle(mu[np.arange(len(node)), pick])
        t = np.where(w_star >= slow_rad_s, np.mod(phase - math.pi, 2 * math.pi) / w_star, math.inf)
        for c in np.argsort(t)[::-1]:                                          # the least wins
            if t[c] <= tau[node[c]]:
                tau[node[c]], wc[node[c]] = t[c], w_star[c]
    tau[unstable] = math.nan
    return tau, wc


def _refine(resp, node, j, a, b, fa, fb) -> np.ndarray:
    """Illinois regula falsi in log omega on the j-th sorted modulus minus 1, all crossings at once."""
    side = np.zeros(len(node))
    for _ in range(_REFINE):
        c = (a * fb - b * fa) / (fb - fa)
        fc = _moduli(resp, node, np.exp(c)[:, None])[:, 0][np.arange(len(node)), j] - 1.0
        same = np.sign(fc) == np.sign(fb)
        fa = np.where(same & (side == 1), fa / 2, fa)
        fb = np.where(~same & (side == -1), fb / 2, fb)
        a, fa = np.where(same, a, b), np.where(same, fa, fb)
        b, fb = c, fc
        side = np.where(same, 1, -1)
        if np.all(np.abs(b - a) < 1e-9):
            break
    return np.exp(b)


def loop_margins(A, B, K, slow_rad_s: float = 0.0) -> LoopMargins:
    """Every margin of one loop (A (n, n), B (n, m), K (m, n)); ``slow_rad_s`` as
    :func:`delay_margins`."""
    stable = bool(spectral_abscissa(A, B, K, 1.0, slow_rad_s) < 0.0)
    if not stable:
        return LoopMargins(math.nan, math.nan, math.nan, math.nan, False)
    tau, wc = delay_margins(A, B, K, slow_rad_s=slow_rad_s)
    lo, hi = gain_margins(A, B, K, slow_rad_s)
    return LoopMargins(float(tau[0]), float(wc[0]), float(lo[0]), float(hi[0]), True)


def node_margins(A, B, K, slow_rad_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(delay margin s, g_lo, g_hi) of each loop of a stack; NaN where not Hurwitz
    (``slow_rad_s`` as :func:`delay_margins`)."""
    tau, _ = delay_margins(A, B, K, slow_rad_s=slow_rad_s)
    lo, hi = gain_margins(A, B, K, slow_rad_s)
    return tau, lo, hi


def schedule_margins(s_m, tau_s, g_lo, g_hi) -> ScheduleMargins:
    """The worst of per-node margins (:func:`node_margins`) at arc lengths ``s_m`` (N,, sorted).

    Nodes whose frozen closed loop is not Hurwitz (NaN) are left out of the minima and reported
    as stretches of s (between the analysed nodes around them)."""
    s_m, tau, lo, hi = (np.asarray(a, dtype=float) for a in (s_m, tau_s, g_lo, g_hi))
    bad = np.isnan(tau)
    stretches: list[tuple[float, float]] = []
    for i in np.flatnonzero(bad):
        start, end = float(s_m[max(i - 1, 0)]), float(s_m[min(i + 1, len(s_m) - 1)])
        if stretches and start <= stretches[-1][1]:
            stretches[-1] = (stretches[-1][0], end)
        else:
            stretches.append((start, end))
    if bad.all():
        nan = math.nan
        return ScheduleMargins(nan, nan, nan, nan, nan, nan, len(s_m), tuple(stretches))
    t = np.where(bad, math.inf, tau)
    low = np.where(bad, -math.inf, lo)
    high = np.where(bad, math.inf, hi)
    i, a, b = int(np.argmin(t)), int(np.argmax(low)), int(np.argmin(high))
    def where(k: int, v: float) -> float:
        return float(s_m[k]) if math.isfinite(v) else math.nan

    return ScheduleMargins(float(t[i]), where(i, t[i]), float(low[a]),
                           where(a, low[a] if low[a] > 0 else math.inf), float(high[b]),
                           where(b, high[b]), len(s_m), tuple(stretches))


def lag_model_loop(A, B, K) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The loop of a controller that feeds back its *own model* of the rotor lag.

    ``A`` (n+m, n+m), ``B`` (n+m, m): a plant whose last m states are the achieved wrench
    ``a`` (:mod:`mavreg.control.design.actuator`, in time); ``K`` (m, n+m): gains whose last m columns
    act on ``a``. The regulator does not measure ``a``: it runs the lag on its own commands
    (or the predictor does), :math:`\dot{\hat a} = A_{aw} w + A_{aa}\hat a + B_a y`,
    :math:`y = -K_w w - K_a \hat a`, and only the plant's copy sees a gain or a delay. The
    composite state is :math:`(w, a, \hat a)`:

    .. math::
        A_c = \begin{bmatrix} A_{ww} & A_{wa} & 0\\ A_{aw} & A_{aa} & 0\\
              A_{aw} - B_a K_w & 0 & A_{aa} - B_a K_a\end{bmatrix},\quad
        B_c = \begin{bmatrix}0\\ B_a\\ 0\end{bmatrix},\quad
        K_c = [K_w\; 0\; K_a].

    Nominally :math:`\hat a = a`, and the spectrum is that of :math:`A - BK` plus the lag's
    own. Stacks (N, ...) give stacks.
    """
    A, B, K = _stack(A, B, K)
    N, nz, m = B.shape
    n = nz - m
    Ac = np.zeros((N, nz + m, nz + m))
    Ac[:, :nz, :nz] = A
    Ba = B[:, n:]
    Ac[:, nz:, :n] = A[:, n:, :n] - Ba @ K[:, :, :n]
    Ac[:, nz:, nz:] = A[:, n:, n:] - Ba @ K[:, :, n:]
    Bc = np.concatenate([B, np.zeros((N, m, m))], axis=1)
    Kc = np.concatenate([K[:, :, :n], np.zeros((N, m, m)), K[:, :, n:]], axis=2)
    return Ac, Bc, Kc


def rotor_loop(A, B, K, mixer, rotor: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The loop broken at one rotor's command, the other three closed.

    With :math:`u = M f` (``mixer`` M, eq 34), a gain g on rotor i alone makes the plant see
    :math:`M(I + (g-1)e_ie_i^T)M^{-1}u`; so the loop through rotor i is
    :math:`(A - BK + B m_i n_i^T K,\; B m_i,\; n_i^T K)` with :math:`m_i` the i-th column of M
    and :math:`n_i^T` the i-th row of :math:`M^{-1}`. A common gain or delay on all four
    rotors equals one on the wrench: that is the loop of :func:`gain_margins` as given.
    """
    M = np.asarray(mixer, dtype=float)
    mi = M[:, rotor:rotor + 1]
    ni = np.linalg.inv(M)[rotor:rotor + 1]
    return A - B @ K + B @ mi @ ni @ K, B @ mi, ni @ K
