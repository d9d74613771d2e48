"""Planning off the event loop, in a worker process.

Planning (loader, nominal, feasibility, Riccati sweep) is seconds of CPU-bound Python
that holds the GIL, so a thread would stall the control loop; it runs in a
:class:`concurrent.futures.ProcessPoolExecutor` (one worker, ``spawn`` context, so the
worker shares no sockets or event loop with the daemon) through ``loop.run_in_executor``.
The worker loads the vehicle and controller files once and returns the picklable Plan,
or the one-line reason a user error (ConfigError, ManeuverError) gave.
"""
from __future__ import annotations

import asyncio
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

__all__ = ["PlanResult", "PlannerPool", "plan_in_worker"]

_CACHE: dict = {}


@dataclass(frozen=True)
class PlanResult:
    """A plan, or the reason there is none."""

    plan: object | None
    reason: str = ""

    @property
    def accepted(self) -> bool:
        return self.plan is not None


def _params(vehicle_path: str, controller_path: str):
    key = (vehicle_path, controller_path)
    if key not in _CACHE:
        from ..config.controller import load_controller
        from ..config.vehicle import load_vehicle
        _CACHE[key] = (load_vehicle(vehicle_path), load_controller(controller_path))
    return _CACHE[key]


def plan_in_worker(yaml_text: str, source: str, vehicle_path: str, controller_path: str) -> PlanResult:
    """Validate and plan one maneuver (runs in the worker process)."""
    from ..maneuver.plan import plan_text
    try:
        vehicle, controller = _params(vehicle_path, controller_path)
        return PlanResult(plan_text(yaml_text, source, vehicle, controller))
    except ValueError as exc:   # ConfigError, ManeuverError: the user's file is at fault
        return PlanResult(None, " ".join(str(exc).split()))


def _warm(vehicle_path: str, controller_path: str) -> bool:
    _params(vehicle_path, controller_path)
    import mavreg.maneuver.plan  # noqa: F401  (import cost paid before the first upload)
    return True


class PlannerPool:
    """One planning worker process shared by every upload."""

    def __init__(self, vehicle_path: str | Path, controller_path: str | Path):
        self.vehicle_path = str(vehicle_path)
        self.controller_path = str(controller_path)
        self._pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
        self.busy = 0

    async def warm_up(self) -> None:
        """Start the worker and import the planner, so the first upload plans at once."""
        loop = asyncio.get_running_loop()
        await loop.run_in_executor(self._pool, _warm, self.vehicle_path, self.controller_path)

    async def plan(self, yaml_text: str, source: str) -> PlanResult:
        loop = asyncio.get_running_loop()
        self.busy += 1
        try:
            return await loop.run_in_executor(self._pool, plan_in_worker, yaml_text, source,
                                              self.vehicle_path, self.controller_path)
        finally:
            self.busy -= 1

    def shutdown(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)
