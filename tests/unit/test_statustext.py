"""STATUSTEXT and forced-disarm messages: what a ground station receives from the daemon."""
from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.vehicle import messages as mm

_PARSER = mavlink2.MAVLink(None)


def _wire(msg):
    return _PARSER.decode(bytearray(msg.pack(mavlink2.MAVLink(None, srcSystem=1, srcComponent=191))))


def test_short_text_is_one_message_with_id_zero():
    (m,) = mm.statustext(mm.SEVERITY_WARNING, "mavreg refused: gate_thrust 1.4", 7)
    d = _wire(m)
    assert d.severity == mavlink2.MAV_SEVERITY_WARNING and d.id == 0 and d.text == "mavreg refused: gate_thrust 1.4"


def test_long_text_is_chunked_and_reassembles():
    text = "mavreg recover: " + "position_error in maneuver at s=12.30 m " * 4
    msgs = [_wire(m) for m in mm.statustext(mm.SEVERITY_CRITICAL, text, 42)]
    assert len(msgs) == -(-len(text) // 50) and {m.id for m in msgs} == {42}
    assert [m.chunk_seq for m in msgs] == list(range(len(msgs)))
    assert "".join(m.text for m in msgs) == text and len(msgs[-1].text) < 50


def test_a_full_last_chunk_is_followed_by_an_empty_one():
    msgs = [_wire(m) for m in mm.statustext(mm.SEVERITY_CRITICAL, "x" * 100, 3)]
    assert [len(m.text) for m in msgs] == [50, 50, 0]


def test_text_is_capped_and_ascii():
    msgs = mm.statustext(mm.SEVERITY_CRITICAL, "\u00b0" * 1000, 1)
    assert len(msgs) == 6 and all(len(m.text) <= 50 for m in msgs)


def test_force_disarm_is_param1_zero_param2_21196():
    d = _wire(mm.force_disarm(1, 1))
    assert (d.command, d.param1, d.param2, d.target_system, d.target_component) == (400, 0.0, 21196.0, 1, 1)
