r"""The batch closed loop compiled: each run a scalar loop in time, the runs one after another.

What the sequential simulator does (:func:`mavreg.sim.maneuver_run.fly_on_design_model`),
numba compiles here as plain loops (:func:`mavreg.accel.njit`), which is several times faster
than numba's array expressions and compiles in seconds instead of tens of seconds. Per run and control
call, the regulator's step is the project's compiled one,
:func:`mavreg.control.controllers.step_kernel.regulator_step` (the same kernel the regulator's compiled
path runs), and between calls the plant of eqs 6-17
(:func:`mavreg.model.quadrotor_kernel.plant_rhs`, the run's inertia)
is stepped by classical RK4 (:func:`~mavreg.model.quadrotor_kernel.rk4_step`), as
:func:`mavreg.sim.closed_loop.simulate` steps it:
the command held, clipped to :math:`[0, f_{sat}]`, the control call's noise added and
clipped again, :math:`u = M f` times the thrust scale.

Only useful compiled: run as plain Python (``MAVREG_PURE=1``) it would be the sequential
simulator again, so :func:`mavreg.sim.batch.fly_batch` runs the sequential simulator then.
"""
from __future__ import annotations

import numpy as np

from ..accel import njit
from ..control.controllers import step_kernel as sk
from ..model.quadrotor_kernel import rk4_step

__all__ = ["run", "RUNNING", "COMPLETED", "DIVERGED", "BAD_COMMAND", "TIMEOUT"]

RUNNING, COMPLETED, DIVERGED, BAD_COMMAND, TIMEOUT = 0, 1, 2, 3, 4
"""A run still flying; done (s reached the end); diverged (state); the controller returned
non-finite rotor forces; the maximum duration was reached."""


@njit
def _diverged(x, limits):
    """Whether x is non-finite or beyond ``limits`` (:func:`mavreg.sim.closed_loop._divergence`'s bounds)."""
    max_speed, max_rate, max_pos, min_cos = limits
    for j in range(12):
        if not np.isfinite(x[j]):
            return True
    if np.sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8]) > max_speed:
        return True
    if np.sqrt(x[9] * x[9] + x[10] * x[10] + x[11] * x[11]) > max_rate:
        return True
    if max(abs(x[0]), abs(x[1]), abs(x[2])) > max_pos:
        return True
    return abs(np.cos(x[4])) < min_cos


@njit
def _fly(r, x, st, status, k_end, xs, cmd, app, step, M, plant, J, upper, noise, thrust_scale, dt, period,
         limits):
    """Run ``r`` from state x and regulator state ``st`` (see :func:`run`)."""
    table, s_tab, s_nodes, coef, ends, prm = step
    n_steps = xs.shape[1] - 1
    jx, jy, jz = J[r, 0], J[r, 1], J[r, 2]
    out = np.empty(sk.OUT_WIDTH)
    none = np.zeros(4)
    no_torque = np.zeros(6)
    f = np.zeros(4)
    command = np.zeros(4)
    acting = np.zeros(4)
    applied = np.zeros(4)
    ns = np.zeros(4)
    work = (np.empty(12), np.empty(12), np.empty(12), np.empty(12), np.empty(12))
    no_force = np.zeros(4)
    s = st[0]
    calls = 0
    for i in range(n_steps):
        if i % period == 0:
            s = sk.regulator_step(x, none, False, False, 0.0, 0.0, 0.0, 0.0, 0.0, no_torque, table, s_tab, s_nodes,
                                  coef, ends, prm, st, out)[0]
            finite = True
            for j in range(4):
                command[j] = out[sk.OUT_ROTORS + j]
                finite = finite and np.isfinite(command[j])
            if not finite:
                cmd[r, i] = command
                app[r, i] = applied
                status[r] = BAD_COMMAND
                k_end[r] = i
                return
            for j in range(4):
                acting[j] = min(max(command[j], 0.0), upper[r])
                ns[j] = noise[min(calls, noise.shape[0] - 1), j, r]
            calls += 1
        for j in range(4):
            applied[j] = min(max(acting[j] + ns[j], 0.0), upper[r])
            f[j] = applied[j] * thrust_scale
        cmd[r, i] = command
        app[r, i] = applied
        u0 = M[0, 0] * f[0] + M[0, 1] * f[1] + M[0, 2] * f[2] + M[0, 3] * f[3]
        u1 = M[1, 0] * f[0] + M[1, 1] * f[1] + M[1, 2] * f[2] + M[1, 3] * f[3]
        u2 = M[2, 0] * f[0] + M[2, 1] * f[1] + M[2, 2] * f[2] + M[2, 3] * f[3]
        u3 = M[3, 0] * f[0] + M[3, 1] * f[1] + M[3, 2] * f[2] + M[3, 3] * f[3]
        rk4_step(x, u0, u1, u2, u3, no_force, plant, jx, jy, jz, dt, work)
        xs[r, i + 1] = x
        if _diverged(x, limits):
            status[r] = DIVERGED
            k_end[r] = i + 1
            return
        if s >= prm[sk.P_END]:
            status[r] = COMPLETED
            k_end[r] = i + 1
            return
    status[r] = TIMEOUT
    k_end[r] = n_steps


@njit
def run(X, ST, status, k_end, xs, cmd, app, step, M, plant, J, upper, noise, thrust_scale, dt, period, limits):
    """Fly every run whose ``status`` is RUNNING: X (N, 12) start states, ST (N, W) the step
    kernel's state per run (s first), ``step`` = (table, s_tab, s_nodes, coef, ends, prm) of
    :class:`mavreg.control.controllers.fastpath.FastStep`; ``xs`` (N, K+1, 12), ``cmd`` and ``app``
    (N, K+1, 4) receive the records, ``status`` and ``k_end`` how and where each run ended.
    ``plant`` = (mass, g, c_xy, c_z, c_parasitic, the drag's thrust exponent), J (N, 3), ``upper`` (N,) the saturation,
    ``noise`` (C, 4, N): the rotor noise of each control call (:func:`mavreg.sim.batch._noise`)."""
    for r in range(X.shape[0]):
        if status[r] == RUNNING:
            _fly(r, X[r].copy(), ST[r].copy(), status, k_end, xs, cmd, app, step, M, plant, J, upper, noise,
                 thrust_scale, dt, period, limits)
