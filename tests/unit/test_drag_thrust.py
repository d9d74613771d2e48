"""A rotor-plane drag that grows with the thrust, c_xy (T / m g)^e (vehicle file:
``rotor_drag_thrust_exponent``): its value, its kernel, the plant and its linearization, the
flat nominal that feeds it forward, the predictor, the disturbance observer's regressor, the
fit that identifies it; and e = 0 is the constant-coefficient model, bit for bit."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tests.helpers.identify_synth import MASS_KG, MAX_ROTOR_N, synthetic_flight
from mavreg.config.loader import ConfigError
from mavreg.config.loader import load_text
from mavreg.config.vehicle import VehicleParams
from mavreg.control.estimation.disturbance import regressors
from mavreg.control.estimation.observer_kernel import update as observer_update
from mavreg.identify.fit import FitOptions, identify
from mavreg.model import drag, drag_kernel
from mavreg.model.linearize import model_jacobians
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.quadrotor_kernel import plant_rhs
from mavreg.model.rotation import rpy_to_matrix

MODEL = QuadrotorModel(0.8, (0.004, 0.004, 0.007), 9.80665, (0.2, 0.15), 0.01)
MODEL_E = dataclasses.replace(MODEL, rotor_drag_thrust_exponent=0.5)
X = np.array([1.0, -2.0, -3.0, 0.3, -0.5, 1.9, 6.0, -3.0, 0.7, 0.8, -0.6, 0.2])
U = np.array([4.0 * 0.8 * 9.80665, 0.01, -0.02, 0.003])          # four times the hover thrust


def test_the_scale_has_its_analytic_value_and_exponent_zero_is_exactly_one():
    mg = 0.8 * 9.80665
    assert drag.rotor_plane_scale(4 * mg, mg, 0.5) == pytest.approx(2.0, rel=1e-15)
    assert drag.rotor_plane_scale(2 * mg, mg, 1.0) == pytest.approx(2.0, rel=1e-15)
    assert drag.rotor_plane_scale(-1.0, mg, 0.5) == 0.0          # no thrust, no momentum drag
    assert drag.rotor_plane_scale(123.0, mg, 0.0) == 1.0
    for T in (0.0, 0.3 * mg, mg, 5.3 * mg):
        assert drag_kernel.rotor_plane_scale(T, mg, 0.5) == pytest.approx(
            float(drag.rotor_plane_scale(T, mg, 0.5)), rel=1e-14, abs=0)
    # the jet: (T/Th)^e and its time derivatives against finite differences of a thrust T(t)
    t, h = 0.3, 1e-4
    T = lambda t: mg * (2.0 + np.sin(3 * t))                      # noqa: E731
    s = lambda t: (T(t) / mg) ** 0.5                              # noqa: E731
    jet = drag.rotor_plane_scale_jet((T(t), 3 * mg * np.cos(3 * t), -9 * mg * np.sin(3 * t)), mg, 0.5)
    assert jet[0] == pytest.approx(s(t), rel=1e-14)
    assert jet[1] == pytest.approx((s(t + h) - s(t - h)) / (2 * h), rel=1e-6)
    assert jet[2] == pytest.approx((s(t + h) - 2 * s(t) + s(t - h)) / h ** 2, rel=1e-5)


def test_the_plant_drag_grows_as_the_square_root_of_the_thrust():
    vdot = MODEL_E.body_derivatives(rpy_to_matrix(*X[3:6])[2], X[6:9], X[9:12], U)[0]
    ref = MODEL.body_derivatives(rpy_to_matrix(*X[3:6])[2], X[6:9], X[9:12], U)[0]
    # at 4 g the rotor-plane drag is twice the hover coefficient's: the difference is c_xy v_xy / m
    assert np.allclose(vdot - ref, [-0.2 * 6.0 / 0.8, 0.2 * 3.0 / 0.8, 0.0], atol=1e-12)


@pytest.mark.parametrize("model", [MODEL, MODEL_E])
def test_plant_kernel_agrees_with_the_reference(model):
    out = np.empty(12)
    plant_rhs(X, *U, (model.mass_kg, model.g, *model.rotor_drag_n_s_per_m, model.parasitic_drag_n_s2_per_m2,
                      model.rotor_drag_thrust_exponent), *model.inertia_kg_m2, out)
    assert np.allclose(out, model.f(X, U), rtol=0, atol=1e-12)


def test_linearization_against_finite_differences():
    A, B = model_jacobians(MODEL_E.f, X, U)
    h = 1e-6
    fd_B = np.stack([(MODEL_E.f(X, U + h * e) - MODEL_E.f(X, U - h * e)) / (2 * h) for e in np.eye(4)], axis=1)
    fd_A = np.stack([(MODEL_E.f(X + h * e, U) - MODEL_E.f(X - h * e, U)) / (2 * h) for e in np.eye(12)], axis=1)
    assert np.allclose(B, fd_B, atol=1e-7) and np.allclose(A, fd_A, atol=1e-6)
    # the thrust column now carries the drag's growth (negative control: the constant model's does not)
    B0 = model_jacobians(MODEL.f, X, U)[1]
    dc = 0.2 * 0.5 / (2.0 * 0.8 * 9.80665)           # d c_xy / dT at 4 g: c_xy e (T/Th)^(e-1) / Th
    assert np.allclose(B[6:8, 0] - B0[6:8, 0], -dc * X[6:8] / 0.8, atol=1e-12)


def test_exponent_zero_is_the_constant_model_bit_for_bit():
    plain = QuadrotorModel(0.8, (0.004, 0.004, 0.007), 9.80665, (0.2, 0.15), 0.01)
    zero = dataclasses.replace(plain, rotor_drag_thrust_exponent=0.0)
    assert np.array_equal(plain.f(X, U), zero.f(X, U))
    text = "kind: vehicle\nversion: 1\nname: v\nmass_kg: 0.8\ninertia_kg_m2: [0.004, 0.004, 0.007]\n" \
           "arm_length_m: 0.18\ndrag_torque_ratio_m: 0.012\nmax_rotor_thrust_n: 15\n"
    assert load_text(text, VehicleParams, source="v", kind="vehicle").rotor_drag_thrust_exponent == 0.0
    with pytest.raises(ConfigError, match="rotor_drag_thrust_exponent"):
        load_text(text + "rotor_drag_thrust_exponent: -0.5\n", VehicleParams, source="v", kind="vehicle")


def _circle_plan(model):
    """A vertical 1.5 m circle at 8 m/s (a loop's bottom pulls 5 g), sampled densely."""
    from mavreg.maneuver.flatness import flat_nominal
    r, v, n = 1.5, 8.0, 400
    s = np.linspace(0.0, 2 * np.pi * r, n, endpoint=False)
    a = s / r
    c = np.stack([0 * a, -r * np.sin(a), -r * (1 - np.cos(a))], axis=1)       # east-down plane
    t = np.stack([0 * a, -np.cos(a), -np.sin(a)], axis=1)
    K = np.stack([0 * a, np.sin(a), -np.cos(a)], axis=1) / r
    m1 = K * r
    m2 = np.cross(t, m1)
    F = np.stack([t, m1, m2], axis=2)
    k = np.stack([np.full(n, 1 / r), np.zeros(n)], axis=1)
    zeros = np.zeros_like(k)
    v4 = np.stack([np.full(n, v), 0 * a, 0 * a, 0 * a])
    x, u, R = flat_nominal(model, F, k, zeros, zeros, c, v4, np.zeros((4, n)))
    return x, u, t * v, K * v * v


def test_the_flat_nominal_feeds_the_thrust_dependent_drag_forward():
    for model in (MODEL_E, MODEL):
        x, u, vel, acc = _circle_plan(model)
        # the model at the nominal state and input accelerates as the path does
        for i in range(0, len(u), 37):
            R = rpy_to_matrix(*x[i, 3:6])
            vdot_b = model.body_derivatives(R[2], x[i, 6:9], x[i, 9:12], u[i])[0]
            a_ned = R @ (vdot_b + np.cross(x[i, 9:12], x[i, 6:9]))
            assert np.allclose(a_ned, acc[i], atol=1e-6), (model, i)
    # negative control: the constant model at the thrust-dependent nominal misses by the drag's growth
    x, u, vel, acc = _circle_plan(MODEL_E)
    i = int(np.argmax(u[:, 0]))
    R = rpy_to_matrix(*x[i, 3:6])
    a_ned = R @ (MODEL.body_derivatives(R[2], x[i, 6:9], x[i, 9:12], u[i])[0] + np.cross(x[i, 9:12], x[i, 6:9]))
    assert np.linalg.norm(a_ned - acc[i]) > 0.5


def test_the_predictor_takes_the_drag_at_the_thrust_flown():
    from mavreg.config.vehicle import load_vehicle
    from tests.helpers.repo import ROOT
    from mavreg.control.estimation.predictor import StatePredictor
    base = load_vehicle(ROOT / "mavreg/params/vehicles/ardupilot_freestyle.yaml")
    base = dataclasses.replace(base, rotor_time_constant_s=0.0, parasitic_drag_n_s2_per_m2=0.0)
    T = 3.0 * base.mass_kg * 9.80665                      # a steady 3 g pull
    x = np.zeros(12)
    x[6:9] = (0.0, 7.0, 0.0)
    R = np.eye(3)
    preds = []
    for e, cxy in ((0.5, 0.2), (0.0, 0.2 * 3.0 ** 0.5), (0.0, 0.2)):
        veh = dataclasses.replace(base, rotor_drag_thrust_exponent=e, rotor_drag_n_s_per_m=(cxy, 0.1))
        p = StatePredictor(veh)
        p.reset(np.full(4, T / 4))
        p.record(0.0, np.full(4, T / 4))
        preds.append(p.predict(0.0, x, R, 0.05).x)
    assert np.allclose(preds[0], preds[1], atol=1e-12)
    assert not np.allclose(preds[0], preds[2], atol=1e-5)          # negative control


def test_the_observer_regressor_scales_the_rotor_plane_column_alike_in_the_kernel():
    R = rpy_to_matrix(0.6, -0.3, 1.0)
    v = np.array([5.0, -2.0, 1.0])
    phi1, phi2 = regressors(R, v, 20.0), regressors(R, v, 20.0, 2.0)
    assert np.allclose(phi2[:, 0], 2.0 * phi1[:, 0]) and np.array_equal(phi2[:, 1:], phi1[:, 1:])
    kf = np.zeros((8, 6))
    kf[2] = 0.01
    kf[3] = 1.0
    kf[4] = -10.0
    kf[5] = 10.0
    outs = []
    for scale in (1.0, 2.0):
        k, P = kf.copy(), np.eye(6) * 0.01
        observer_update(k, P, 0.005, 0.8, 1e-4, 0.0, 100.0, R, *v, 20.0, 0.01, -0.02, 0.005, scale)
        H = (0.005 / 0.8) * regressors(R, v, 20.0, scale)
        S = H @ (np.eye(6) * 0.01 + np.diag(kf[2] * 0.005)) @ H.T + 1e-4 * np.eye(3)
        Kg = np.linalg.solve(S, H @ (np.eye(6) * 0.01 + np.diag(kf[2] * 0.005))).T
        assert np.allclose(k[0], np.clip(Kg @ [0.01, -0.02, 0.005], -10, 10), atol=1e-12)
        outs.append(k[0].copy())
    assert not np.allclose(outs[0], outs[1])


@pytest.fixture(scope="module")
def grown_drag_flight():
    return synthetic_flight(duration_s=10.0, seed=9, excite=2.5, noise_sd=0.0, drag_thrust_exponent=0.5)


def test_identify_recovers_the_hover_coefficients_with_the_exponent(grown_drag_flight):
    with_e = identify(grown_drag_flight, MASS_KG, MAX_ROTOR_N, FitOptions(replicates=50,
                                                                         rotor_drag_thrust_exponent=0.5))
    without = identify(grown_drag_flight, MASS_KG, MAX_ROTOR_N, FitOptions(replicates=50))
    cx, cy = with_e.drag_n_s_per_m[0].value, with_e.drag_n_s_per_m[1].value
    assert cx == pytest.approx(0.25, rel=0.1) and cy == pytest.approx(0.35, rel=0.1)
    # negative control: a constant coefficient fits the same flight worse
    assert without.residual_rms_m_s2 > 1.1 * with_e.residual_rms_m_s2
