"""Plans of maneuver files and uploads, through the on-disk plan cache.

:func:`plan_file` and :func:`plan_text` load a maneuver (:mod:`mavreg.config.maneuver`) and
plan it through :func:`~mavreg.planning.cache.default_cache`; :func:`plan_cached` plans a
loaded one through a given :class:`~mavreg.planning.cache.PlanCache`. The planning itself is
the pure :func:`mavreg.maneuver.plan.plan_spec`; a cache hit is rebuilt by
:func:`mavreg.maneuver.plan.plan_from_entry`.
"""
from __future__ import annotations

import os

from ..config.controller import ControllerParams
from ..config.maneuver import ManeuverSpec, load_maneuver, load_maneuver_text
from ..config.vehicle import VehicleParams
from ..maneuver.plan import Plan, plan_from_entry, plan_spec
from ..maneuver.plan_entry import PlanEntry
from .cache import PlanCache, default_cache

__all__ = ["plan_cached", "plan_file", "plan_text", "text_in_cache"]


def plan_cached(spec: ManeuverSpec, vehicle: VehicleParams, controller: ControllerParams,
                strict: bool = True, cache: PlanCache | None = None) -> Plan:
    """:func:`~mavreg.maneuver.plan.plan_spec` through ``cache`` (None: plan without one).

    The cache keeps a :class:`~mavreg.maneuver.plan_entry.PlanEntry` (the gains, a tenth
    of the plan's size); a hit computes the path and the nominal again, bit for bit as
    planning does, and puts the stored gains on them. An entry that does not fit is planned
    again.
    """
    if cache is None:
        return plan_spec(spec, vehicle, controller, strict)
    fresh = []

    def build() -> PlanEntry:
        fresh.append(plan_spec(spec, vehicle, controller, strict))
        return PlanEntry.of(fresh[0])

    entry = cache.get_or_plan((spec, vehicle, controller, strict), build)
    if fresh:
        return fresh[0]
    plan = plan_from_entry(spec, vehicle, controller, entry)
    return plan if plan is not None else plan_spec(spec, vehicle, controller, strict)


def plan_file(path: str | os.PathLike, vehicle: VehicleParams, controller: ControllerParams,
              laps: int | None = None, strict: bool = True, use_cache: bool = True) -> Plan:
    """Load and plan a maneuver YAML file (through :func:`~mavreg.planning.cache.default_cache`
    with ``use_cache``)."""
    spec = load_maneuver(path)
    if laps is not None:
        spec = spec.with_laps(laps)
    return plan_cached(spec, vehicle, controller, strict, default_cache() if use_cache else None)


def plan_text(text: str, source: str, vehicle: VehicleParams, controller: ControllerParams,
              strict: bool = True, use_cache: bool = True) -> Plan:
    """Load and plan maneuver YAML text (an upload); errors name ``source``."""
    return plan_cached(load_maneuver_text(text, source), vehicle, controller, strict,
                       default_cache() if use_cache else None)


def text_in_cache(text: str, source: str, vehicle: VehicleParams, controller: ControllerParams,
                  strict: bool = True) -> bool | None:
    """Whether :func:`plan_text` of these would be served from the plan cache (True), plan
    (False), or there is no cache or no plan (None: the cache is off, or the text does not
    load; planning then says why)."""
    cache = default_cache()
    if cache is None:
        return None
    try:
        spec = load_maneuver_text(text, source)
    except Exception:       # the planner's rejection says it, in its own words
        return None
    return cache.has((spec, vehicle, controller, strict))
