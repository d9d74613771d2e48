r"""The batch closed loop in numpy: one loop over time, every operation across all the runs.

Every array here has the runs on its **last** axis: a state batch is (12, N), rotor forces
(4, N), the path's geometry at the runs' arc lengths (18, N); the tables keep one row per
node, so that the rows of N runs are one gather. A time step is a few hundred numpy
operations whatever N is. This is the pure path of :func:`mavreg.sim.batch.fly_batch` (no
numba, or ``MAVREG_PURE=1``); :mod:`mavreg.sim.batch_compiled` is the compiled one.

The maths is the sequential path's, operation for operation where that matters for
rounding (the path's Hermite polynomials, the tables' linear interpolation, the RK4 stages,
the yaw-then-lift allocation), and in the same order; sums of products (dot products,
``K w``, the mixer) may round differently from BLAS, by an ulp:

- :func:`path_point`: :meth:`mavreg.geometry.path.Path.point` (straight extensions included);
- :func:`project`: :meth:`mavreg.geometry.projection.Projector.update` (Newton on
  :math:`t^T(y - c(\sigma)) = 0`, at most 12 iterations, within the window);
- :func:`regulator_step`: :meth:`mavreg.control.regulator.ManeuverRegulator.step` for the
  paper's design (gains (4, 11), no disturbance compensation, no speed governor):
  :math:`u = \bar u(s + v(s)\,\ell) - K(s)\,w`, rotor forces by
  :func:`mavreg.model.mixer.yaw_then_lift`;
- :func:`mavreg.sim.batch_plant.plant_rhs`: :meth:`mavreg.model.quadrotor.QuadrotorModel.f`
  with one inertia per run;
- :func:`run`: the loop of :func:`mavreg.sim.closed_loop.simulate` (zero-order hold, rotor
  forces clipped to [0, saturation], noise held over a control period, RK4, the divergence
  checks, the regulator's "s has reached the end" as the stop condition).

Status codes of :func:`run`: see :data:`RUNNING` ... :data:`TIMEOUT`.
"""
from __future__ import annotations

import numpy as np

from .batch_plant import plant_rhs

__all__ = ["path_point", "project", "locate", "regulator_step", "run",
           "RUNNING", "COMPLETED", "DIVERGED", "BAD_COMMAND", "TIMEOUT"]

RUNNING, COMPLETED, DIVERGED, BAD_COMMAND, TIMEOUT = 0, 1, 2, 3, 4
"""A run still flying; done (s reached the end); diverged (state); the controller returned
non-finite rotor forces; the maximum duration was reached."""


def path_point(s, s_nodes, coef, length, ends):
    """Path geometry at arc lengths ``s`` (N,): (18, N) rows c (3), frame row-major (9; column
    0 is t, 1 is m1, 2 is m2), k, dk, ddk (2 each).

    ``s_nodes``, ``coef`` (M, 4, 18: the Hermite coefficients in u = (s - s_i)/h_i per
    interval), ``ends`` (2, 18: the values at s = 0 and s = length, for the straight
    extensions): :func:`mavreg.geometry.projection_kernel.path_tables`.
    """
    n = s_nodes.shape[0]
    i = np.minimum(np.maximum(np.searchsorted(s_nodes, s, side="right") - 1, 0), n - 2)
    s0 = s_nodes[i]
    u = ((s - s0) / (s_nodes[i + 1] - s0)).reshape(-1, 1)
    a = coef[i]
    v = (a[:, 0] + u * (a[:, 1] + u * (a[:, 2] + u * a[:, 3]))).T
    for side in range(2):
        ref = 0.0 if side == 0 else length
        out = s <= ref if side == 0 else s >= ref
        if out.any():
            e = ends[side]
            ext = np.empty_like(v)
            for j in range(3):
                ext[j] = e[j] + (s - ref) * e[3 + 3 * j]
            for j in range(3, 12):
                ext[j] = e[j]
            for j in range(12, 18):
                ext[j] = np.where(s == ref, e[j], 0.0)
            v = np.where(out, ext, v)
    return v


def project(y0, y1, y2, s_prev, window, s_nodes, coef, length, ends):
    """Warm-started nearest points of positions (y0, y1, y2) (each (N,)) from ``s_prev``:
    the new s (N,) and the path geometry there (18, N)."""
    lo = s_prev - window
    hi = s_prev + window
    s = s_prev.copy()
    v = path_point(s, s_nodes, coef, length, ends)
    active = np.ones(s.shape[0], dtype=np.bool_)
    for _ in range(12):
        d0 = y0 - v[0]
        d1 = y1 - v[1]
        d2 = y2 - v[2]
        g = v[3] * d0 + v[6] * d1 + v[9] * d2
        # curvature vector K = m1 k1 + m2 k2, then dg = K.d - 1
        dg = ((v[4] * v[12] + v[5] * v[13]) * d0 + (v[7] * v[12] + v[8] * v[13]) * d1
              + (v[10] * v[12] + v[11] * v[13]) * d2) - 1.0
        active = active & ~(dg > -1e-3)      # at or past the focal point: stop there
        if not active.any():
            break
        step = np.minimum(np.maximum(-g / dg, -0.5), 0.5)
        s_new = np.minimum(np.maximum(s + step, lo), hi)
        converged = np.abs(s_new - s) < 1e-9
        s = np.where(active, s_new, s)
        v = path_point(s, s_nodes, coef, length, ends)
        active = active & ~converged
        if not active.any():
            break
    return s, v


def locate(s, s_tab, last):
    """Table row i (N,) and blend a (N,) of arc lengths s, clamped to the table's ends."""
    i = np.minimum(np.maximum(np.searchsorted(s_tab, s) - 1, 0), last)
    s_i = s_tab[i]
    a = np.minimum(np.maximum((s - s_i) / (s_tab[i + 1] - s_i), 0.0), 1.0)
    return i, a


def wrap_angle(a):
    """Angles wrapped to (-pi, pi] (:func:`mavreg.model.rotation.wrap_angle`)."""
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


def regulator_step(X, s_prev, path, table, Minv, fmax):
    """Rotor forces (4, N) and arc lengths (N,) for states X (12, N).

    ``path`` = (s_nodes, coef, length, ends, window); ``table`` = (s (n,), T (n, 61),
    D (n - 1, 61), lead_s): the plan's nodes, a row per node of x (12), u (4), v (1) and K
    (4 x 11, row-major) (:func:`mavreg.control.fastpath.plan_table`), and the differences
    between consecutive rows (the rows of N runs are gathered and blended in one operation).
    """
    s_nodes, coef, length, ends, window = path
    s_tab, T, D, lead = table
    last = s_tab.shape[0] - 2
    n = X.shape[1]
    s, p = project(X[0], X[1], X[2], s_prev, window, s_nodes, coef, length, ends)
    i, a = locate(s, s_tab, last)
    row = T[i] + a.reshape(-1, 1) * D[i]
    xbar = row[:, 0:12].T
    v = row[:, 16]
    if lead > 0.0:
        i, a = locate(s + v * lead, s_tab, last)
        ubar = (T[i, 12:16] + a.reshape(-1, 1) * D[i, 12:16]).T
    else:
        ubar = row[:, 12:16].T
    d0 = X[0] - p[0]
    d1 = X[1] - p[1]
    d2 = X[2] - p[2]
    w = np.empty((n, 11))
    w[:, 0] = d0 * p[4] + d1 * p[7] + d2 * p[10]
    w[:, 1] = d0 * p[5] + d1 * p[8] + d2 * p[11]
    w[:, 2:5] = wrap_angle(X[3:6] - xbar[3:6]).T
    w[:, 5:] = (X[6:] - xbar[6:]).T
    u = np.empty((4, n))
    for r in range(4):
        u[r] = ubar[r] - (row[:, 17 + 11 * r:28 + 11 * r] * w).sum(axis=1)
    return yaw_then_lift(Minv, u, fmax), s


def yaw_then_lift(Minv, u, fmax):
    """:func:`mavreg.model.mixer.yaw_then_lift` for a batch u (4, N)."""
    base = Minv[:, 0:1] * u[0] + Minv[:, 1:2] * u[1] + Minv[:, 2:3] * u[2]
    yaw = Minv[:, 3:4] * u[3]
    f = base + yaw
    if not (f < 0.0).any():
        return f
    beta = np.ones(u.shape[1])
    for r in range(4):
        b, y = base[r], yaw[r]
        ratio = np.maximum(b, 0.0) / -y
        beta = np.where((b + y < 0.0) & (ratio < beta), ratio, beta)
    f = base + beta * yaw
    low = np.minimum(np.minimum(f[0], f[1]), np.minimum(f[2], f[3]))
    high = np.maximum(np.maximum(f[0], f[1]), np.maximum(f[2], f[3]))
    lift = np.minimum(-low, np.maximum(fmax - high, 0.0))
    return np.where(low < 0.0, f + lift, f)


def diverged(X, limits):
    """Runs (N,) whose state is non-finite or beyond ``limits`` = (max speed, max body rate,
    max |position|, min |cos pitch|) (:func:`mavreg.sim.closed_loop._divergence`'s tests)."""
    max_speed, max_rate, max_pos, min_cos = limits
    finite = np.isfinite((X * 0.0).sum(axis=0))
    speed = np.sqrt(X[6] * X[6] + X[7] * X[7] + X[8] * X[8])
    rate = np.sqrt(X[9] * X[9] + X[10] * X[10] + X[11] * X[11])
    dist = np.maximum(np.maximum(np.abs(X[0]), np.abs(X[1])), np.abs(X[2]))
    return (~finite | (speed > max_speed) | (rate > max_rate) | (dist > max_pos)
            | (np.abs(np.cos(X[4])) < min_cos))


def run(X, S, status, k_end, xs, cmd, app, path, table, Minv, M, fmax, plant, J, upper, noise, thrust_scale,
        dt, period, limits):
    """Fly every run with ``status`` RUNNING from state X (12, N) and arc length S (N,) until
    it ends or ``xs`` is full: ``xs`` (N, K+1, 12) gets the states (row 0 must hold X),
    ``cmd`` and ``app`` (N, K+1, 4) the rotor forces commanded and applied over each step;
    ``status`` and ``k_end`` (N,) are set to how and at which row each run ended.

    ``plant`` = (mass, g, c_xy, c_z, c_parasitic), J (3, N) the runs' inertia (jx, jy, jz);
    ``upper`` (N,): rotor saturation (inf: none); ``noise`` (C, 4, N): the noise of each
    control call (C = 1: the same for every call); ``period``: physics steps per control
    call; ``limits``: see :func:`diverged`.
    """
    n_steps = xs.shape[1] - 1
    n = X.shape[1]
    jx, jy, jz = J
    alive = status == RUNNING
    command = np.zeros((4, n))
    applied = np.zeros((4, n))
    acting = np.zeros((4, n))
    noise_now = np.zeros((4, n))
    calls = 0
    half, sixth = 0.5 * dt, dt / 6.0
    for i in range(n_steps):
        if not alive.any():
            break
        everyone = alive.all()
        bad_any = False
        if i % period == 0:
            new, s_new = regulator_step(X, S, path, table, Minv, fmax)
            S = s_new if everyone else np.where(alive, s_new, S)
            command = new if everyone else np.where(alive, new, command)
            bad = alive & ~np.isfinite(command.sum(axis=0))
            bad_any = bad.any()
            if bad_any:                 # the run ends at this step, its row k as simulate fills it
                last_applied = applied
                for r in range(n):
                    if bad[r]:
                        status[r] = BAD_COMMAND
                        k_end[r] = i
                alive = alive & ~bad
                everyone = False
            acting = np.minimum(np.maximum(command, 0.0), upper)
            noise_now = noise[min(calls, noise.shape[0] - 1)]
            calls += 1
        applied = np.minimum(np.maximum(acting + noise_now, 0.0), upper)
        cmd[:, i] = command.T
        app[:, i] = applied.T
        if bad_any:
            app[bad, i] = last_applied[:, bad].T
        f = applied * thrust_scale
        U = M[:, 0:1] * f[0] + M[:, 1:2] * f[1] + M[:, 2:3] * f[2] + M[:, 3:4] * f[3]
        k1, k2, k3, k4 = (np.empty_like(X) for _ in range(4))
        plant_rhs(X, U[0], U[1], U[2], U[3], plant, jx, jy, jz, k1)
        plant_rhs(X + half * k1, U[0], U[1], U[2], U[3], plant, jx, jy, jz, k2)
        plant_rhs(X + half * k2, U[0], U[1], U[2], U[3], plant, jx, jy, jz, k3)
        plant_rhs(X + dt * k3, U[0], U[1], U[2], U[3], plant, jx, jy, jz, k4)
        X_new = X + sixth * (k1 + 2.0 * (k2 + k3) + k4)
        X = X_new if everyone else np.where(alive, X_new, X)
        xs[:, i + 1] = X.T
        bad = alive & diverged(X, limits)
        done = alive & ~bad & (S >= path[2] - 1e-6)
        for r in range(n):
            if bad[r] or done[r]:
                status[r] = DIVERGED if bad[r] else COMPLETED
                k_end[r] = i + 1
        alive = alive & ~(bad | done)
    for r in range(n):
        if alive[r]:
            status[r] = TIMEOUT
            k_end[r] = n_steps
