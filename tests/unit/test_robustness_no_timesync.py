"""firmware_sim --no-timesync: a vehicle that does not answer TIMESYNC (the robustness cell)."""
from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

from mavreg.config.vehicle import load_vehicle
from firmware_sim.autopilot import Autopilot, AutopilotConfig
from firmware_sim.cli import build_parser
from firmware_sim.params import default_vehicle_path
from firmware_sim.stabilizer import Stabilizer


def _autopilot(answer: bool) -> Autopilot:
    v = load_vehicle(default_vehicle_path())
    stab = Stabilizer(v.mass_kg, [[0.01, 0, 0], [0, 0.01, 0], [0, 0, 0.02]], v.arm_length_m,
                      v.drag_torque_ratio_m, v.max_rotor_thrust_n)
    return Autopilot(AutopilotConfig(max_rotor_thrust_n=v.max_rotor_thrust_n, answer_timesync=answer),
                     stab, v.mass_kg * 9.81 / 4)


def _request(ts1: int):
    msg = mavlink2.MAVLink_timesync_message(0, ts1)
    return mavlink2.MAVLink(None).parse_buffer(msg.pack(mavlink2.MAVLink(None, 1, 191)))[0]


def test_a_request_is_answered_by_default_and_ignored_with_no_timesync():
    state, ground = (0.0,) * 3 + (1.0, 0.0, 0.0, 0.0) + (0.0,) * 6, True
    on = _autopilot(True)
    assert [m.get_type() for m in on.handle(_request(7), 1.0, state, ground)] == ["TIMESYNC"]
    off = _autopilot(False)
    assert off.handle(_request(7), 1.0, state, ground) == []
    assert off.drops["unsupported"] == 1


def test_the_flag_is_off_unless_given():
    assert build_parser().parse_args([]).no_timesync is False
    assert build_parser().parse_args(["--no-timesync"]).no_timesync is True
