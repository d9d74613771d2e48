"""The s-varying Riccati machinery against closed forms, scipy's CARE and periodicity."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

from mavreg.control.design.riccati import (
    care,
    check_step,
    max_stable_step,
    periodic_riccati,
    riccati_rhs,
    sweep_backward,
)
from mavreg.model.linearize import model_jacobians
from mavreg.model.quadrotor import QuadrotorModel

MODEL = QuadrotorModel(0.749, (0.0176, 0.0177, 0.034))


def constant_grid(A, B, N):
    A_nodes = np.broadcast_to(A, (N,) + A.shape).copy()
    B_nodes = np.broadcast_to(B, (N,) + B.shape).copy()
    return A_nodes, B_nodes, A_nodes[:-1].copy(), B_nodes[:-1].copy()


def sampled_grid(A_fun, B_fun, s0, h, N):
    s = s0 + h * np.arange(N)
    sm = s[:-1] + 0.5 * h
    return (np.stack([A_fun(x) for x in s]), np.stack([B_fun(x) for x in s]),
            np.stack([A_fun(x) for x in sm]), np.stack([B_fun(x) for x in sm]))


def hover_11():
    """Hover linearization with the along-track position p1 removed (it feeds nothing)."""
    A, B = model_jacobians(MODEL.f, np.zeros(12), MODEL.hover_input())
    return A[1:, 1:], B[1:, :]


Q11 = np.diag([100, 100, 9, 9, 9, 10, 10, 10, 3, 3, 3.0])
R4 = np.diag([0.1, 0.1, 1.0, 0.1])


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


# --- care ------------------------------------------------------------------------------

def test_care_matches_scipy_and_stabilizes():
    A, B = hover_11()
    P, K = care(A, B, Q11, R4)
    np.testing.assert_allclose(P, scipy.linalg.solve_continuous_are(A, B, Q11, R4), rtol=1e-12)
    np.testing.assert_allclose(K, np.linalg.solve(R4, B.T @ P), rtol=1e-12)
    assert np.linalg.eigvals(A - B @ K).real.max() < 0
    assert np.abs(riccati_rhs(A, B @ np.linalg.solve(R4, B.T), Q11, P)).max() < 1e-8 * np.abs(P).max()


def test_care_not_stabilizable_is_a_clear_error():
    A = np.diag([1.0, -1.0])
    B = np.array([[0.0], [1.0]])
    with pytest.raises(ValueError, match="not stabilizable"):
        care(A, B, np.eye(2), np.eye(1))


def test_care_rejects_bad_weights():
    A, B = np.zeros((2, 2)), np.eye(2)
    with pytest.raises(ValueError, match="R must be symmetric positive definite"):
        care(A, B, np.eye(2), -np.eye(2))
    with pytest.raises(ValueError, match="Q has shape"):
        care(A, B, np.eye(3), np.eye(2))


# --- constant coefficients: the sweep converges to the CARE -------------------------------

@pytest.mark.parametrize("case", ["double_integrator", "hover_11", "random"])
def test_long_sweep_converges_to_care(case):
    rng = np.random.default_rng(3)
    if case == "double_integrator":
        A, B, Q, R = np.array([[0, 1.0], [0, 0]]), np.array([[0], [1.0]]), np.eye(2), np.eye(1)
    elif case == "hover_11":
        (A, B), Q, R = hover_11(), Q11, R4
    else:
        A, B = rng.normal(size=(6, 6)), rng.normal(size=(6, 2))
        Q, R = np.diag(rng.uniform(0.5, 2, 6)), np.diag(rng.uniform(0.5, 2, 2))
    P_care, K_care = care(A, B, Q, R)
    # The transient from P = 0 has faster closed-loop modes than the steady state.
    h = 0.5 * max_stable_step(A, B, K_care)
    slow = -np.linalg.eigvals(A - B @ K_care).real.max()
    N = int(np.ceil(30.0 / (2 * slow * h))) + 1        # e^{-2 slow tau} ~ 1e-26
    P, K = sweep_backward(*constant_grid(A, B, N), h, Q, R, np.zeros_like(A))
    assert rel(P[0], P_care) < 1e-9
    assert rel(K[0], K_care) < 1e-9
    assert np.allclose(P[0], P[0].T, rtol=0, atol=0)


# --- scalar closed form -------------------------------------------------------------------

def scalar_exact(a, b, q, r, p_T, tau):
    """p(tau) of dp/dtau = 2 a p - (b^2/r) p^2 + q, tau = L - s (backward), p(0) = p_T."""
    sig = b * b / r
    beta = np.sqrt(a * a + sig * q)
    p_plus, p_minus = (a + beta) / sig, (a - beta) / sig
    C = (p_T - p_plus) / (p_T - p_minus)
    e = C * np.exp(-2.0 * beta * tau)
    return (p_plus - p_minus * e) / (1.0 - e)


def test_scalar_closed_form_and_fourth_order():
    a, b, q, r, L = 0.7, 1.3, 2.0, 0.5, 2.0
    errs = []
    for N in (41, 81, 161):
        h = L / (N - 1)
        P, _ = sweep_backward(*constant_grid(np.array([[a]]), np.array([[b]]), N), h,
                              [[q]], [[r]], [[0.0]])
        tau = L - h * np.arange(N)
        errs.append(np.abs(P[:, 0, 0] - scalar_exact(a, b, q, r, 0.0, tau)).max())
    assert errs[0] < 1e-5
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert np.all((ratios > 13) & (ratios < 19)), ratios      # 2^4 = 16


def test_s_varying_scalar_is_fourth_order_with_midpoints():
    """a(s) = sin(3 s): needs A at the midpoints for order 4; reference from solve_ivp."""
    a_f = lambda s: np.array([[np.sin(3 * s)]])
    b_f = lambda s: np.array([[1.0 + 0.5 * np.cos(2 * s)]])
    q, r, L = 1.0, 0.2, 2.0

    def rhs(s, p):
        a, b = a_f(s)[0, 0], b_f(s)[0, 0]
        return [-(2 * a * p[0] - b * b / r * p[0] ** 2 + q)]

    ref = scipy.integrate.solve_ivp(rhs, (L, 0.0), [0.5], rtol=1e-13, atol=1e-14).y[0, -1]
    errs = []
    for N in (21, 41, 81):
        h = L / (N - 1)
        P, _ = sweep_backward(*sampled_grid(a_f, b_f, 0.0, h, N), h, [[q]], [[r]], [[0.5]])
        errs.append(abs(P[0, 0, 0] - ref))
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert np.all((ratios > 12) & (ratios < 20)), (errs, ratios)


# --- periodic -----------------------------------------------------------------------------

PERIOD = 2 * np.pi


def osc_A(s):
    return np.array([[0.0, 1.0], [-(1.0 + 0.5 * np.sin(s)), -0.2]])


def osc_B(s):
    return np.array([[0.0], [1.0 + 0.3 * np.cos(s)]])


def test_periodic_solution_is_periodic_and_solves_the_ode():
    N = 401
    h = PERIOD / (N - 1)
    Q, R = np.diag([2.0, 1.0]), np.array([[0.5]])
    grid = sampled_grid(osc_A, osc_B, 0.0, h, N)
    P, K = periodic_riccati(*grid, h, Q, R, tol=1e-12)
    assert P.shape == (N, 2, 2) and K.shape == (N, 1, 2)
    assert rel(P[0], P[-1]) < 1e-12
    # genuinely s-varying
    assert rel(P[N // 4], P[3 * N // 4]) > 1e-2
    # 5-point finite-difference derivative vs -F(P): O(h^4)
    dP = (-P[4:] + 8 * P[3:-1] - 8 * P[1:-3] + P[:-4]) / (12 * h)
    S = grid[1] @ np.linalg.solve(R, np.transpose(grid[1], (0, 2, 1)))
    F = np.stack([riccati_rhs(grid[0][k], S[k], Q, P[k]) for k in range(2, N - 2)])
    assert np.abs(dP + F).max() < 1e-6 * np.abs(F).max()


def test_long_sweep_converges_to_the_periodic_solution():
    N = 201
    h = PERIOD / (N - 1)
    Q, R = np.eye(2), np.array([[1.0]])
    grid = sampled_grid(osc_A, osc_B, 0.0, h, N)
    P_per, _ = periodic_riccati(*grid, h, Q, R)
    laps = 25
    long = sampled_grid(osc_A, osc_B, 0.0, h, laps * (N - 1) + 1)
    P_long, _ = sweep_backward(*long, h, Q, R, np.zeros((2, 2)))
    for k in (0, N // 3, N - 1):
        assert rel(P_long[k], P_per[k]) < 1e-9


def test_periodic_requires_a_periodic_grid_and_reports_non_convergence():
    N = 101
    h = 1.0 / (N - 1)
    grid = sampled_grid(osc_A, osc_B, 0.0, h, N)   # covers s in [0, 1], not a period
    with pytest.raises(ValueError, match="exactly one period"):
        periodic_riccati(*grid, h, np.eye(2), np.eye(1))
    grid = sampled_grid(osc_A, osc_B, 0.0, PERIOD / (N - 1), N)
    with pytest.raises(ValueError, match="did not converge in 1 periods: relative residual"):
        periodic_riccati(*grid, PERIOD / (N - 1), np.eye(2), np.eye(1), tol=1e-14, max_periods=1)


# --- step size and blow-up ---------------------------------------------------------------

def test_step_check_raises_beyond_the_stability_limit_and_warns_near_it():
    A, B = hover_11()
    _, K = care(A, B, Q11, R4)
    h_edge = max_stable_step(A, B, K, safety=1.0)
    assert max_stable_step(A, B, K) == pytest.approx(0.5 * h_edge)
    lam = np.linalg.eigvals(A - B @ K)
    assert h_edge == pytest.approx(2.5 / np.abs(lam[:, None] + lam[None, :]).max())
    A_n, B_n, _, _ = constant_grid(A, B, 3)
    K_n = np.broadcast_to(K, (3,) + K.shape)
    with pytest.raises(ValueError, match="exceeds the stability limit"):
        check_step(A_n, B_n, K_n, 1.2 * h_edge)
    with pytest.warns(RuntimeWarning, match="resolved poorly"):
        check_step(A_n, B_n, K_n, 0.8 * h_edge)
    check_step(A_n, B_n, K_n, 0.4 * h_edge)        # silent


def test_blow_up_is_reported_with_the_node():
    # Unstable uncontrolled mode with tiny control authority: P grows like e^{2 a tau}.
    A, B = np.array([[5.0]]), np.array([[1e-9]])
    N = 400
    with pytest.raises(ValueError, match=r"blew up at node \d+"):
        sweep_backward(*constant_grid(A, B, N), 0.05, [[1.0]], [[1.0]], [[0.0]], step_check="off")


@pytest.mark.parametrize("sweep", ["loops", "numpy"])
def test_both_sweep_forms_agree_and_report_a_nan_with_its_node(sweep):
    """The compiled form (loops into buffers) and the reference (numpy products) of the RK4
    sweep, called directly: the same P to round-off on a random time-varying system, and a
    NaN in A(s) is reported at the node where it enters, not hidden by the running maximum."""
    from mavreg.control.design import riccati, riccati_kernel
    rng = np.random.default_rng(7)
    N, n = 60, 5
    At_n, At_m = rng.normal(size=(N, n, n)), rng.normal(size=(N - 1, n, n))
    Bn, Bm = rng.normal(size=(N, n, 2)), rng.normal(size=(N - 1, n, 2))
    S_n, S_m = Bn @ Bn.transpose(0, 2, 1), Bm @ Bm.transpose(0, 2, 1)
    steps, Q, PT = np.full(N - 1, 0.01), np.eye(n), np.eye(n)
    run = {"loops": riccati_kernel.rk4_sweep_loops, "numpy": riccati.rk4_sweep_numpy}[sweep]
    P, P_ref = np.empty((N, n, n)), np.empty((N, n, n))
    assert run(At_n, S_n, At_m, S_m, steps, Q, PT, 1e12, P)[:2] == (-1, 0)
    assert riccati.rk4_sweep_numpy(At_n, S_n, At_m, S_m, steps, Q, PT, 1e12, P_ref)[:2] == (-1, 0)
    assert np.abs(P - P_ref).max() <= 1e-12 * np.abs(P_ref).max()
    assert np.array_equal(P, P.transpose(0, 2, 1))
    At_m[20, 1, 3] = np.nan
    node, failure, _ = run(At_n, S_n, At_m, S_m, steps, Q, PT, 1e12, P)
    assert (node, failure) == (20, 1)
