"""One flight's status: the supervisor's part of the control endpoint's ``status`` answer.

Read-only: gathered from the flight's context and counters into a JSON-ready dict; nothing here
changes them. The daemon's whole answer, with the link, planner and loop, is
:func:`mavreg.daemon.jobs.status.status_report`.
"""
from __future__ import annotations

import math

__all__ = ["supervisor_status"]


def supervisor_status(ctx, counters, state_counters, envelope_peaks: dict) -> dict:
    """One flight's part of the report: its phase, maneuvers, vehicle, outcome, envelope peaks
    and counters (the supervisor's and the state assembler's), from the flight's context
    (:class:`~mavreg.daemon.flight.context.FlightContext`)."""
    a = state_counters
    return {
        "phase": ctx.phase, "reason": ctx.reason, "s_m": None if math.isnan(ctx.s_m) else ctx.s_m,
        "active": None if ctx.active is None else ctx.active.plan.name,
        "pending": [q.plan.name for q in ctx.pending], "done": list(ctx.maneuvers_done),
        "vehicle_mode": None if ctx.heard.status is None else ctx.heard.status.mode,
        "vehicle_armed": None if ctx.heard.status is None else ctx.heard.status.armed,
        "failure": None if ctx.failure is None else ctx.failure.as_dict(),
        "recoveries": ctx.recovery.count, "touchdown_speed_m_s": ctx.landing.touchdown_speed_m_s,
        "envelope_peaks": {k: dict(v) for k, v in sorted(envelope_peaks.items())},
        "counters": {**counters.__dict__, "state_late": a.late, "state_unmatched": a.unmatched,
                     "state_euler_refused": a.euler_near_vertical, "state_non_finite": a.non_finite},
    }
