r"""Closed-loop simulation on the design model (issue 2 item 8).

The plant is :class:`~mavreg.model.quadrotor.QuadrotorModel` (eqs 6-17), driven through the
rotor mixer of eq 34, ``u = M f_applied``, plus an optional external force:

.. math::
    \dot x = f_{plant}(x, M f_{applied}) + \begin{bmatrix}0_6\\ R^T F_{ext}/m\\ 0_3\end{bmatrix},

integrated by classical fixed-step RK4 with physics step ``dt_s``. The controller
``controller(t, x) -> rotor forces (4,)`` is called every ``control_period_steps`` physics
steps (at ``t = k * control_period_steps * dt_s``) and its command is held (zero-order hold)
until the next call. Between command and plant:

``f_applied = clip(lag(f_command) + noise, 0, saturation_n)``: the command (clipped to
[0, saturation_n]) passes a first-order lag of time constant ``rotor_time_constant_s``
(exact for a held command; the physics step uses the lagged force's mean over the step),
then Gaussian noise of standard deviation ``rotor_noise_sd_n`` per rotor, drawn from a
seeded ``numpy.random.Generator`` either once per control period (``noise_redraw="control"``:
the propellers' error is held with the command) or every physics step (``"physics"``).
Rotor forces are never negative.

Delays (rounded to whole physics steps): the controller called at ``t`` sees the state of
``t - measurement_delay_s``, and its command reaches the rotors at ``t + command_delay_s``.

The plant may differ from the design (``SimOptions.inertia_kg_m2``): the controller is
whatever the caller designed, the plant is the model with that inertia. Exit status, like
RotorPy's: ``completed`` (``done(t, x)`` became true; checked at every physics step, also at
t = 0), ``timeout`` (``max_duration_s`` reached) or ``diverged`` (non-finite state or
command, speed, body rate or position beyond bounds, or pitch at the Euler singularity).
"""
from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ..model.mixer import Mixer
from ..model.quadrotor import NX, QuadrotorModel
from ..model.rotor_lag import lag_decay, lag_toward, mean_fraction
from .plant_step import RpyStep, So3Step

__all__ = ["SimOptions", "SimResult", "SimStatus", "simulate", "window_force"]

Controller = Callable[[float, np.ndarray], np.ndarray]
ForceFn = Callable[[float, np.ndarray], np.ndarray]
DoneFn = Callable[[float, np.ndarray], bool]


class SimStatus(str, enum.Enum):
    """How a simulation ended."""

    COMPLETED = "completed"
    TIMEOUT = "timeout"
    DIVERGED = "diverged"


@dataclass(frozen=True)
class SimOptions:
    """Simulation settings (SI units). Arrays given for tuple fields are converted."""

    initial_state: tuple[float, ...] = (0.0,) * NX
    """x(0) = (p, phi theta psi, v_body, w_body)."""
    dt_s: float = 1e-3
    """Physics (RK4) step."""
    control_period_steps: int = 1
    """The controller runs every this many physics steps (rate 1 / (steps * dt_s))."""
    max_duration_s: float = 10.0
    """Timeout."""
    inertia_kg_m2: Optional[tuple[float, float, float]] = None
    """Plant inertia diagonal (jx, jy, jz); None: the design model's."""
    rotor_noise_sd_n: float = 0.0
    """Standard deviation of the Gaussian noise added to each rotor force."""
    noise_redraw: str = "control"
    """'control': one draw per control period; 'physics': one draw per physics step."""
    seed: Optional[int] = None
    """Seed of the noise generator when no ``rng`` is passed to :func:`simulate`."""
    saturation_n: Optional[float] = None
    """Per-rotor upper limit; None: none. The lower limit is always 0."""
    rotor_time_constant_s: float = 0.0
    """First-order lag of each rotor's force (0: ideal rotors, the design model's eq 34)."""
    measurement_delay_s: float = 0.0
    """Age of the state the controller is given."""
    command_delay_s: float = 0.0
    """Time from a controller call to its command reaching the rotors."""
    thrust_scale: float = 1.0
    """Force (and torque) each rotor gives per unit of its applied command (a sagging battery: 0.9)."""
    force_fn: Optional[ForceFn] = None
    """External force ``force_fn(t, x) -> (3,)`` in NED (N), evaluated at the start of each
    physics step and held over it (exact for windows on the step grid; first order in dt
    for state-dependent forces such as drag)."""
    done: Optional[DoneFn] = None
    """Stop condition ``done(t, x) -> bool``."""
    max_speed_m_s: float = 50.0
    max_rate_rad_s: float = 100.0
    max_position_m: float = 1e4
    min_cos_pitch: float = 1e-3
    """Diverged when |cos(theta)| falls below this (Euler-angle singularity at +-90 deg);
    ``attitude="rpy"`` only."""
    attitude: str = "rpy"
    """How the plant integrates its attitude: ``rpy``, the paper's Euler kinematics (eqs
    9-11), singular at pitch +-90 deg; ``so3``, the rotation matrix (R' = R hat(w),
    re-orthonormalized every step), for maneuvers through any attitude. The state handed to
    the controller and recorded keeps roll-pitch-yaw either way."""

    def __post_init__(self):
        x0 = tuple(float(v) for v in np.asarray(self.initial_state, dtype=float).ravel())
        if len(x0) != NX or not np.all(np.isfinite(x0)):
            raise ValueError(f"initial_state must be {NX} finite numbers")
        object.__setattr__(self, "initial_state", x0)
        if self.inertia_kg_m2 is not None:
            J = tuple(float(v) for v in np.asarray(self.inertia_kg_m2, dtype=float).ravel())
            if len(J) != 3 or min(J) <= 0.0:
                raise ValueError(f"inertia_kg_m2 must be 3 positive numbers, not {J}")
            object.__setattr__(self, "inertia_kg_m2", J)
        if not (self.dt_s > 0.0 and np.isfinite(self.dt_s)):
            raise ValueError(f"dt_s must be positive, not {self.dt_s}")
        if int(self.control_period_steps) != self.control_period_steps or self.control_period_steps < 1:
            raise ValueError(f"control_period_steps must be a positive integer, not "
                             f"{self.control_period_steps}")
        if not self.max_duration_s > 0.0:
            raise ValueError(f"max_duration_s must be positive, not {self.max_duration_s}")
        if not self.rotor_noise_sd_n >= 0.0:
            raise ValueError(f"rotor_noise_sd_n must be >= 0, not {self.rotor_noise_sd_n}")
        if self.attitude not in ("rpy", "so3"):
            raise ValueError(f"attitude must be 'rpy' or 'so3', not {self.attitude!r}")
        if self.noise_redraw not in ("control", "physics"):
            raise ValueError(f"noise_redraw must be 'control' or 'physics', not {self.noise_redraw!r}")
        if self.saturation_n is not None and not self.saturation_n > 0.0:
            raise ValueError(f"saturation_n must be positive or None, not {self.saturation_n}")
        if not (np.isfinite(self.thrust_scale) and self.thrust_scale > 0.0):
            raise ValueError(f"thrust_scale must be positive, not {self.thrust_scale}")
        for name in ("rotor_time_constant_s", "measurement_delay_s", "command_delay_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0, not {v}")

    @property
    def control_period_s(self) -> float:
        return self.control_period_steps * self.dt_s


@dataclass(frozen=True)
class SimResult:
    """Samples at ``t_k = k dt_s``. Row k of the force arrays is what acted over
    ``[t_k, t_k + dt_s)``; the last row repeats the previous one (no step follows it)."""

    t: np.ndarray
    """(K,) time (s)."""
    x: np.ndarray
    """(K, 12) state."""
    rotor_command_n: np.ndarray
    """(K, 4) rotor forces asked for by the controller (held)."""
    rotor_applied_n: np.ndarray
    """(K, 4) rotor forces applied: command + noise, clipped to [0, saturation]."""
    status: SimStatus
    reason: str
    controller_calls: int

    @property
    def completed(self) -> bool:
        return self.status is SimStatus.COMPLETED

    @property
    def stable(self) -> bool:
        """Not diverged."""
        return self.status is not SimStatus.DIVERGED


def window_force(force_n, t_start_s: float, t_end_s: float) -> ForceFn:
    """A constant NED force (N) acting for ``t_start_s <= t < t_end_s``, zero otherwise."""
    F = np.asarray(force_n, dtype=float).reshape(3)
    zero = np.zeros(3)

    def force(t: float, x: np.ndarray) -> np.ndarray:
        return F if t_start_s <= t < t_end_s else zero

    return force


def _divergence(x: np.ndarray, opt: SimOptions) -> Optional[str]:
    if not np.all(np.isfinite(x)):
        return "non-finite state"
    speed = np.sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8])
    if speed > opt.max_speed_m_s:
        return f"speed {speed:.3g} m/s > {opt.max_speed_m_s:g} m/s"
    rate = np.sqrt(x[9] * x[9] + x[10] * x[10] + x[11] * x[11])
    if rate > opt.max_rate_rad_s:
        return f"body rate {rate:.3g} rad/s > {opt.max_rate_rad_s:g} rad/s"
    dist = np.abs(x[0:3]).max()
    if dist > opt.max_position_m:
        return f"position {dist:.3g} m from the origin > {opt.max_position_m:g} m"
    if opt.attitude == "rpy" and abs(np.cos(x[4])) < opt.min_cos_pitch:
        return f"pitch {np.degrees(x[4]):.2f} deg at the Euler-angle singularity"
    return None


class _RotorLine:
    """A command's way to the rotors: the transport delay, the clip to [0, saturation], the
    rotor lag (:mod:`mavreg.model.rotor_lag`, its mean over each physics step applied) and
    the noise (drawn per control call or per physics step)."""

    def __init__(self, opt: SimOptions, rng: np.random.Generator):
        dt = opt.dt_s
        self.cmd_lag = int(round(opt.command_delay_s / dt))
        self.pending: list = []          # (physics step it acts from, command)
        self.decay = lag_decay(dt, opt.rotor_time_constant_s)
        self.mean_frac = mean_fraction(dt, opt.rotor_time_constant_s, self.decay)
        self.lagged = self.acting = None  # (before the first command: as if it had always acted)
        self.noise = np.zeros(4)
        self.upper = np.inf if opt.saturation_n is None else float(opt.saturation_n)
        self.sd = float(opt.rotor_noise_sd_n)
        self.per_physics = opt.noise_redraw == "physics"
        self.rng = rng

    def command(self, i: int, command: np.ndarray) -> None:
        """A control call's command at physics step i."""
        self.pending.append((i + self.cmd_lag, command))
        if self.acting is None:
            self.acting = np.clip(command, 0.0, self.upper)
            self.lagged = self.acting.copy()
        if self.sd > 0.0 and not self.per_physics:
            self.noise = self.rng.normal(0.0, self.sd, 4)

    def applied(self, i: int) -> np.ndarray:
        """The rotor forces applied over physics step i."""
        while self.pending and self.pending[0][0] <= i:
            self.acting = np.clip(self.pending.pop(0)[1], 0.0, self.upper)
        mean = lag_toward(self.lagged, self.acting, self.mean_frac)
        self.lagged = lag_toward(self.lagged, self.acting, self.decay)
        if self.sd > 0.0 and self.per_physics:
            self.noise = self.rng.normal(0.0, self.sd, 4)
        return np.clip(mean + self.noise, 0.0, self.upper)


def simulate(model: QuadrotorModel, mixer: Mixer, controller: Controller,
             options: SimOptions = SimOptions(), *,
             rng: Optional[np.random.Generator] = None) -> SimResult:
    """Run the closed loop until ``done``, timeout or divergence.

    Parameters
    ----------
    model : QuadrotorModel
        The design model; the plant is this model with ``options.inertia_kg_m2`` if given.
    mixer : Mixer
        Eq 34, ``u = mixer.matrix @ f_applied``.
    controller : callable ``(t, x) -> (4,)``
        Rotor forces (N) asked for; called at the control rate, held in between.
    options : SimOptions
    rng : numpy.random.Generator, optional
        Noise source; default ``numpy.random.default_rng(options.seed)``.

    Returns
    -------
    SimResult
        Arrays trimmed to the samples actually simulated, status and reason.
    """
    opt = options
    plant = model if opt.inertia_kg_m2 is None else dataclasses.replace(
        model, inertia_kg_m2=opt.inertia_kg_m2)
    if rng is None:
        rng = np.random.default_rng(opt.seed)
    M = np.asarray(mixer.matrix, dtype=float)
    dt = opt.dt_s
    n_steps = int(np.ceil(opt.max_duration_s / dt - 1e-9))
    ts = np.arange(n_steps + 1) * dt
    xs, cmd, app = np.empty((n_steps + 1, NX)), np.empty((n_steps + 1, 4)), np.empty((n_steps + 1, 4))
    inv_mass, force_fn = 1.0 / plant.mass_kg, opt.force_fn
    period = int(opt.control_period_steps)
    step = So3Step(plant) if opt.attitude == "so3" else RpyStep(plant)
    rotors = _RotorLine(opt, rng)
    x = np.array(opt.initial_state, dtype=float)
    xs[0] = x
    meas_lag = int(round(opt.measurement_delay_s / dt))
    command, applied = np.zeros(4), np.zeros(4)
    calls, last_filled = 0, False          # last_filled: row k's forces already written (controller failure)
    status, reason, k = SimStatus.TIMEOUT, f"max duration {opt.max_duration_s:g} s reached", n_steps
    why = _divergence(x, opt)
    if why is not None:
        status, reason, k = SimStatus.DIVERGED, f"initial state: {why}", 0
    elif opt.done is not None and opt.done(0.0, x):
        status, reason, k = SimStatus.COMPLETED, "done at t = 0", 0
    else:
        for i in range(n_steps):
            t = ts[i]
            if i % period == 0:
                seen = xs[max(i - meas_lag, 0)].copy()
                command = np.asarray(controller(t, seen), dtype=float).reshape(4)
                calls += 1
                if not np.all(np.isfinite(command)):
                    cmd[i], app[i], last_filled = command, applied, True
                    status, reason, k = (SimStatus.DIVERGED, "controller returned non-finite "
                                         f"rotor forces at t = {t:.6g} s", i)
                    break
                rotors.command(i, command)
            applied = rotors.applied(i)
            cmd[i], app[i] = command, applied
            u = M @ (applied * opt.thrust_scale)
            F = None if force_fn is None else np.asarray(force_fn(t, x), dtype=float) * inv_mass
            x = step(x, u, F, dt)
            xs[i + 1] = x
            why = _divergence(x, opt)
            if why is not None:
                status, reason, k = SimStatus.DIVERGED, f"{why} at t = {ts[i + 1]:.6g} s", i + 1
                break
            if opt.done is not None and opt.done(ts[i + 1], x):
                status, reason, k = SimStatus.COMPLETED, f"done at t = {ts[i + 1]:.6g} s", i + 1
                break
    if not last_filled:
        cmd[k] = cmd[k - 1] if k > 0 else 0.0
        app[k] = app[k - 1] if k > 0 else 0.0
    return SimResult(t=ts[:k + 1], x=xs[:k + 1], rotor_command_n=cmd[:k + 1],
                     rotor_applied_n=app[:k + 1], status=status, reason=reason,
                     controller_calls=calls)
