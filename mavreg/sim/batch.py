r"""Many closed-loop runs of one plan at once: the regulator and the plant vectorized across runs.

:func:`fly_batch` flies N runs of one :class:`~mavreg.maneuver.plan.Plan` on the design model
as :func:`mavreg.sim.maneuver_run.fly_on_design_model` flies one: the regulator at the
control rate with its feedforward led by half a control period, the plant
:math:`\dot x = f(x, M f_{applied})` of eqs 6-17 with the run's own inertia, classical RK4
at ``dt_s``, the command held between calls and clipped to :math:`[0, f_{sat}]`, Gaussian
rotor noise drawn once per control call from the run's seed, and the same exit rules
(``completed`` when the regulator's s reaches the end, ``diverged``, ``timeout`` after the
nominal duration plus ``extra_time_s``). The runs differ by their :class:`BatchRun`: start
offset, plant inertia, rotor noise, saturation, seed. They share the regulator: its
allocation and speed governor (a controller file's sections; default: the paper's), built
by :class:`~mavreg.control.controllers.regulator.ManeuverRegulator` as the sequential
simulator builds it.

Compiled (numba, :mod:`mavreg.sim.batch_kernel`), each run is a scalar loop in time, the
regulator's step the project's compiled kernel
(:func:`mavreg.control.controllers.step_kernel.regulator_step`), RK4 on plain floats, and each run's
:class:`~mavreg.sim.closed_loop.SimResult` agrees with the sequential one to rounding
(``tests/unit/test_batch_sim.py``: 1e-9). Without numba (or with ``MAVREG_PURE=1``, or
``compiled=False``) the runs are flown one after another by the sequential simulator
(:func:`~mavreg.sim.maneuver_run.fly_on_design_model`), the reference itself (the numpy
copy of the whole loop across runs that stood here once is retired: it was a third copy of
the regulator's step and the plant).

Scope: the paper's design (gains (4, 11)), ideal rotors (no lag), no delays, no external
force: what the paper's Section 4 flies on the design model (``mavreg experiment --via sim``
flies its runs that fit here in batches: :mod:`mavreg.experiments.via_batch`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from ..accel import use_compiled
from ..config.regulation import AllocationParams, SpeedGovernorParams
from ..control.controllers.regulator import ManeuverRegulator
from ..control.controllers.step_kernel import ST_S
from ..control.estimation.lag_in_effect import RotorLagInEffect
from ..maneuver.plan import Plan
from ..model.mixer import Mixer
from ..model.quadrotor import NX, QuadrotorModel
from . import batch_kernel
from .batch_kernel import BAD_COMMAND, COMPLETED, DIVERGED, RUNNING
from .closed_loop import SimOptions, SimResult, SimStatus, _divergence
from .maneuver_run import fly_on_design_model

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


def fly_batch(plan: Plan, runs: Sequence[BatchRun], *, control_rate_hz: float = 1000.0,
              dt_s: float = 0.001, extra_time_s: float = 5.0, compiled: Optional[bool] = None,
              allocation: Optional[AllocationParams] = None,
              speed_governor: Optional[SpeedGovernorParams] = None) -> list[SimResult]:
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
    compiled : bool, optional
        The compiled path (:mod:`~mavreg.sim.batch_kernel`) or the sequential simulator
        run by run; default: compiled when numba is in use (:data:`mavreg.accel.ACCELERATED`).
    allocation, speed_governor : optional
        The regulator's allocation and speed governor, as
        :func:`~mavreg.sim.maneuver_run.fly_on_design_model` takes them (default: the paper's
        allocation, no governor).

    Raises
    ------
    ValueError
        For lag-aware gains, an empty batch, a control rate that is not a whole number of
        physics steps, ``compiled=True`` without numba (and whatever :class:`SimOptions`
        refuses in a run).
    """
    if plan.K.shape[-1] != 11:
        raise ValueError(f"the batch simulator flies the paper's design (gains (4, 11)), not gains "
                         f"{plan.K.shape[1:]} (a lag-aware design)")
    if not runs:
        raise ValueError("a batch needs at least one run")
    compiled_path = use_compiled(compiled, "batch")
    steps = int(round(1.0 / (control_rate_hz * dt_s)))
    if steps < 1 or abs(steps * dt_s * control_rate_hz - 1.0) > 1e-9:
        raise ValueError(f"control rate {control_rate_hz} Hz is not a whole number of "
                         f"{dt_s * 1e3:g} ms physics steps")
    if not compiled_path:
        return [fly_on_design_model(plan, offset_m=run.offset_m, inertia_kg_m2=run.inertia_kg_m2,
                                    rotor_noise_sd_n=run.rotor_noise_sd_n, saturation_n=run.saturation_n,
                                    seed=run.seed, control_rate_hz=control_rate_hz, dt_s=dt_s,
                                    extra_time_s=extra_time_s, allocation=allocation,
                                    speed_governor=speed_governor, true_metrics=False).result for run in runs]
    regulator = ManeuverRegulator(plan, plan.vehicle, steps * dt_s, RotorLagInEffect(0.0), allocation=allocation,
                                  speed_governor=speed_governor, compiled=True)
    return _fly_compiled(plan, runs, steps, dt_s, extra_time_s, regulator)


def _fly_compiled(plan: Plan, runs: Sequence[BatchRun], steps: int, dt_s: float,
                  extra_time_s: float, regulator: ManeuverRegulator) -> list[SimResult]:
    """:func:`fly_batch` on the compiled path (``steps`` physics steps per control call), the
    step that of ``regulator``."""
    vehicle = plan.vehicle
    mixer = Mixer.from_vehicle(vehicle)
    projector = regulator.projector
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
    X = np.array(x0s)
    S = np.array([projector.reset(x0[:3]).s for x0 in x0s])
    status = np.full(n, RUNNING, dtype=np.int64)
    k_end = np.zeros(n, dtype=np.int64)
    for r, o in enumerate(options):
        if _divergence(X[r], o) is not None:
            status[r] = DIVERGED
        elif S[r] >= plan.length_m - 1e-6:
            status[r] = COMPLETED
    J = np.array([o.inertia_kg_m2 or tuple(vehicle.inertia_kg_m2) for o in options])
    upper = np.array([np.inf if o.saturation_n is None else float(o.saturation_n) for o in options])
    noise = _noise(options, -(-n_steps // steps))
    xs = np.empty((n, n_steps + 1, NX))
    cmd = np.empty((n, n_steps + 1, 4))
    app = np.empty((n, n_steps + 1, 4))
    xs[:, 0] = X
    limits = (opt.max_speed_m_s, opt.max_rate_rad_s, opt.max_position_m, opt.min_cos_pitch)
    M = np.ascontiguousarray(mixer.matrix)
    fs = regulator.compiled_step
    ST = np.zeros((n, fs.state.size))   # each run's step state, reset to its s
    ST[:, ST_S] = S
    batch_kernel.run(X, ST, status, k_end, xs, cmd, app, (fs.table, fs.s_tab, fs.s_nodes, fs.coef, fs.ends,
                                                             fs.prm), M, QuadrotorModel.from_vehicle(vehicle).kernel_params, J, upper,
                       noise, 1.0, float(dt_s), steps, limits)
    ts = np.arange(n_steps + 1) * dt_s
    return [_result(ts, xs[r], cmd[r], app[r], int(status[r]), int(k_end[r]), steps, o)
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
    if code == BAD_COMMAND:
        status, reason = SimStatus.DIVERGED, f"controller returned non-finite rotor forces at t = {t_k} s"
        calls = k // steps + 1
    else:
        calls = -(-k // steps)
        if code == COMPLETED:
            status, reason = SimStatus.COMPLETED, "done at t = 0" if k == 0 else f"done at t = {t_k} s"
        elif code == DIVERGED:
            why = _divergence(xs[k], opt)
            status = SimStatus.DIVERGED
            reason = f"initial state: {why}" if k == 0 else f"{why} at t = {t_k} s"
        else:
            status, reason = SimStatus.TIMEOUT, f"max duration {opt.max_duration_s:g} s reached"
        cmd[k] = cmd[k - 1] if k > 0 else 0.0
        app[k] = app[k - 1] if k > 0 else 0.0
    return SimResult(t=ts[:k + 1].copy(), x=xs[:k + 1].copy(), rotor_command_n=cmd[:k + 1].copy(),
                     rotor_applied_n=app[:k + 1].copy(), status=status, reason=reason, controller_calls=calls)
