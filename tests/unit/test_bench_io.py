"""The I/O benchmarks' plumbing: figure records, the .tlog reader, the codec figures' shape."""
from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from benchmarks.codec import pymavlink_crc_is_fast, run_codec
from benchmarks.io_helpers import figure, read_tlog
from mavreg.daemon.logs.tlog import TlogWriter


def test_ratio_is_always_times_better_than_the_baseline():
    assert figure(300.0, 100.0, unit="periods/s", higher_is_better=True)["ratio"] == pytest.approx(3.0)
    assert figure(20.0, 100.0, unit="us", higher_is_better=False)["ratio"] == pytest.approx(5.0)
    assert figure(20.0, None, unit="us", higher_is_better=False)["ratio"] is None
    f = figure(1.0, 2.0, target=3.0, unit="x", note="n", higher_is_better=True)
    assert set(f) == {"value", "baseline", "ratio", "target", "met", "unit", "note"} and f["target"] == 3.0
    assert f["met"] is False and figure(3.0, target=3.0, unit="x", higher_is_better=True)["met"] is True
    assert figure(20.0, target=25.0, unit="us", higher_is_better=False)["met"] is True
    assert figure(20.0, unit="us", higher_is_better=False)["met"] is None


def test_tlog_reader_gives_time_component_and_id_of_every_frame(tmp_path):
    clock = iter([100.0, 100.5, 101.25])
    vehicle = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    daemon = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)
    with TlogWriter(tmp_path / "f.tlog", clock_s=lambda: next(clock)) as w:
        w.write(mavlink2.MAVLink_local_position_ned_message(1, 0, 0, 0, 0, 0, 0).pack(vehicle))
        w.write(mavlink2.MAVLink_set_actuator_control_target_message(1, 0, 1, 1, [0.0] * 8).pack(daemon))
        w.write(mavlink2.MAVLink_heartbeat_message(2, 12, 0, 0, 4, 3).pack(vehicle, force_mavlink1=True))
    rows = read_tlog(tmp_path / "f.tlog")
    assert rows == [(100.0, 1, 32), (100.5, 191, 139), (101.25, 1, 0)]


def test_codec_figures_cover_the_hot_messages_and_report_the_crc_path():
    figs = run_codec(quick=True)
    for name in ("ATTITUDE", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", "SET_ACTUATOR_CONTROL_TARGET",
                 "TIMESYNC", "HEARTBEAT"):
        for op in ("pack", "parse"):
            f = figs[f"codec_us.{op}.{name}"]
            assert f["value"] > 0 and f["baseline"] > 0 and f["unit"] == "us"
    assert figs["pymavlink_fast_crc"]["value"] == (1.0 if pymavlink_crc_is_fast() else 0.0)
