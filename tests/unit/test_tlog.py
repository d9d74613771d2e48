"""The .tlog writer produces pymavlink's format: mavutil and mavlogdump.py read it back."""
import subprocess

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.vehicle.messages import actuator_target, daemon_heartbeat
from mavreg.daemon.logs.tlog import TlogWriter


def test_tlog_round_trip(tmp_path):
    path = tmp_path / "t.tlog"
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)
    clock = iter(1.7e9 + 0.01 * k for k in range(100))
    with TlogWriter(path, clock_s=lambda: next(clock)) as tl:
        tl.write(daemon_heartbeat(True).pack(mav))
        for k in range(5):
            tl.write(actuator_target(1000 + k, 1, 1, [0.1 * k, 0.2, 0.3, 0.4]).pack(mav))
    conn = mavutil.mavlink_connection(str(path))
    msgs = []
    while (m := conn.recv_match()) is not None:
        msgs.append(m)
    assert [m.get_type() for m in msgs] == ["HEARTBEAT"] + ["SET_ACTUATOR_CONTROL_TARGET"] * 5
    assert msgs[3].controls[0] == 0.2 * 1.0 or abs(msgs[3].controls[0] - 0.2) < 1e-6
    assert abs(msgs[0]._timestamp - 1.7e9) < 1e-3 and abs(msgs[5]._timestamp - (1.7e9 + 0.05)) < 1e-3
    out = subprocess.run(["mavlogdump.py", str(path)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0
    assert out.stdout.count("SET_ACTUATOR_CONTROL_TARGET") == 5 and "HEARTBEAT" in out.stdout


def test_actuator_target_refuses_non_finite_and_out_of_range():
    import math
    import pytest
    for bad in ([math.nan, 0, 0, 0], [0, math.inf, 0, 0], [1.5, 0, 0, 0], [0, 0, 0]):
        with pytest.raises(ValueError):
            actuator_target(0, 1, 1, bad)


def test_frames_sent_together_share_one_time_stamp(tmp_path):
    from pymavlink.dialects.v20 import common as m2
    mav = m2.MAVLink(None, srcSystem=1, srcComponent=191)
    frames = [m2.MAVLink_set_actuator_control_target_message(1, 0, 1, 1, [0.5] * 4 + [0] * 4).pack(mav),
              m2.MAVLink_timesync_message(0, 7).pack(mav)]
    clock = iter([12.5, 13.0])
    with TlogWriter(tmp_path / "m.tlog", clock_s=lambda: next(clock)) as w:
        w.write_many(frames)
        w.write_many([])
        assert w.count == 2
    raw = (tmp_path / "m.tlog").read_bytes()
    n0 = len(frames[0])
    assert raw == (12_500_000).to_bytes(8, "big") + frames[0] + (12_500_000).to_bytes(8, "big") + frames[1]
    assert len(raw) == 16 + n0 + len(frames[1])


def test_vehicle_clock_starts_at_the_wall_time_and_follows_the_vehicle():
    from mavreg.daemon.logs.tlog import VehicleClock
    vehicle = [None]
    clock = VehicleClock(lambda: vehicle[0], wall_s=lambda: 1.7e9)
    assert clock() == 1.7e9                      # before the vehicle's first sample: the start
    vehicle[0] = 12.5                            # the vehicle's clock need not start at 0
    assert clock() == 1.7e9
    vehicle[0] = 42.5
    assert clock() == 1.7e9 + 30.0               # vehicle seconds, however fast they came
    vehicle[0] = 3.0                             # a vehicle clock that restarts holds the log still
    assert clock() == 1.7e9 + 30.0


def test_a_lockstep_tlog_spans_the_vehicle_time(tmp_path):
    """Written through the writer: 10 vehicle seconds that took no wall time at all."""
    from mavreg.daemon.logs.tlog import VehicleClock
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    vehicle = [None]
    with TlogWriter(tmp_path / "v.tlog", VehicleClock(lambda: vehicle[0])) as tl:
        for k in range(11):
            vehicle[0] = float(k)
            tl.write(mavlink2.MAVLink_local_position_ned_message(k * 1000, 0, 0, 0, 0, 0, 0).pack(mav))
    conn = mavutil.mavlink_connection(str(tmp_path / "v.tlog"))
    stamps = []
    while (m := conn.recv_match()) is not None:
        stamps.append(m._timestamp)
    assert abs(stamps[-1] - stamps[0] - 10.0) < 1e-6


def test_an_unknown_tlog_clock_is_refused_in_one_line():
    import pytest
    from mavreg.config.controller import load_controller
    from mavreg.daemon.jobs.app import DaemonConfig
    from mavreg.daemon.flight.supervisor import SupervisorParams
    from mavreg.config.paths import PAPER_CONTROLLER
    with pytest.raises(ValueError, match="tlog clock 'gps'"):
        DaemonConfig("udpout:127.0.0.1:1", load_controller(PAPER_CONTROLLER), None, None, SupervisorParams(),
                     tlog_clock="gps")
