"""``mavreg serve`` flies flight after flight without a restart (issue 32, the soak's short
form in the default suite; the full soak is ``mavreg experiment soak``, docs/reliability.md).

The emulator in lockstep and ``serve`` as processes, driven by the campaign's own rig
(:mod:`mavreg.experiments.serve_campaign`) as a user uploads: two hops, a hostile upload
before the second. Each flight has its record in the daemon's status, ok and landed under
1 m/s; the hostile upload is rejected and changes nothing; the logs are one file per flight
and only ``--keep-logs`` of them stay; the serve exits 0 on SIGTERM between flights."""
from __future__ import annotations

import pytest

from mavreg.experiments.serve_campaign import KEEP_LOGS, fly_campaign
from mavreg.experiments.serve_campaign_report import summarize
from mavreg.experiments.serve_draws import FlightDraw
from mavreg.experiments.serve_run import run_serve_campaign

pytestmark = pytest.mark.sitl


def _draws(n: int) -> list[FlightDraw]:
    return [FlightDraw(k, "hop", None, ("unknown_key",) if k == 2 else (), (), False, False)
            for k in range(1, n + 1)]


def test_serve_flies_two_flights_in_one_process_and_bounds_its_logs(tmp_path):
    result = fly_campaign(_draws(2), tmp_path, say=print)
    rows = result["rows"]
    assert [r["record"]["number"] for r in rows] == [1, 2], rows
    assert all(r["record"]["result"] == "ok" for r in rows), [r["record"]["detail"] for r in rows]
    assert all(r["record"]["touchdown_speed_m_s"] < 1.0 for r in rows)
    assert rows[1]["hostile"] == {"unknown_key": "rejected"}
    assert result["serve_exit"] == 0
    sm = summarize("soak", result)
    assert not sm["unsafe"] and not sm["lost_results"] and sm["samples_without_command"] == 0
    # one .tlog per flight (the third is the flight begun after the second), the newest kept
    tlogs = [f for f in result["log_files"] if f.endswith(".tlog")]
    assert tlogs == ["flight-0001.tlog", "flight-0002.tlog", "flight-0003.tlog"][-KEEP_LOGS:]
    assert [f for f in result["log_files"] if f.endswith(".npz")] == ["control-0001.npz", "control-0002.npz"]


@pytest.mark.slow
def test_forty_soak_flights_in_one_serve_stay_flat(tmp_path):
    """The soak's first 40 flights (about 10 min): every flight has its outcome, nothing
    unsafe or lost, and memory, descriptors and threads within 5 % from flight 20 on."""
    sm = run_serve_campaign("soak", 0, 40, tmp_path)
    assert sm["flights"] == 40 and not sm["lost_results"] and not sm["unsafe"], sm
    assert sm["hostile_uploads"] == 8 and sm["hostile_not_rejected"] == 0
    for name, g in sm["growth"].items():
        assert g is not None and g["growth_pct"] <= 5.0, (name, g)
