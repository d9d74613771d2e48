"""The vehicle reboots between flights, on a stock ArduCopter (issue 32 item 2, its SITL):
``mavreg serve`` flies a hop, a ground station reboots the autopilot, and the next upload
flies in the same ``serve``, judged by the SITL's true state (SIM_STATE).

The daemon has the SITL's first MAVLink port (SERIAL0); the test is a pilot's ground station
on its second (SERIAL1, :class:`~harness.ardupilot_sitl.GroundLink`): it asks for the
reboot (MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN) and receives SIM_STATE for the truth. Slow (about
3 minutes in real time: two EKF starts, two hops) and skipped where the SITL is absent.
"""
from __future__ import annotations

import signal
import time

import pytest

from mavreg.daemon.jobs.endpoint import request
from harness.ardupilot_flight import PILOT_PARAMS, sim_touchdowns
from tests.helpers.ardupilot_serve import serve_on_arducopter, set_pilot_params
from harness.ardupilot_sitl import M, SitlError, require_ardupilot
from tests.helpers.repo import ROOT as REPO

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

HOP = (REPO / "tests/sitl/gcs_hop.yaml").read_text()


def _hop(serve, sock, name: str, number: int) -> str:
    """Upload the hop, land after it (serve holds for the next upload otherwise): its line."""
    assert request(sock, {"op": "upload", "name": name, "yaml": HOP}, 600)["ok"]
    serve.wait_line("maneuver finished", 240, nth=number)
    assert request(sock, {"op": "land"}, 60)["ok"]
    return serve.wait_line(f"flight {number}:", 120, nth=1 if number == 1 else 2)   # after "waiting"


def _daemon_s(line: str) -> float:
    """The daemon's clock of a log line (``daemon  105.250 s ...``)."""
    return float(line.split()[1])


def _params_after_reboot(gcs, timeout_s: float = 30.0) -> dict:
    """The pilot's parameters as the rebooted autopilot has them (read once it answers)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return {name: gcs.get_param(name, 1.0) for name in PILOT_PARAMS}
        except SitlError:                # still booting: its first requests go unanswered
            if time.monotonic() > deadline:
                raise


def test_serve_flies_again_after_the_arducopter_reboots_between_flights(tmp_path):
    """Reboot between flights: the daemon follows the rebooted SITL to the new UDP port it
    sends from (its old one silent for 2 s: :mod:`mavreg.daemon.vehicle.peers`), sees ArduCopter's
    clock go back, rebuilds, waits through its start (a position estimate about 40 s after
    boot, as at a cold start) and flies the next upload.

    The SITL started by start.sh comes back from a reboot with its default parameters: it
    runs its own command line again, ``--wipe`` included (eeprom.bin is wiped; started
    without ``--wipe`` it keeps them, as a vehicle does). So the ground station sets the
    pilot's parameters (``GUID_OPTIONS``, ``GUID_TIMEOUT``, ``ATC_ANGLE_BOOST``) again after
    the reboot, as a pilot whose vehicle lost them would, before the next upload; mavreg
    never sets them, it checks them again before that flight's arm."""
    require_ardupilot()
    t0 = time.monotonic()
    with serve_on_arducopter(tmp_path) as (gcs, serve, sock):
        first = _hop(serve, sock, "first", 1)
        serve.wait_line("flight 2: waiting for an upload", 30)
        ack = gcs.command_long(M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1)
        t_reboot = time.monotonic()
        seen = serve.wait_line("vehicle_rebooted", 60)
        t_seen = time.monotonic()
        after_reboot = _params_after_reboot(gcs)
        set_pilot_params(gcs)
        t_upload = time.monotonic()
        second = _hop(serve, sock, "second", 2)
        status = request(sock, {"op": "status"}, 60)["status"]
        code = serve.stop(signal.SIGINT, 60)
        rows = list(gcs.sim_state)
    downs = sim_touchdowns(rows)
    armed = [ln for ln in serve.lines[serve.lines.index(seen):] if "vehicle armed" in ln]
    print(f"\n{first}\n{seen}\n{second}\nparameters after the reboot: {after_reboot}\n"
          f"wall {time.monotonic() - t0:.0f} s; reboot at {t_reboot - t0:.0f} s, seen "
          f"{t_seen - t_reboot:.1f} s after it, second upload {t_upload - t_reboot:.1f} s after it, "
          f"armed {_daemon_s(armed[0]) - _daemon_s(seen):.1f} s after the reboot was seen; "
          f"touchdowns (wall s, m/s): {[(round(t - t0, 1), round(v, 2)) for t, v in downs]}")
    assert ack.result == M.MAV_RESULT_ACCEPTED
    assert code == 0, serve.lines[-20:]
    assert first.startswith("flight 1: ok") and second.startswith("flight 2: ok"), (first, second)
    assert "went back from" in seen and "on the ground" in seen, seen
    records = status["flights"]["last"]          # each flight's own supervisor counts its reboots
    assert [(r["number"], r["result"], r["counters"]["reboots"]) for r in records] == [(1, "ok", 0), (2, "ok", 1)]
    assert not any("motors stopped" in ln or "motors_stopped" in ln for ln in serve.lines)
    assert len(downs) == 2 and all(v < 1.0 for _, v in downs), downs
    assert downs[0][0] < t_reboot < downs[1][0]
