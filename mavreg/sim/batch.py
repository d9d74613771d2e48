r"""Many closed-loop runs of one plan at once: the regulator and the plant vectorized across runs.

:func:`fly_batch` flies N runs of one :class:`~mavreg.maneuver.plan.Plan` on the design model
as :func:`mavreg.sim.maneuver_run.fly_on_design_model` flies one: the regulator at the
control rate with its feedforward led by half a control period, the plant
:math:`\dot x = f(x, M f_{applied})` of eqs 6-17 with the run's own inertia, classical RK4
at ``dt_s``, the command held between calls and clipped to :math:`[0, f_{sat}]`, Gaussian
rotor noise drawn once per control call from the run's seed, and the same exit rules
(``completed`` when the regulator's s reaches the end, ``diverged``, ``timeout`` after the
nominal duration plus ``extra_time_s``). The runs differ by their :class:`BatchRun`: start
offset, plant inertia, rotor noise, saturation, seed.

Instead of N passes of a Python loop over time, one loop over time advances all N runs with
array operations (:mod:`mavreg.sim.batch_kernel`; compiled by numba where available, see
:mod:`mavreg.accel`): the Newton projection of every run at once (runs that have
converged wait for the others), the tables interpolated by gathering rows, the rotor
allocation with per-run masks, the plant's derivative on (12, N) arrays. A run that ends
is frozen and recorded up to its end. Each run's :class:`~mavreg.sim.closed_loop.SimResult`
agrees with the sequential one to rounding (``tests/unit/test_batch_sim.py``: 1e-9).

Scope: the paper's design (gains (4, 11)), ideal rotors (no lag), no delays, no external
force: what the paper's Section 4 flies on the design model (``mavreg experiment --via sim``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from ..config.vehicle import G
from ..geometry.projection import Projector
from ..maneuver.plan import Plan
from ..model.mixer import Mixer
from ..model.quadrotor import NX
from . import batch_kernel as kernel
from .closed_loop import SimOptions, SimResult, SimStatus, _divergence

__all__ = ["BatchRun", "fly_batch"]


@dataclass(frozen=True)
class BatchRun:
    """One run of a batch (SI units); the fields of
    :func:`~mavreg.sim.maneuver_run.fly_on_design_model` that may differ between runs."""

    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Start position minus the nominal entry position, NED."""
    inertia_kg_m2: Optional[tuple[float, float, float]] = None
    """The plant's jx, jy, jz; None: the design's."""
    rotor_noise_sd_n: float = 0.0
    saturation_n: Optional[float] = None
    """Rotor force limit of the plant (the regulator keeps the vehicle's); None: none."""
    seed: Optional[int] = None
    """Seed of the rotor noise."""


def _path_tables(plan: Plan, window_m: float) -> tuple:
    """(s_nodes, coef (M, 4, 18), length, ends (2, 18), window) for :func:`batch_kernel.path_point`."""
    path = plan.path
    ends = np.stack([np.concatenate([path.c_nodes[i], path.frame_nodes[i].ravel(), path.k_nodes[i],
                                     path.dk_nodes[i], path.ddk_nodes[i]]) for i in (0, -1)])
    # the Hermite coefficients of Path.point (a private table of the same package)
    return (np.ascontiguousarray(path.s_nodes), np.ascontiguousarray(path._coef), float(path.length_m), ends,
            float(window_m))


def _gain_tables(plan: Plan, lead_s: float) -> tuple:
    """The plan's nodes, its table (x, u, v, K per node) and the table's row differences
    (see :func:`batch_kernel.regulator_step`)."""
    n = len(plan.s)
    T = np.concatenate([plan.x, plan.u, np.reshape(plan.speed_m_s, (n, 1)), plan.K.reshape(n, 44)], axis=1)
    return np.ascontiguousarray(plan.s), np.ascontiguousarray(T), np.diff(T, axis=0), float(lead_s)


def fly_batch(plan: Plan, runs: Sequence[BatchRun], *, control_rate_hz: float = 1000.0,
              dt_s: float = 0.001, extra_time_s: float = 5.0) -> list[SimResult]:
    """Fly every run of ``runs`` on the design model; one :class:`SimResult` per run, in order.

    Parameters
    ----------
    plan : Plan
        Nominal and gains (the paper's design: gains (4, 11)); ``plan.vehicle`` is the design
        vehicle of the regulator, the mixer and the plant's mass.
    runs : sequence of BatchRun
    control_rate_hz, dt_s, extra_time_s
        As :func:`~mavreg.sim.maneuver_run.fly_on_design_model`: the control rate must be a
        whole number of physics steps ``dt_s``; each run stops at the nominal duration plus
        ``extra_time_s``.

    Raises
    ------
    ValueError
        For lag-aware gains, an empty batch, or a control rate that is not a whole number
        of physics steps (and whatever :class:`SimOptions` refuses in a run).
    """
    if plan.K.shape[-1] != 11:
        raise ValueError(f"the batch simulator flies the paper's design (gains (4, 11)), not gains "
                         f"{plan.K.shape[1:]} (a lag-aware design)")
    if not runs:
        raise ValueError("a batch needs at least one run")
    steps = int(round(1.0 / (control_rate_hz * dt_s)))
    if steps < 1 or abs(steps * dt_s * control_rate_hz - 1.0) > 1e-9:
        raise ValueError(f"control rate {control_rate_hz} Hz is not a whole number of "
                         f"{dt_s * 1e3:g} ms physics steps")
    vehicle = plan.vehicle
    mixer = Mixer(vehicle.arm_length_m, vehicle.drag_torque_ratio_m)
    projector = Projector(plan.path)
    x0s, options = [], []
    for run in runs:
        x0 = plan.entry_state
        x0[:3] += np.asarray(run.offset_m, dtype=float)
        x0s.append(x0)
        options.append(SimOptions(initial_state=tuple(x0), dt_s=dt_s, control_period_steps=steps,
                                  max_duration_s=plan.duration_s + extra_time_s,
                                  inertia_kg_m2=run.inertia_kg_m2, rotor_noise_sd_n=run.rotor_noise_sd_n,
                                  seed=run.seed, saturation_n=run.saturation_n))
    n, opt = len(runs), options[0]
    n_steps = int(np.ceil(opt.max_duration_s / dt_s - 1e-9))
    X = np.ascontiguousarray(np.array(x0s).T)
    S = np.array([projector.reset(x0[:3]).s for x0 in x0s])
    status = np.full(n, kernel.RUNNING, dtype=np.int64)
    k_end = np.zeros(n, dtype=np.int64)
    for r, o in enumerate(options):
        if _divergence(X[:, r], o) is not None:
            status[r] = kernel.DIVERGED
        elif S[r] >= plan.length_m - 1e-6:
            status[r] = kernel.COMPLETED
    J = np.array([o.inertia_kg_m2 or tuple(vehicle.inertia_kg_m2) for o in options]).T
    drag = tuple(float(c) for c in vehicle.rotor_drag_n_s_per_m)
    plant = (float(vehicle.mass_kg), float(G), J[0].copy(), J[1].copy(), J[2].copy(), drag[0], drag[1],
             float(vehicle.parasitic_drag_n_s2_per_m2))
    upper = np.array([np.inf if o.saturation_n is None else float(o.saturation_n) for o in options])
    noise = _noise(options, -(-n_steps // steps))
    xs = np.empty((n_steps + 1, NX, n))
    cmd = np.empty((n_steps + 1, 4, n))
    app = np.empty((n_steps + 1, 4, n))
    xs[0] = X
    limits = (opt.max_speed_m_s, opt.max_rate_rad_s, opt.max_position_m, opt.min_cos_pitch)
    with np.errstate(all="ignore"):     # the allocation's ratios where a rotor has no yaw share
        kernel.run(X, S, status, k_end, xs, cmd, app, _path_tables(plan, projector.window_m),
                   _gain_tables(plan, steps * dt_s / 2), np.ascontiguousarray(mixer.inverse),
                   np.ascontiguousarray(mixer.matrix), float(vehicle.max_rotor_thrust_n), plant, upper, noise,
                   1.0, float(dt_s), steps, limits)
    ts = np.arange(n_steps + 1) * dt_s
    return [_result(ts, xs[:, :, r], cmd[:, :, r], app[:, :, r], int(status[r]), int(k_end[r]), steps, o)
            for r, o in enumerate(options)]


def _noise(options: Sequence[SimOptions], calls: int) -> np.ndarray:
    """(C, 4, N) rotor noise per control call: each noisy run's generator seeded as
    :func:`~mavreg.sim.closed_loop.simulate` seeds it, drawn in the same order (4 per call);
    (1, 4, N) zeros when no run is noisy."""
    if all(o.rotor_noise_sd_n == 0.0 for o in options):
        return np.zeros((1, 4, len(options)))
    out = np.zeros((calls, 4, len(options)))
    for r, o in enumerate(options):
        if o.rotor_noise_sd_n > 0.0:
            out[:, :, r] = np.random.default_rng(o.seed).normal(0.0, o.rotor_noise_sd_n, (calls, 4))
    return out


def _result(ts, xs, cmd, app, code: int, k: int, steps: int, opt: SimOptions) -> SimResult:
    """One run's :class:`SimResult` as :func:`~mavreg.sim.closed_loop.simulate` would return it."""
    t_k = f"{ts[k]:.6g}"
    if code == kernel.BAD_COMMAND:
        status, reason = SimStatus.DIVERGED, f"controller returned non-finite rotor forces at t = {t_k} s"
        calls = k // steps + 1
    else:
        calls = -(-k // steps)
        if code == kernel.COMPLETED:
            status, reason = SimStatus.COMPLETED, "done at t = 0" if k == 0 else f"done at t = {t_k} s"
        elif code == kernel.DIVERGED:
            why = _divergence(xs[k], opt)
            status = SimStatus.DIVERGED
            reason = f"initial state: {why}" if k == 0 else f"{why} at t = {t_k} s"
        else:
            status, reason = SimStatus.TIMEOUT, f"max duration {opt.max_duration_s:g} s reached"
        cmd[k] = cmd[k - 1] if k > 0 else 0.0
        app[k] = app[k - 1] if k > 0 else 0.0
    return SimResult(t=ts[:k + 1].copy(), x=xs[:k + 1].copy(), rotor_command_n=cmd[:k + 1].copy(),
                     rotor_applied_n=app[:k + 1].copy(), status=status, reason=reason, controller_calls=calls)
