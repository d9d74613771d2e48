"""What the running daemon reports: the control endpoint's ``status`` answer and the latency
figures of a flight's summary.

Read-only: the report gathers the counters the daemon's parts keep (supervisor, link,
signing, ground stations, planner, the loop's tick gaps, the link delay and the disturbance
estimate) into one JSON-ready dict; nothing here changes them.
"""
from __future__ import annotations

from typing import Iterable

__all__ = ["status_report", "latency_summary"]


def latency_summary(samples_ns: Iterable[int]) -> dict:
    """Median and 99th percentile (ms) of datagram-receipt-to-command latencies in ns, and
    their count; ``{}`` without any."""
    lat = sorted(samples_ns)
    if not lat:
        return {}
    n = len(lat)
    return {"median": lat[n // 2] / 1e6, "p99": lat[min(n - 1, int(0.99 * n))] / 1e6, "samples": n}


def status_report(daemon, tick_s: float) -> dict:
    """The status of ``daemon`` (a :class:`~mavreg.daemon.jobs.app.Daemon`) whose tick task runs
    every ``tick_s``: the supervisor's status with the link's counters, signing, uploads,
    ground stations, latency, planning, the loop, the link delay and the disturbance."""
    sup = daemon.supervisor
    st = sup.status()
    if daemon.link is not None:
        st["link"] = dict(daemon.link.counters.__dict__)
        peer = daemon.link.peer
        st["vehicle_ids"] = {"system_id": peer.vehicle.system_id, "component_id": peer.vehicle.component_id,
                             "pinned": peer.vehicle.pinned,
                             "dropped_by_system": {str(k): v for k, v in sorted(peer.heard.frames.items())}}
    sg = daemon.signing
    st["signing"] = None if sg is None else {"accepted": sg.accepted, **sg.drops,
                                             "state_file": str(sg.path)}
    st["uploads"] = dict(daemon.uploads)
    st["flights"] = {"current": daemon.flight_number, "waiting_for_disarm": daemon._waiting_disarm,
                     **daemon.book.status()}
    tlog = getattr(daemon, "_tlog", None)
    st["tlog"] = None if tlog is None else tlog.status()
    if daemon.gcs is not None:
        st["gcs"] = daemon.gcs.status()
    st["latency_ms"] = latency_summary(daemon.latency_ns)
    st["planning"] = 0 if daemon.pool is None else daemon.pool.busy
    pool = daemon.pool
    st["planner"] = None if pool is None else {"worker_pid": pool.worker_pid, "busy": pool.busy,
                                               "restarts": pool.restarts, "timeouts": pool.timeouts}
    st["loop"] = {"max_tick_gap_ms": daemon.max_tick_gap_s * 1e3, "max_tick_gap_phase": daemon.max_tick_gap_phase,
                  "max_tick_cpu_ms": daemon.max_tick_cpu_s * 1e3,
                  "tick_ms": tick_s * 1e3,
                  "endpoint_refused": 0 if daemon.endpoint is None else daemon.endpoint.refused}
    st["link_delay_ms"] = sup.delay.status(predicting=sup.forecaster.predict)
    fc = sup.forecaster
    dist = fc.disturbance
    st["disturbance"] = None if dist is None else {
        "drag_n_s_per_m": list(dist.drag_n_s_per_m), "force_ned_n": list(dist.force_ned_n),
        "thrust_scale": dist.thrust_scale, "updates": fc.observer.updates,
        "rejected": fc.observer.rejected}
    if dist is not None and fc.observer.torque is not None:
        tq = fc.observer.torque
        st["disturbance"]["torque_bias"] = {"constant_n_m": list(dist.torque_bias[:3]),
                                            "per_thrust_m": list(dist.torque_bias[3:]),
                                            "updates": tq.updates, "rejected": tq.rejected}
    if dist is not None and fc.observer.lag is not None:
        lag, in_effect = fc.observer.lag, fc.rotor_lag
        st["disturbance"]["rotor_lag"] = {"time_constant_s": in_effect.estimate_s, "applied_s": in_effect.applied_s,
                                          "file_s": in_effect.file_s, "sd_s": lag.sd_s,
                                          "updates": lag.updates, "rejected": lag.rejected}
    return st
