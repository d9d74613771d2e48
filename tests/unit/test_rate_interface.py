"""The rate-and-thrust interface of a stock autopilot: its thrust map and the rate loop's
inverse (mavreg.model.rate_interface), and the daemon's rate output (mavreg.daemon.flight.output)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mavreg.config.loader import ConfigError
from mavreg.config.paths import DEFAULT_VEHICLE
from mavreg.config.vehicle import G, RateInterfaceParams, load_vehicle, with_output
from mavreg.daemon.vehicle import messages as mm
from mavreg.daemon.flight.output import RateOutput, RotorOutput, command_output
from mavreg.daemon.vehicle.peers import VehicleIds
from mavreg.model.mixer import Mixer
from mavreg.model.rate_interface import ThrustMap, rate_command, rate_response_rhs

RATES = RateInterfaceParams(hover_thrust=0.3, thrust_expo=0.4, rate_time_constant_s=0.03,
                            rate_delay_s=0.01, max_body_rate_rad_s=(10.0, 10.0, 5.0))


@pytest.fixture(scope="module")
def vehicle():
    return dataclasses.replace(load_vehicle(DEFAULT_VEHICLE), output="rates", rate_interface=RATES)


@pytest.mark.parametrize("expo", [0.0, 0.25, 0.7, 1.0])
def test_thrust_map_hover_and_round_trip(expo):
    m = ThrustMap(0.8, 0.2, expo)
    assert m.thrust_n(0.2) == pytest.approx(0.8 * G, rel=1e-12)        # the hover thrust holds the mass
    t = np.linspace(0.0, 1.0, 101)
    back = np.array([m.normalized(f) for f in m.thrust_n(t)])
    np.testing.assert_allclose(back, t, atol=1e-12)
    assert np.all(np.diff(m.thrust_n(t)) > 0)                            # monotonic


def test_thrust_map_clips_and_refuses_nan():
    m = ThrustMap(1.0, 0.5, 0.3)
    assert m.normalized(-3.0) == 0.0
    assert m.normalized(10 * m.max_thrust_n) == 1.0
    assert np.isnan(m.normalized(float("nan")))
    with pytest.raises(ValueError):
        ThrustMap(1.0, 1.0, 0.0)


def test_rate_command_gives_the_torque_exactly():
    """Through the first-order rate loop, the rate command makes the body's angular
    acceleration the one the torque gives the rigid body (random states and torques)."""
    rng = np.random.default_rng(1)
    J = np.array([0.0176, 0.0177, 0.034])
    tau = 0.025
    for _ in range(50):
        w, g = rng.normal(0, 4, 3), rng.normal(0, 0.5, 3)
        rigid = (g - np.cross(w, J * w)) / J
        through_loop = rate_response_rhs(w, rate_command(w, g, J, tau), tau)
        np.testing.assert_allclose(through_loop, rigid, rtol=1e-12, atol=1e-12)
    # negative control: without the gyroscopic term the spinning body gets another torque
    w = np.array([6.0, -5.0, 3.0])
    naive = w + tau * np.zeros(3) / J
    assert np.linalg.norm(rate_response_rhs(w, naive, tau) - (-np.cross(w, J * w) / J)) > 1.0


def test_rate_command_with_delay_predicted_matches_rigid_body():
    """A rate loop with a pure delay d, fed commands computed at the state predicted d ahead
    (the daemon's prediction), flies the rigid body's trajectory under the same torque law."""
    J = np.array([0.0176, 0.0177, 0.034])
    tau, d, dt = 0.02, 0.01, 0.0005
    torque = lambda t: np.array([0.05 * np.sin(7 * t), -0.04 * np.cos(5 * t), 0.01])   # noqa: E731
    rigid = solve_ivp(lambda t, w: (torque(t) - np.cross(w, J * w)) / J, (0, 0.5), np.zeros(3),
                      max_step=dt, dense_output=True, rtol=1e-10, atol=1e-12)
    n = int(round(0.5 / dt))
    w = np.zeros(3)
    for k in range(n):
        t = k * dt
        # the command that acts now was sent at t - d from the state then predicted to t
        w_pred = rigid.sol(t) if t >= d else w
        cmd = rate_command(w_pred, torque(t), J, tau) if t >= d else np.zeros(3)
        w = w + dt * rate_response_rhs(w, cmd, tau)
    assert np.max(np.abs(w - rigid.sol(0.5))) < 0.02 * np.max(np.abs(rigid.sol(0.5)))


def test_rate_output_realizes_the_wrench(vehicle):
    out = RateOutput(vehicle, VehicleIds(1))
    mixer = Mixer.from_vehicle(vehicle)
    wrench = np.array([9.0, 0.02, -0.01, 0.005])
    x = np.zeros(12)
    x[9:12] = (0.5, -0.3, 0.2)
    rates, thrust = out.command(mixer.inverse @ wrench, x)
    tmap = ThrustMap.from_params(vehicle.mass_kg, RATES)
    assert tmap.thrust_n(thrust) == pytest.approx(9.0, rel=1e-9)
    np.testing.assert_allclose(rates, rate_command(x[9:12], wrench[1:], vehicle.inertia_kg_m2, 0.03), atol=1e-12)
    msg = out.message(12.345, None, mixer.inverse @ wrench, x)
    assert msg.get_type() == "SET_ATTITUDE_TARGET" and msg.type_mask == 128
    assert (msg.time_boot_ms, msg.thrust) == (12345, pytest.approx(thrust, abs=1e-6))
    np.testing.assert_allclose([msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate], rates, atol=1e-6)


def test_a_slower_yaw_loop_is_inverted_on_its_own_axis(vehicle):
    """``yaw_rate_time_constant_s``: the yaw command leads by the yaw loop's own time constant,
    and through per-axis first-order loops the body still gets the torque exactly; roll and
    pitch are as without it."""
    slow_yaw = dataclasses.replace(vehicle, rate_interface=dataclasses.replace(RATES, yaw_rate_time_constant_s=0.35))
    mixer = Mixer.from_vehicle(vehicle)
    wrench = np.array([9.0, 0.02, -0.01, 0.005])
    x = np.zeros(12)
    x[9:12] = (0.5, -0.3, 0.2)
    same, _ = RateOutput(vehicle, VehicleIds(1)).command(mixer.inverse @ wrench, x)
    rates, _ = RateOutput(slow_yaw, VehicleIds(1)).command(mixer.inverse @ wrench, x)
    np.testing.assert_allclose(rates[:2], same[:2], atol=1e-12)
    tau = np.array([0.03, 0.03, 0.35])
    J = np.asarray(vehicle.inertia_kg_m2)
    rigid = (wrench[1:] - np.cross(x[9:12], J * x[9:12])) / J
    np.testing.assert_allclose(rate_response_rhs(x[9:12], rates, tau), rigid, rtol=1e-12, atol=1e-12)
    # negative control: the roll-pitch time constant on yaw gives the body a tenth of its yaw torque
    assert abs(rate_response_rhs(x[9:12], same, tau)[2] - rigid[2]) > 0.5 * abs(rigid[2])


def test_rate_output_clips_rates_and_idles(vehicle):
    out = RateOutput(vehicle, VehicleIds(1))
    mixer = Mixer.from_vehicle(vehicle)
    rates, _ = out.command(mixer.inverse @ np.array([9.0, 50.0, -50.0, 50.0]), np.zeros(12))
    np.testing.assert_allclose(np.abs(rates), (10.0, 10.0, 5.0))
    rates, thrust = out.command(np.zeros(4), np.r_[np.zeros(9), 1.0, 2.0, 3.0])
    assert thrust == 0.0 and not np.any(rates)


def test_rate_target_refuses_bad_values():
    with pytest.raises(ValueError):
        mm.rate_target(0, 1, 1, (0.0, float("nan"), 0.0), 0.5)
    with pytest.raises(ValueError):
        mm.rate_target(0, 1, 1, (0.0, 0.0, 0.0), 1.2)


def test_output_choice_and_its_errors(vehicle):
    base = load_vehicle(DEFAULT_VEHICLE)
    assert isinstance(command_output(base, VehicleIds(1)), RotorOutput)
    assert isinstance(command_output(vehicle, VehicleIds(1)), RateOutput)
    with pytest.raises(ConfigError, match="rate_interface"):
        with_output(dataclasses.replace(base, rate_interface=None), "rates")
    assert with_output(vehicle, "rotors").output == "rotors"
    with pytest.raises(ValueError, match="rate_interface"):
        dataclasses.replace(base, output="rates", rate_interface=None)


def test_the_dialect_key_and_its_override(tmp_path):
    """``dialect:`` in the vehicle file (the one validating loader), ``--dialect`` over it."""
    from mavreg.config.loader import load_text
    from mavreg.config.vehicle import VehicleParams, with_dialect
    text = DEFAULT_VEHICLE.read_text()
    base = load_vehicle(DEFAULT_VEHICLE)
    assert base.dialect is None
    chosen = load_text(text + "\ndialect: ardupilot\n", VehicleParams, kind="vehicle", source="v.yaml")
    assert chosen.dialect == "ardupilot" and with_dialect(chosen, None) is chosen
    assert with_dialect(chosen, "px4").dialect == "px4"
    for bad, words in (("inav", "expected one of px4, ardupilot, got 'inav'"),
                       ("PX4", "expected one of px4, ardupilot, got 'PX4'"),
                       ("12", "expected a string, got int 12"), ("[px4]", "expected a string")):
        with pytest.raises(ConfigError, match=f"dialect: {words}") as exc:
            load_text(text + f"\ndialect: {bad}\n", VehicleParams, kind="vehicle", source="v.yaml")
        assert "\n" not in str(exc.value)
    with pytest.raises(ConfigError, match="expected one of px4, ardupilot, got 'generic'"):
        with_dialect(base, "generic")


def test_rate_output_lags_the_torque_as_the_rotors_would(vehicle):
    """The torque realized follows a step of the commanded one with the vehicle's rotor lag:
    63 % after one time constant (vehicle time), the collective at once."""
    out = RateOutput(vehicle, VehicleIds(1))
    mixer = Mixer.from_vehicle(vehicle)
    tau, J, tau_w = vehicle.rotor_time_constant_s, np.asarray(vehicle.inertia_kg_m2), 0.03
    out.command(mixer.inverse @ np.array([8.0, 0.0, 0.0, 0.0]), np.zeros(12), 1.0)
    step = mixer.inverse @ np.array([8.0, 0.02, 0.0, 0.0])
    dt = 0.002
    for k in range(1, int(round(tau / dt)) + 1):
        rates, thrust = out.command(step, np.zeros(12), 1.0 + k * dt)
    assert rates[0] == pytest.approx(tau_w * 0.02 / J[0] * (1 - np.exp(-1.0)), rel=1e-6)
    assert ThrustMap.from_params(vehicle.mass_kg, RATES).thrust_n(thrust) == pytest.approx(8.0)
    out_nolag = RateOutput(dataclasses.replace(vehicle, rotor_time_constant_s=0.0), VehicleIds(1))
    out_nolag.command(mixer.inverse @ np.array([8.0, 0.0, 0.0, 0.0]), np.zeros(12), 1.0)
    assert out_nolag.command(step, np.zeros(12), 1.002)[0][0] == pytest.approx(tau_w * 0.02 / J[0])


def test_plant_through_the_rate_loop_linearizes_as_the_design_model(vehicle):
    """The design's plant (eqs 6-17, torque input) and the plant flown in rate mode (body rates
    from the first-order rate loop, fed by the rate command) have the same Jacobians in state
    and wrench: central finite differences of the second against complex-step of the first,
    at random states of an aggressive maneuver."""
    from mavreg.model.linearize import complex_step_jacobian
    from mavreg.model.quadrotor import QuadrotorModel
    model = QuadrotorModel.from_vehicle(vehicle)
    J = np.asarray(vehicle.inertia_kg_m2)
    tau = RATES.rate_time_constant_s

    def through_loop(x, u):
        xdot = model.f(x, u).astype(float)
        xdot[9:12] = rate_response_rhs(x[9:12], rate_command(x[9:12], u[1:], J, tau), tau)
        return xdot

    rng = np.random.default_rng(7)
    for _ in range(5):
        x = np.r_[rng.normal(0, 2, 3), rng.uniform(-1, 1, 3), rng.normal(0, 4, 3), rng.normal(0, 5, 3)]
        u = np.r_[rng.uniform(2, 30), rng.normal(0, 0.2, 3)]
        A = complex_step_jacobian(lambda z: model.f(z, u), x)
        B = complex_step_jacobian(lambda v: model.f(x, v), u)
        h = 1e-6
        A_fd = np.column_stack([(through_loop(x + h * e, u) - through_loop(x - h * e, u)) / (2 * h)
                                for e in np.eye(12)])
        B_fd = np.column_stack([(through_loop(x, u + h * e) - through_loop(x, u - h * e)) / (2 * h)
                                for e in np.eye(4)])
        np.testing.assert_allclose(A_fd, A, atol=2e-5 * max(1.0, np.abs(A).max()))
        np.testing.assert_allclose(B_fd, B, atol=2e-5 * max(1.0, np.abs(B).max()))
    # negative control: a rate command that ignores the loop's time constant changes B
    B_wrong = np.column_stack([
        (rate_response_rhs(x[9:12], rate_command(x[9:12], u[1:] + h * e[1:], J, 2 * tau), tau)
         - rate_response_rhs(x[9:12], rate_command(x[9:12], u[1:] - h * e[1:], J, 2 * tau), tau)) / (2 * h)
        for e in np.eye(4)])
    assert np.abs(B_wrong - B[9:12]).max() > 0.5 * np.abs(B[9:12]).max()


def test_lag_loop_factor_is_the_achieved_wrench_gain_over_one_period():
    """rho(K_a) (1 - e^{-T/tau}) on gains with a known spectral radius; 0 without the lag."""
    from mavreg.control.design.actuator import lag_loop_factor
    from mavreg.model.rotor_lag import lag_decay
    K = np.zeros((3, 4, 15))
    K[1, :, 11:] = np.diag([0.5, 3.0, -4.0, 1.0])
    decay = lag_decay(0.005, 0.02)
    assert lag_loop_factor(K, decay) == pytest.approx(4.0 * (1 - np.exp(-0.25)))
    assert lag_loop_factor(np.ones((3, 4, 11)), decay) == 0.0


def test_an_autopilots_attitude_loop_on_the_command_integral_is_cancelled():
    """An ArduCopter-like rate loop aims for the command plus K times the integral of (command
    - rate). Fed through the compensation, a rate step is followed as the first-order model
    says; fed directly, it overshoots (negative control)."""
    from mavreg.model.rate_interface import AttitudeLoopCompensation
    tau, K, dt = 0.011, np.array([15.0, 15.0, 10.0]), 0.005
    steps = int(round(0.4 / dt))
    t = dt * np.arange(1, steps + 1)
    model = 1.0 - np.exp(-t / tau)

    def fly(compensate: bool) -> np.ndarray:
        comp = AttitudeLoopCompensation(K if compensate else np.zeros(3))
        w, e, out = np.zeros(3), np.zeros(3), []
        for _ in range(steps):
            send = comp.rates(np.ones(3), w, dt) if compensate else np.ones(3)
            for _ in range(10):                         # its loop, 10x faster than the commands
                target = send + K * e                   # its rate target
                e = e + dt / 10 * (send - w)
                w = w + dt / 10 * (target - w) / tau
            out.append(w[0])
        return np.array(out)

    assert np.abs(fly(True) - model).max() < 0.08
    assert fly(False).max() > 1.08 and np.abs(fly(False) - model).max() > 0.1   # without it: overshoot
    comp = AttitudeLoopCompensation(K)
    comp.rates(np.ones(3), np.zeros(3), 1.0)
    assert np.all(np.abs(comp.error) <= comp.max_error_rad)
    comp.reset()
    assert not np.any(comp.error)
