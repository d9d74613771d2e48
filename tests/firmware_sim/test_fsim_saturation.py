"""--rotor-saturation-n: the rotors saturate while the controls keep the vehicle file's scale."""
from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_sim.cli import build_engine, build_parser


def _target(c):
    msg = mavlink2.MAVLink_set_actuator_control_target_message(0, 0, 1, 1, list(c) + [0.0] * 4)
    return mavlink2.MAVLink(None).parse_buffer(msg.pack(mavlink2.MAVLink(None, 1, 191)))[0]


def _engine(*extra):
    args = build_parser().parse_args(["--listen", "udpin:127.0.0.1:0", "--quiet", "--world", "ideal",
                                      "--start", "z_m=-20", "--rotor-time-constant-s", "0", *extra])
    return build_engine(args)[0]


@pytest.mark.parametrize("extra, scale_n, limit_n", [
    ((), 12.0, 12.0),                                   # the vehicle file: 12 N
    (("--max-rotor-thrust-n", "7"), 7.0, 7.0),          # scale and limit move together
    (("--rotor-saturation-n", "7"), 12.0, 7.0),         # only the limit moves
])
def test_a_control_asks_for_its_share_of_the_scale_and_the_rotors_clip_at_the_limit(extra, scale_n, limit_n):
    engine = _engine(*extra)
    try:
        ap, sim = engine.ap, engine.sim
        ap.handle(_target([0.25, 0.5, 0.75, 1.0]), 0.0, sim.state, False)
        assert ap.target_n == pytest.approx([0.25 * scale_n, 0.5 * scale_n, 0.75 * scale_n, scale_n])
        sim.advance(ap.target_n, True, 0)
        expected = [min(f, limit_n) for f in ap.target_n]
        assert sim.applied_n == pytest.approx(expected)    # no lag, no noise: exact
    finally:
        engine.link.close()


def test_bad_saturation_value_is_a_usage_error(capsys):
    from firmware_sim.cli import main
    with pytest.raises(SystemExit) as exc:
        main(["--rotor-saturation-n", "-1", "--listen", "udpin:127.0.0.1:0"])
    assert exc.value.code == 2
    assert "--rotor-saturation-n" in capsys.readouterr().err
