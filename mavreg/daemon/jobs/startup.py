"""The daemon's start, said as it goes: compiling the kernels, planning, the vehicle.

Three slow things happen before a vehicle arms, each said as a stage of a
:class:`mavreg.progress.Progress` (module docstring there):

- **compiling the kernels** (:func:`compile_kernels`): the regulator's step and the
  per-sample kernels, compiled by numba on a machine whose cache is cold (a fresh install,
  or a kernel source edited since: :func:`mavreg.accel.kernel_cached` tells before compiling)
  and loaded from the cache in a few tenths of a second otherwise. It runs in a thread of its
  own, so that the planner worker (another process) plans meanwhile: on a 2-core computer the
  two overlap. The thread is a daemon thread: a maneuver refused by the planner ends the
  command at once, without waiting for a compile nobody needs;
- **planning** the maneuver given on the command line (a plan-cache miss is announced:
  :func:`mavreg.planning.plan_io.text_in_cache`);
- **the vehicle** (:class:`PreflightWatch`): no message from it yet, no position estimate
  yet (its EKF), not armed yet. A wait that ends within ``late_s`` is not said; a longer
  one is said when it starts to matter and every ``every_s`` while it lasts.
"""
from __future__ import annotations

import asyncio
import threading
from typing import Callable

from ...accel import ACCELERATED, kernel_cached
from ...config.defaults import MAX_PREDICTION_S
from ...control.controllers import fastpath
from ...control.controllers import step_kernel
from ...control.controllers.sample_warmup import warm_up_sample_kernels
from ...progress import Progress, cpu_speed_factor

__all__ = ["compile_kernels", "kernels_cold", "PreflightWatch", "preflight_wait", "COMPILE_S"]

COMPILE_S = 32.0
"""Seconds the daemon's kernels took to compile from a cold cache on the reference machine
(:data:`mavreg.progress.REFERENCE_LOOP_S`, measured in the same conditions): scaled by
:func:`mavreg.progress.cpu_speed_factor` for the estimate said before compiling."""


def _loop_kernels() -> tuple:
    """The kernels the daemon's loop calls first: the regulator's step, the prediction, the
    observer, the hover LQR (the kernels they call compile with them)."""
    from ...control.controllers import hover_kernel
    from ...control.estimation import observer_kernel, predictor_kernel
    return (step_kernel.regulator_step, predictor_kernel.predict_into, observer_kernel.update,
            hover_kernel.reference, hover_kernel.feedback)


def kernels_cold() -> bool:
    """True when one of the loop's kernels (:func:`_loop_kernels`) is not in numba's cache:
    its first call compiles (a fresh install, an edited kernel source, a warm-up cut short)."""
    return ACCELERATED and any(kernel_cached(k) is False for k in _loop_kernels())


def warm_daemon_kernels(vehicle, control_rate_hz: float, controller, hover) -> None:
    """Compile (or load) every kernel the daemon's loop calls (no clock, no output);
    ``controller`` may be None (the defaults)."""
    fastpath.warm_up()
    warm_up_sample_kernels(vehicle, 1.0 / control_rate_hz,
                           MAX_PREDICTION_S if controller is None else controller.max_prediction_s,
                           None if controller is None else controller.disturbance, hover)


async def compile_kernels(progress: Progress, warm: Callable[[], None]) -> None:
    """Run ``warm`` (:func:`warm_daemon_kernels`) in a daemon thread as a stage of ``progress``:
    announced, with an estimate, when the cache is cold; said only if it is slow otherwise."""
    cold = kernels_cold()
    if cold:
        about_s = 5 * round(COMPILE_S * cpu_speed_factor() / 5) or 5
        doing = f"compiling the controller's kernels (first run on this machine, about {about_s:.0f} s)"
        done = "compiled the controller's kernels"
    else:
        doing, done = "loading the controller's compiled kernels", "loaded the controller's kernels"
    loop = asyncio.get_running_loop()
    finished = loop.create_future()

    def body() -> None:
        try:
            with progress.stage(doing, done, announce=cold):
                warm()
        except BaseException as exc:       # handed to the awaiting coroutine
            _hand_over(loop, finished, exc)
        else:
            _hand_over(loop, finished, None)
    threading.Thread(target=body, name="compile-kernels", daemon=True).start()
    await finished


def _hand_over(loop, future: asyncio.Future, exc: BaseException | None) -> None:
    try:
        loop.call_soon_threadsafe(_settle, future, exc)
    except RuntimeError:        # the loop is closed: the command ended (a refusal) meanwhile
        pass


def _settle(future: asyncio.Future, exc: BaseException | None) -> None:
    if future.done():
        return
    if exc is None:
        future.set_result(None)
    else:
        future.set_exception(exc)


def preflight_wait(heard: bool, has_sample: bool, armed: bool | None, flying_soon: bool) -> str | None:
    """What the daemon waits for before take-off, or None (nothing, or an upload: the
    endpoint says that). ``heard``: any message from the vehicle; ``has_sample``: a complete
    attitude and position sample; ``armed``: the vehicle's last HEARTBEAT; ``flying_soon``:
    a maneuver is queued."""
    if not heard:
        return "waiting for the vehicle (no message from it yet)"
    if not has_sample:
        return ("waiting for the vehicle's position estimate (its EKF: no complete attitude and "
                "position telemetry yet)")
    if flying_soon and not armed:
        return "waiting for the vehicle to arm (its parameters checked, then the arm request)"
    return None


class PreflightWatch:
    """Say a :func:`preflight_wait` that lasts: when it has lasted ``late_s`` and every
    ``every_s`` after, on ``say``; :meth:`update` with the injected time."""

    def __init__(self, say: Callable[[str], None], late_s: float = 1.0, every_s: float = 10.0):
        self.say = say
        self.late_s = float(late_s)
        self.every_s = float(every_s)
        self._what: str | None = None
        self._since_s = 0.0
        self._next_s = 0.0

    def update(self, what: str | None, now_s: float) -> None:
        if what != self._what:
            self._what, self._since_s, self._next_s = what, now_s, now_s + self.late_s
        if what is None or now_s < self._next_s:
            return
        waited_s = now_s - self._since_s
        self.say(what if waited_s < self.late_s + self.every_s / 2 else f"{what} ({waited_s:.0f} s so far)")
        self._next_s = now_s + self.every_s
