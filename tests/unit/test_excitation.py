"""The identification flight's excitation: the doublet schedule, off by default, refused in
the rotors output, and sent as clean rate steps (docs/identify.md, *The identification
flight*). The flight itself: tests/sitl/test_rates_sitl.py."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mavreg.cli.main import main
from mavreg.config.paths import DEFAULT_VEHICLE, PARAMS_DIR
from mavreg.config.vehicle import load_vehicle, with_output
from mavreg.daemon.flight.excitation import MAX_TURN_RAD, ExcitationParams, RateStep
from mavreg.daemon.flight.output import RateOutput
from mavreg.daemon.vehicle.peers import VehicleIds
from mavreg.daemon.flight.supervisor import Supervisor, SupervisorParams
from mavreg.model.mixer import Mixer

FREESTYLE = PARAMS_DIR / "vehicles" / "ardupilot_freestyle.yaml"


def test_the_schedule_roll_pitch_yaw_pulses_with_their_amplitudes_and_timing():
    e = ExcitationParams()
    assert e.amplitude_rad_s == (0.5, 0.5, 0.1) and e.step_s == 0.15 and e.rest_s == 0.2 and e.settle_s == 0.6
    assert e.duration_s == pytest.approx(3 * 3 * 1.4)
    # the first round: roll, pitch, yaw; +a, -a, +a for 0.15, 0.3, 0.15 s, 0 for rest_s, then the hover LQR alone
    assert e.rate_at(0.0) == (0, 0.5) and e.rate_at(0.149) == (0, 0.5)
    assert e.rate_at(0.15) == (0, -0.5) and e.rate_at(0.449) == (0, -0.5)
    assert e.rate_at(0.45) == (0, 0.5) and e.rate_at(0.599) == (0, 0.5)
    assert e.rate_at(0.6) == (0, 0.0) and e.rate_at(0.799) == (0, 0.0)
    assert e.rate_at(0.801) is None and e.rate_at(1.39) is None
    assert e.rate_at(1.4) == (1, 0.5) and e.rate_at(1.6) == (1, -0.5)
    assert e.rate_at(2.9) == (2, 0.1)
    # the second round reversed, the third as the first; nothing before or after, or at NaN
    assert e.rate_at(4.3) == (0, -0.5) and e.rate_at(4.4) == (0, 0.5)
    assert e.rate_at(8.5) == (0, 0.5)
    for t in (-0.01, e.duration_s, e.duration_s + 5.0, float("nan"), float("inf")):
        assert e.rate_at(t) is None
    # each pulse's rates and attitude integrate to zero (the attitude and the velocity it
    # gives come back); its peak turn is a * step_s
    dt = 1e-4
    t = np.arange(0.0, e.duration_s, dt) + dt / 2
    steps = [e.rate_at(float(x)) for x in t]
    for axis, a in enumerate(e.amplitude_rad_s):
        r = np.array([s[1] if s is not None and s[0] == axis else 0.0 for s in steps])
        angle = np.cumsum(r) * dt
        assert abs(angle[-1]) < 1e-9 and abs(angle.sum() * dt) < 1e-6
        assert np.max(np.abs(angle)) == pytest.approx(a * 0.15, abs=1e-3)
        assert np.count_nonzero(r) * dt == pytest.approx(3 * 0.6, abs=1e-3)
        held = sum(1 for s in steps if s is not None and s[0] == axis)
        assert held * dt == pytest.approx(3 * 0.8, abs=1e-3)      # the pulses and their rests


def test_amplitudes_that_would_leave_the_holds_bounds_are_refused():
    for bad in ({"amplitude_rad_s": (1.5, 0.6, 0.6)}, {"amplitude_rad_s": (0.6, 0.0, 0.6)},
                {"amplitude_rad_s": (0.6, 0.6)}, {"step_s": 0.01}, {"repeats": 0},
                {"amplitude_rad_s": (1.0, 1.0, 1.0), "step_s": 0.3}):
        with pytest.raises(ValueError):
            ExcitationParams(**bad)
    assert 1.0 * 0.2 <= MAX_TURN_RAD        # the largest amplitude at 0.2 s is accepted
    ExcitationParams(amplitude_rad_s=(1.0, 1.0, 1.0), step_s=0.2)


def test_off_by_default():
    assert SupervisorParams().excitation is None
    from mavreg.cli.main import build_parser
    parser, _ = build_parser()
    maneuver = str(PARAMS_DIR / "maneuvers" / "barrel_roll.yaml")
    for cmd in (["fly", maneuver], ["serve"]):
        assert parser.parse_args(cmd).identify_excitation is False


def test_refused_in_the_rotors_output_in_one_line(capsys):
    vehicle = with_output(load_vehicle(DEFAULT_VEHICLE), "rotors")
    with pytest.raises(ValueError, match="needs --output rates"):
        Supervisor(vehicle, SupervisorParams(excitation=ExcitationParams()), lambda plan, rotor_lag: None)
    Supervisor(with_output(load_vehicle(DEFAULT_VEHICLE), "rates"),
               SupervisorParams(excitation=ExcitationParams()), lambda plan, rotor_lag: None)    # accepted there
    maneuver = PARAMS_DIR / "maneuvers" / "barrel_roll.yaml"
    assert main(["fly", str(maneuver), "--output", "rotors", "--identify-excitation"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--identify-excitation" in err[0] and "--output rates" in err[0]


@pytest.mark.parametrize("path", [DEFAULT_VEHICLE, FREESTYLE])
def test_the_pulse_goes_out_as_a_clean_step_on_its_axis(path):
    """The pulse's rate replaces the hover's on its axis, exactly, even where the output
    compensates an autopilot's attitude term (ArduCopter's file); the other axes are as
    without it. Negative control: without the excitation the axis carries the hover's rate."""
    vehicle = with_output(load_vehicle(path), "rates")
    mixer = Mixer.from_vehicle(vehicle).matrix
    forces = np.linalg.solve(mixer, [vehicle.mass_kg * 9.81, 0.02, -0.01, 0.003])
    x = np.zeros(12)
    x[9:12] = (0.1, -0.05, 0.02)
    plain, excited = RateOutput(vehicle, VehicleIds(1)), RateOutput(vehicle, VehicleIds(1))
    for k in range(50):
        t = 0.002 * k
        r0, th0 = plain.command(forces, x, t)
        r1, th1 = excited.command(forces, x, t, excitation=RateStep(1, -0.6))
        assert r1[1] == -0.6 and th1 == th0
        np.testing.assert_allclose(r1[[0, 2]], r0[[0, 2]], rtol=0, atol=1e-12)
        assert abs(r0[1] + 0.6) > 0.3
    msg = excited.message(1.0, 0.1, forces, x, RateStep(2, 0.6))
    assert msg.body_yaw_rate == pytest.approx(0.6)


def test_a_pulse_is_clipped_to_the_files_rate_limit():
    base = with_output(load_vehicle(DEFAULT_VEHICLE), "rates")
    ri = dataclasses.replace(base.rate_interface, max_body_rate_rad_s=(0.5, 0.5, 0.5))
    vehicle = dataclasses.replace(base, rate_interface=ri)
    out = RateOutput(vehicle, VehicleIds(1))
    forces = np.full(4, vehicle.mass_kg * 9.81 / 4)
    rates, _ = out.command(forces, np.zeros(12), 0.0, excitation=RateStep(0, 0.6))
    assert rates[0] == 0.5


def test_leaving_the_hold_cuts_the_excitation_short_and_says_so():
    """A phase change in the middle (a recovery, say) ends the excitation for good, with the
    end STATUSTEXT that identify closes its window by; no pulse goes out after it."""
    from mavreg.daemon.flight.phases import Output, Phase
    sup = Supervisor(with_output(load_vehicle(DEFAULT_VEHICLE), "rates"),
                     SupervisorParams(excitation=ExcitationParams()), lambda plan, rotor_lag: None)
    ctx, out = sup.ctx, Output()
    ctx.phase, ctx.excitation.start_vehicle_s, ctx.excitation.rate_step = Phase.HOLD, 1.0, RateStep(0, 0.5)
    sup.flight.set_phase(out, Phase.RECOVER, "a bound")
    assert ctx.excitation.rate_step is None and ctx.excitation.end_vehicle_s is not None
    ends = [e for e in out.events if e.kind == "excitation"]
    assert len(ends) == 1 and ends[0].detail.startswith("end: cut short")
    texts = [m.text for m in out.messages if m.get_type() == "STATUSTEXT"]
    assert texts and texts[0].startswith(b"mavreg excitation: end:" if isinstance(texts[0], bytes)
                                         else "mavreg excitation: end:")
