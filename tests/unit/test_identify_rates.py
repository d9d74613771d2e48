"""``mavreg identify`` on flights of the rates output: the thrust map and the rate loop
(mavreg.identify.rate_fit), the tlog reader's SET_ATTITUDE_TARGET, and the command."""
from __future__ import annotations

import re

from mavreg.config.paths import DEFAULT_VEHICLE

import json

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from tests.helpers.identify_synth import MASS_KG, synthetic_rate_flight, write_tlog
from mavreg.cli.main import main
from mavreg.config.vehicle import load_vehicle
from mavreg.daemon.vehicle.messages import actuator_target, rate_target
from mavreg.daemon.logs.tlog import TlogWriter
from mavreg.identify.fit import FitOptions, IdentifyError, identify
from mavreg.identify.flightlog import read_flight
from mavreg.identify.rate_fit import identify_rates

TRUTH = {"hover_thrust": 0.35, "expo": 0.4, "rate_tau_s": (0.0315, 0.028, 0.045), "delay_s": 0.013,
         "thrust_tau_s": 0.025}
"""The autopilot of the synthetic flights; the delay is a whole number of the simulation's
1 ms step and not of the 2 ms sample period."""

KNOWN_DELAY = FitOptions(delay_s=TRUTH["delay_s"])
"""The collective's delay given, as TIMESYNC gives it to the command (the rate loop's is
searched all the same)."""


def _flight(**kw):
    args = dict(duration_s=12.0, gyro_sd=0.02, hover_thrust=TRUTH["hover_thrust"], expo=TRUTH["expo"],
                rate_tau_s=TRUTH["rate_tau_s"], delay_s=TRUTH["delay_s"], thrust_tau_s=TRUTH["thrust_tau_s"])
    return synthetic_rate_flight(**{**args, **kw})


@pytest.fixture(scope="module")
def flight():
    """12 s closed loop, velocity noise 2 cm/s (0.2 s Gauss-Markov), gyro noise 0.02 rad/s."""
    return _flight(seed=5)


@pytest.fixture(scope="module")
def fitted(flight):
    return identify_rates(flight, MASS_KG, KNOWN_DELAY)


def _covers(e, truth, slack=0.0):
    return e.low - slack <= truth <= e.high + slack


GRID_S = 1e-4
"""The rate loop's intervals are a few tenths of a millisecond wide on these flights, as
narrow as the bootstrap's local grid (1 ms by 0.5 ms, its minima placed by parabolas) can
resolve: they are checked to this slack."""


def test_the_thrust_map_and_the_rate_loop_are_recovered_with_intervals_covering_the_truth(fitted):
    r = fitted
    assert r.hover_thrust.value == pytest.approx(TRUTH["hover_thrust"], rel=0.01)
    assert r.thrust_expo.value == pytest.approx(TRUTH["expo"], rel=0.1)
    assert r.collective_time_constant_s.value == pytest.approx(TRUTH["thrust_tau_s"], rel=0.1)
    for e, truth in ((r.hover_thrust, TRUTH["hover_thrust"]), (r.thrust_expo, TRUTH["expo"]),
                     (r.collective_time_constant_s, TRUTH["thrust_tau_s"])):
        assert _covers(e, truth)
    for name, tau in zip(("roll", "pitch", "yaw"), TRUTH["rate_tau_s"]):
        a = r.rate_axes[name]
        assert a.time_constant_s.value == pytest.approx(tau, rel=0.1) and _covers(a.time_constant_s, tau, GRID_S)
        assert a.delay_s.value == pytest.approx(TRUTH["delay_s"], rel=0.1)
        assert _covers(a.delay_s, TRUTH["delay_s"], GRID_S)
        assert a.free_gain == pytest.approx(1.0, abs=0.01)
        assert a.residual_rms_rad_s < 0.016                 # the gyro noise, 0.02 / sqrt(2) per interval mean
    rp = r.rate_axes["roll_pitch"].time_constant_s.value    # one tau for both: between the two
    assert TRUTH["rate_tau_s"][1] < rp < TRUTH["rate_tau_s"][0]
    assert r.collective_delay_s.value == TRUTH["delay_s"] and r.collective_delay_s.why == "given"
    assert r.drag_n_s_per_m[1].value == pytest.approx(0.35, rel=0.05)


def test_a_linearized_thrust_finds_no_curvature():
    """ArduPilot linearizes its thrust (e = 0): the interval of e contains 0."""
    r = identify_rates(_flight(seed=6, expo=0.0), MASS_KG, KNOWN_DELAY)
    assert abs(r.thrust_expo.value) < 0.05 and _covers(r.thrust_expo, 0.0)
    assert r.hover_thrust.value == pytest.approx(TRUTH["hover_thrust"], rel=0.01)


def test_a_rate_loop_of_the_wrong_order_leaves_a_larger_residual(fitted):
    """Negative control: two cascaded lags (of half the time constant each) are not the
    first-order model; the same noise leaves 1.5 times the residual and the delay absorbs
    the misfit."""
    r = identify_rates(_flight(seed=5, rate_order=2), MASS_KG, KNOWN_DELAY)
    for name in ("roll", "pitch"):
        wrong, right = r.rate_axes[name], fitted.rate_axes[name]
        assert wrong.residual_rms_rad_s > 1.4 * right.residual_rms_rad_s
        assert not _covers(wrong.delay_s, TRUTH["delay_s"])


def test_a_flight_that_does_not_turn_does_not_identify_the_rate_loop():
    """Negative control: no rate excitation (the commands are the attitude hold's answer to
    the gyro noise): every axis is reported not identified, the thrust map still is."""
    r = identify_rates(_flight(seed=7, excite=0.0, duration_s=5.0), MASS_KG, KNOWN_DELAY)
    for a in r.rate_axes.values():
        assert a.time_constant_s.value is None and "does not turn" in a.time_constant_s.why
    json.dumps(r.as_dict(), allow_nan=False)          # strict JSON: no NaN for the axes not fitted
    assert r.hover_thrust.value == pytest.approx(TRUTH["hover_thrust"], rel=0.02)


def test_a_vehicle_that_reports_no_body_rates_is_refused_in_one_line(flight):
    import dataclasses
    silent = dataclasses.replace(flight, body_rates_rad_s=np.zeros_like(flight.body_rates_rad_s))
    with pytest.raises(IdentifyError) as e:
        identify_rates(silent, MASS_KG)
    assert "reports no body rates" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(IdentifyError, match="not body rates"):
        identify_rates(dataclasses.replace(flight, output="rotors"), MASS_KG)
    with pytest.raises(IdentifyError, match="not rotor forces"):       # nor the rotor fit on rates
        identify(flight, MASS_KG, 12.0)


# ------------------------------------------------------------------ reading the tlog

VEH = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
DMN = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)


def _samples(tl, ms, rates_q=(0.0, 0.0, 0.0), rates_e=None):
    if rates_e is not None:
        tl.write(mavlink2.MAVLink_attitude_message(ms, 0, 0, 0, *rates_e).pack(VEH))
    tl.write(mavlink2.MAVLink_attitude_quaternion_message(ms, 1.0, 0, 0, 0, *rates_q).pack(VEH))
    tl.write(mavlink2.MAVLink_local_position_ned_message(ms, 0, 0, -1, 0, 0, 0).pack(VEH))


def test_rate_commands_make_a_rates_flight_with_body_rates(tmp_path):
    path = tmp_path / "f.tlog"
    with TlogWriter(path, clock_s=lambda: 1.7e9) as tl:
        _samples(tl, 0, rates_q=(0.1, -0.2, 0.3))
        tl.write(rate_target(1, 1, 1, (1.0, 2.0, 3.0), 0.4).pack(DMN))
        _samples(tl, 2, rates_e=(0.5, 0.6, 0.7))                 # zero in ATTITUDE_QUATERNION
        other = mavlink2.MAVLink_set_attitude_target_message(3, 1, 1, 0, [1, 0, 0, 0], 9, 9, 9, 0.9)
        tl.write(other.pack(DMN))                                 # an attitude target: not ours
        tl.write(rate_target(3, 1, 1, (-1.0, 0.0, 0.5), 0.6).pack(DMN))
    s = read_flight(path)
    assert s.output == "rates"
    np.testing.assert_allclose(s.body_rates_rad_s, [[0.1, -0.2, 0.3], [0.5, 0.6, 0.7]], atol=1e-6)
    np.testing.assert_allclose(s.command_controls, [[1, 2, 3, 0.4], [-1, 0, 0.5, 0.6]], atol=1e-6)
    assert np.allclose(s.command_t_s, [0.0, 0.002])


def test_a_tlog_of_both_outputs_is_refused(tmp_path):
    path = tmp_path / "f.tlog"
    with TlogWriter(path, clock_s=lambda: 1.7e9) as tl:
        _samples(tl, 0)
        tl.write(rate_target(1, 1, 1, (0.0, 0.0, 0.0), 0.4).pack(DMN))
        _samples(tl, 2)
        tl.write(actuator_target(3000, 1, 1, [0.3] * 4).pack(DMN))
    with pytest.raises(ValueError) as e:
        read_flight(path)
    assert "both rotor commands (1) and rate commands (1)" in str(e.value) and "\n" not in str(e.value)


# ------------------------------------------------------------------ the command

def test_identify_a_rates_tlog_json_table_and_vehicle_file(flight, tmp_path, capsys):
    tlog = tmp_path / "rates.tlog"
    write_tlog(flight, tlog, link_delay_s=0.010)
    out = tmp_path / "rates.yaml"
    assert main(["identify", str(tlog), "--json", "--write-vehicle", str(out), "--replicates", "100"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["output"] == "rates" and d["delay_source"].startswith("TIMESYNC 10.0 ms")
    assert d["hover_thrust"]["value"] == pytest.approx(TRUTH["hover_thrust"], rel=0.01)
    rp = d["rate_loop"]["roll_pitch"]
    assert rp["delay_s"]["value"] == pytest.approx(TRUTH["delay_s"], abs=5e-4)
    assert rp["loop_delay_s"]["value"] == pytest.approx(TRUTH["delay_s"] - 0.010, abs=5e-4)   # less TIMESYNC
    v = load_vehicle(out)
    assert v.output == "rates" and v.thrust_scale == 1.0
    ri = v.rate_interface
    assert ri.hover_thrust == pytest.approx(d["hover_thrust"]["value"], abs=1e-4)
    assert ri.thrust_expo == pytest.approx(d["thrust_expo"]["value"], abs=1e-4)
    assert ri.rate_time_constant_s == pytest.approx(rp["time_constant_s"]["value"], abs=1e-4)
    assert ri.rate_delay_s == pytest.approx(rp["loop_delay_s"]["value"], abs=1e-4)
    assert v.rotor_time_constant_s == pytest.approx(d["collective_time_constant_s"]["value"], abs=1e-4)


def test_the_vehicle_file_table_and_a_block_section_rewritten(fitted, tmp_path):
    """The table names the file's values; a block-style ``rate_interface:`` section is
    replaced whole by the writer (not only its first line)."""
    from mavreg.cli.identify_cmd import write_vehicle
    from mavreg.cli.identify_rates import format_result
    src = tmp_path / "block.yaml"
    base = re.sub(r"(?m)^rate_interface:\n(?:[ #].*\n|\n)*", "", DEFAULT_VEHICLE.read_text())
    src.write_text(base + "output: rates\nrate_interface:\n"
                   "  hover_thrust: 0.5\n  rate_time_constant_s: 0.05\n\n  max_body_rate_rad_s: [9, 9, 4]\n"
                   "estimate_latency_s: 0.004\n")
    vehicle = load_vehicle(src)
    text = format_result(fitted, vehicle, "f.tlog", "given (13.0 ms)")
    for words in ("rates output", "hover thrust t_h", "0.5\n", "thrust expo e", "collective time const (ms)",
                  "roll + pitch (written)", "vehicle file: rate_time_constant_s 50 ms", "no TIMESYNC"):
        assert words in text
    dst = tmp_path / "out.yaml"
    values = write_vehicle(src, dst, fitted)
    v = load_vehicle(dst)
    assert v.rate_interface.hover_thrust == values["rate_interface"]["hover_thrust"] != 0.5
    assert v.rate_interface.max_body_rate_rad_s == (9, 9, 4)          # the file's limits kept
    assert v.estimate_latency_s == 0.004 and "  hover_thrust: 0.5" not in dst.read_text()


def test_identify_rates_timesync_delay_needs_timesync(flight, tmp_path, capsys):
    tlog = tmp_path / "short.tlog"
    write_tlog(_flight(seed=8, duration_s=1.0), tlog, timesync_every=0)
    code = main(["identify", str(tlog), "--delay", "timesync"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "no TIMESYNC replies" in err[0]
