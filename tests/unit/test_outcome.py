"""The fly outcome: ok only for a flight flown within its envelope and landed; otherwise the
first cause, in one line."""
from __future__ import annotations

import math
from types import SimpleNamespace

from mavreg.daemon.jobs.flight_book import outcome
from mavreg.daemon.flight.phases import Phase
from mavreg.daemon.flight.records import Outcome


def _sup(phase=Phase.DISARMED, failure=None, succeeded=True, finished=True, t=42.0, reason=""):
    return SimpleNamespace(phase=phase, failure=failure, succeeded=succeeded, finished=finished,
                           last_sample=SimpleNamespace(time_s=t), reason=reason)


def test_ok_only_when_the_supervisor_succeeded_and_the_emulator_exited_cleanly():
    assert outcome(_sup(), 0, 300.0) is None
    assert outcome(_sup(), None, 300.0) is None            # a vehicle of one's own


def test_the_supervisors_first_bound_wins():
    f = Outcome("impact", Phase.MANEUVER, 26.3, 12.5, 22.6, 1.5, "m/s", "descending at 22.6 m/s",
                "motors stopped (forced disarm)")
    got = outcome(_sup(failure=f, succeeded=False), 3, 300.0)
    assert got is f
    line = got.line()
    assert "\n" not in line and line.startswith("impact in maneuver at s=12.50 m, t=26.300 s: 22.6 m/s (limit 1.5 m/s)")
    assert got.as_dict()["action"] == "motors stopped (forced disarm)"


def test_a_crash_the_daemon_did_not_see_fails_the_flight():
    got = outcome(_sup(), 3, 300.0)
    assert got.bound == "emulator_exit" and "crash" in got.detail and got.value == 3.0


def test_timeout_and_not_flown():
    got = outcome(_sup(phase=Phase.MANEUVER, succeeded=False, finished=False), 0, 120.0)
    assert got.bound == "timeout" and got.phase == Phase.MANEUVER and "120" in got.detail
    got = outcome(_sup(succeeded=False, reason="land requested before take-off; nothing to fly"), 0, 120.0)
    assert got.bound == "not_flown" and "nothing to fly" in got.detail
    assert math.isnan(got.value) and got.as_dict()["value"] is None
