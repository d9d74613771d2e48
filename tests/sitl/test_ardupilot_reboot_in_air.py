"""The vehicle reboots in the air, on a stock ArduCopter (issue 32 item 2, its SITL):
``mavreg serve`` takes off for a hop and, in the hold after the take-off, a ground station
on the SITL's second MAVLink port (SERIAL1) reboots the autopilot.

ArduPilot refuses ``MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN`` while armed (``MAV_RESULT_FAILED``)
unless param6 is its force value, 20190226 (``GCS_MAVLINK::handle_preflight_reboot`` in
``libraries/GCS_MAVLink/GCS_Common.cpp``); the test asks both ways and checks both answers.

What the SITL does at a reboot: it acknowledges, waits 0.2 s and runs its own command line
again (the same process id, ``--wipe`` included: default parameters). Its physics starts
again too: the vehicle is at home, on the ground, at rest, disarmed, a few milliseconds
after it was 1.5 m up (SIM_STATE shows the jump). So the SITL cannot show the fall a real
vehicle would make (motors off in the air, then an impact): no test here measures one; the
emulator's in-air reboot (``tests/sitl/test_reboot_sitl.py``) does. What it does show is
what the daemon sees of a real reboot: the link falls silent, then a new boot (clock from 0,
no telemetry streamed, a new UDP source port, disarmed) that is not the vehicle it flew.

"Ends as described" (docs/daemon.md, *The vehicle reboots*) is then, on what is observable:
the flight is a loss (the record's result is ``vehicle_rebooted``, ``link_lost`` or
``vehicle_mode``, whichever is seen first, and the reboot is named: the event, the record or
the log), the daemon never sends a motor stop (no ``motors_stopped``, no forced disarm in the
``.tlog``), it does not crash (no traceback; SIGINT later exits 0, "stopped on request"),
and ``serve`` stays up: it says the next flight begins once the vehicle reports itself
disarmed, then that it does, then waits for an upload. The ground station sets the pilot's
parameters again after the reboot (the SITL lost them), as a pilot would, so that the
daemon's checks let the next flight begin. Slow (about 2 minutes in real time) and skipped
where the SITL is absent.
"""
from __future__ import annotations

import signal
import time

import pytest

from mavreg.daemon.jobs.endpoint import request
from tests.helpers.ardupilot_serve import serve_on_arducopter, set_pilot_params
from harness.ardupilot_sitl import M, require_ardupilot
from tests.helpers.repo import ROOT as REPO

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

HOP = (REPO / "tests/sitl/gcs_hop.yaml").read_text()
FORCE_REBOOT = 20190226
"""ArduPilot's param6 that lets MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN reboot an armed vehicle."""
LOSS_BOUNDS = ("vehicle_rebooted", "link_lost", "vehicle_mode")


def _reboot(gcs, force: bool):
    """MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN (param1 1: the autopilot) from the ground station."""
    return gcs.command_long(M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1, 0, 0, 0, 0, FORCE_REBOOT if force else 0)


def _wait_for_sim_state(gcs, since: float, rows: int = 25, timeout_s: float = 15.0) -> None:
    """Until the ground station has ``rows`` SIM_STATE rows received after ``since`` (wall s)."""
    deadline = time.monotonic() + timeout_s
    while sum(1 for t, *_ in list(gcs.sim_state) if t >= since) < rows and time.monotonic() < deadline:
        time.sleep(0.1)                   # the pump thread fills gcs.sim_state


def _altitudes(rows, t_from: float, t_to: float) -> list[float]:
    return [alt for t, alt, *_ in rows if t_from <= t < t_to]


def test_serve_reports_the_arducopter_rebooting_in_the_air_as_a_loss(tmp_path):
    require_ardupilot()
    t0 = time.monotonic()
    with serve_on_arducopter(tmp_path) as (gcs, serve, sock):
        assert request(sock, {"op": "upload", "name": "hop", "yaml": HOP}, 600)["ok"]
        hold = serve.wait_line("[hold] phase", 240)
        refused = _reboot(gcs, force=False)
        forced = _reboot(gcs, force=True)
        t_reboot = time.monotonic()
        record = serve.wait_line("flight 1:", 60)
        next_flight = serve.wait_line("the next flight begins once", 60)
        seen = serve.wait_line("vehicle_rebooted", 60)
        t_seen = time.monotonic()
        set_pilot_params(gcs)
        disarmed = serve.wait_line("the vehicle reports itself disarmed (mode", 60)
        waiting = serve.wait_line("flight 2: waiting for an upload", 60)
        status = request(sock, {"op": "status"}, 60)["status"]
        _wait_for_sim_state(gcs, t_reboot + 1.0)
        t_end = time.monotonic()
        code = serve.stop(signal.SIGINT, 60)
        rows = list(gcs.sim_state)
    log = serve.lines
    before, after = _altitudes(rows, t_reboot - 1.0, t_reboot), _altitudes(rows, t_reboot + 1.0, t_end)
    ground = rows[0][1]
    print("\n" + "\n".join([hold, record, next_flight, disarmed, waiting, seen])
          + f"\nwall {t_end - t0:.0f} s; reboot refused unforced (ACK {refused.result}), forced ACK "
          f"{forced.result}; seen {t_seen - t_reboot:.1f} s after it; SIM_STATE altitude above the "
          f"start {before[-1] - ground if before else None:.2f} m before, "
          f"{min(after) - ground if after else float('nan'):.2f}..{max(after) - ground if after else float('nan'):.2f} m after")
    assert refused.result == M.MAV_RESULT_FAILED and forced.result == M.MAV_RESULT_ACCEPTED, (refused, forced)
    assert before and before[-1] - ground > 0.5, before[-5:]           # it was in the air
    assert after and max(after) - ground < 0.1, after[:5]              # the SITL starts again on the ground
    (flight,) = status["flights"]["last"]
    assert flight["number"] == 1 and flight["result"] in LOSS_BOUNDS, flight
    assert "went back from" in seen and "(the boot the previous flight flew)" in seen, seen
    assert "reports itself disarmed" in next_flight, next_flight
    assert code == 0, log[-20:]
    assert not any("Traceback" in ln for ln in log), log[-30:]
    assert not any("motors stopped" in ln or "motors_stopped" in ln or "terminate" in ln for ln in log), log
