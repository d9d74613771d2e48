"""A serve's flights one after another: each flight's record (its outcome, from the same
rule as ``fly``'s), the bounded book, and the numbered logs of which only the newest stay."""
from __future__ import annotations

from pathlib import Path

import pytest

from mavreg.daemon.jobs.flight_book import FlightBook, FlightRecord, NumberedFiles
from mavreg.daemon.flight.supervisor import Phase
from tests.helpers.supervisor_harness import FakePlan, SimVehicle, make_supervisor, run


def test_a_flown_and_landed_flight_is_recorded_ok_with_its_span_and_counters():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    run(sup, veh, 60.0)
    assert sup.phase == Phase.DISARMED
    rec = FlightRecord.of(3, sup, {"median": 0.2}, 12.5)
    assert (rec.number, rec.result, rec.maneuvers) == (3, "ok", ("line",))
    assert rec.touchdown_speed_m_s is not None and rec.touchdown_speed_m_s < 1.0
    first, last = rec.vehicle_span_s
    assert 0.0 <= first < last <= veh.t_ms / 1000.0
    assert rec.counters["samples"] > 0 and rec.counters["actuator_sent"] > 0
    assert "\n" not in rec.line() and rec.line().startswith("flight 3: ok")


def test_a_land_request_before_any_upload_is_no_flight_and_a_stop_in_the_air_is_stopped():
    sup = make_supervisor()
    veh = SimVehicle()
    run(sup, veh, 1.0)
    sup.request_land(1.0)
    run(sup, veh, 2.0)
    assert FlightRecord.of(1, sup, {}, 0.0).result == "no_flight"
    flying = make_supervisor(FakePlan())
    run(flying, SimVehicle(), 12.0)
    assert flying.airborne
    rec = FlightRecord.of(2, flying, {}, 0.0, stopped=True)
    assert rec.result == "stopped" and str(flying.phase) in rec.detail


def test_the_book_counts_every_flight_and_keeps_only_the_newest_records():
    book = FlightBook(keep=3)
    for n in range(1, 8):
        book.add(FlightRecord(n, "ok" if n % 2 else "link_lost", "disarmed", "", (), 0, None, {}, 0.0, {}))
    st = book.status()
    assert st["flown"] == 7 and st["by_result"] == {"link_lost": 3, "ok": 4}
    assert [r["number"] for r in st["last"]] == [5, 6, 7]


def test_numbered_files_keep_the_newest_and_a_single_flight_keeps_its_name(tmp_path):
    files = NumberedFiles(tmp_path / "flight.tlog", keep=2)
    for n in range(1, 6):
        files.begin(n).write_bytes(b"x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["flight-0004.tlog", "flight-0005.tlog"]
    once = NumberedFiles(tmp_path / "one.npz", keep=1, numbered=False)
    assert once.begin(1) == once.begin(7) == tmp_path / "one.npz"
    assert NumberedFiles(Path("/dev/null"), keep=3).begin(5) == Path("/dev/null")    # a device is no log to number
    with pytest.raises(ValueError, match="at least 1"):
        NumberedFiles(tmp_path / "x", keep=0)
