r"""Nominal state and input along a path by differential flatness.

The flat outputs are position and yaw. Along the path, position is :math:`c(s)` with the
rotation-minimizing frame :math:`(t, m_1, m_2)` and curvature vector
:math:`K = k_1 m_1 + k_2 m_2`; time enters through :math:`\dot s = v(s)`. With
:math:`a = v v'` and :math:`b = v^2` (primes are d/ds),

.. math::
    \ddot c = a\,t + b\,K,\qquad
    \dddot c = v\,[\alpha\,t + \beta K + b K_d],\qquad
    \alpha = a' - b\kappa^2,\ \beta = a + b',\ K_d = k_1' m_1 + k_2' m_2,

and the snap follows by one more derivative (:func:`path_derivatives`). The thrust
direction is :math:`z_b = (g e_3 - \ddot c)/|g e_3 - \ddot c|` (body z, FRD), the thrust
:math:`f = m|g e_3 - \ddot c|`; with :math:`x_c = (\cos\psi, \sin\psi, 0)`,
:math:`y_b = z_b\times x_c/|\cdot|` and :math:`x_b = y_b\times z_b` give
:math:`R = [x_b\ y_b\ z_b]`, the ZYX attitude of eq 5. Body rates and their derivatives
come from :math:`\hat\omega = R^T\dot R` and :math:`\dot{\hat\omega} = \mathrm{skew}(R^T\ddot R)`,
carried as exact second-order jets, which has no singularity at roll :math:`\pm 90°`
(unlike solving eq 11 for r). Torques are :math:`\gamma = J\dot\omega + \omega\times J\omega`.

With drag in the model (:class:`~mavreg.model.quadrotor.QuadrotorModel`: body-frame linear
drag :math:`C = \mathrm{diag}(c_{xy}, c_{xy}, c_z)` and parasitic :math:`c_p|v|v`) the flat
map stays explicit, as for rotor drag symmetric in the rotor plane (Faessler, Franchi and
Scaramuzza, 2018): the body drag is :math:`-c_{xy}v - (c_z - c_{xy})(z_b\cdot v)z_b`, whose
second part lies along the thrust axis, so

.. math::
    t = m(g e_3 - \ddot c) - c_{xy}\dot c - c_p|\dot c|\dot c,\qquad z_b = t/|t|,\qquad
    f = |t| - (c_z - c_{xy})\,(z_b\cdot\dot c),

and the jets of :math:`t` carry the drag's derivatives (acceleration, jerk). The nominal then
feeds the known drag forward instead of leaving the feedback to fight it. A rotor-plane
coefficient that grows with the thrust, :math:`c_{xy}(f) = c_{xy}(f/mg)^e`
(``rotor_drag_thrust_exponent``), keeps the map explicit given f; f and c_xy are found
together by a fixed point on their jets (:func:`_thrust_dependent_drag`).
"""
from __future__ import annotations

import numpy as np

from ..model.drag import rotor_plane_scale_jet
from ..model.quadrotor import QuadrotorModel
from ..model.rotation import matrix_to_rpy

__all__ = ["path_derivatives", "flat_nominal", "nominal_from_flat", "FlatnessError", "YAW_MODES"]


def _dot(a, b):
    return np.sum(a * b, axis=-1)


def path_derivatives(F, k, dk, ddk, v4):
    """World-frame velocity, acceleration, jerk and snap of the nominal, each (N, 3).

    ``F`` (N,3,3) frames (t, m1, m2), ``k, dk, ddk`` (N,2), ``v4`` (4,N) speed and its
    first three s-derivatives.
    """
    t, m1, m2 = F[:, :, 0], F[:, :, 1], F[:, :, 2]
    v, v1, v2, v3 = (x[:, None] for x in v4)
    K = k[:, 0:1] * m1 + k[:, 1:2] * m2
    Kd = dk[:, 0:1] * m1 + dk[:, 1:2] * m2
    Kdd = ddk[:, 0:1] * m1 + ddk[:, 1:2] * m2
    kap2 = _dot(k, k)[:, None]
    kdk = _dot(k, dk)[:, None]
    a, a1, a2 = v * v1, v1 ** 2 + v * v2, 3 * v1 * v2 + v * v3
    b, b1, b2 = v ** 2, 2 * v * v1, 2 * v1 ** 2 + 2 * v * v2
    alpha = a1 - b * kap2
    beta = a + b1
    dalpha = a2 - b1 * kap2 - b * 2 * kdk
    dbeta = a1 + b2
    vel = v * t
    acc = a * t + b * K
    jerk = v * (alpha * t + beta * K + b * Kd)
    snap = v * (v1 * (alpha * t + beta * K + b * Kd)
                + v * ((dalpha - beta * kap2 - b * kdk) * t + (alpha + dbeta) * K
                       + (beta + b1) * Kd + b * Kdd))
    return vel, acc, jerk, snap


# ---- second-order jets: (value, d/dt, d2/dt2), vectors (N,3), scalars (N,)
def _jdot(a, b):
    return (_dot(a[0], b[0]), _dot(a[1], b[0]) + _dot(a[0], b[1]),
            _dot(a[2], b[0]) + 2 * _dot(a[1], b[1]) + _dot(a[0], b[2]))


def _jcross(a, b):
    return (np.cross(a[0], b[0]), np.cross(a[1], b[0]) + np.cross(a[0], b[1]),
            np.cross(a[2], b[0]) + 2 * np.cross(a[1], b[1]) + np.cross(a[0], b[2]))


def _jnorm(a):
    q = _jdot(a, a)
    n0 = np.sqrt(q[0])
    n1 = q[1] / (2 * n0)
    n2 = q[2] / (2 * n0) - q[1] ** 2 / (4 * n0 ** 3)
    return n0, n1, n2


def _jnormalize(a):
    n0, n1, n2 = _jnorm(a)
    i0, i1, i2 = 1 / n0, -n1 / n0 ** 2, -n2 / n0 ** 2 + 2 * n1 ** 2 / n0 ** 3
    i0, i1, i2 = i0[:, None], i1[:, None], i2[:, None]
    return (a[0] * i0, a[1] * i0 + a[0] * i1, a[2] * i0 + 2 * a[1] * i1 + a[0] * i2)


def _vee(M):
    return np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0],
                     M[:, 1, 0] - M[:, 0, 1]], axis=1) / 2


class FlatnessError(ValueError):
    """The flat map is undefined at sample ``index``; ``remedy`` says what to change."""

    def __init__(self, what: str, index: int, remedy: str):
        super().__init__(f"{what} at sample {index}")
        self.what, self.index, self.remedy = what, index, remedy


YAW_MODES = ("fixed", "tangent", "velocity")
_MIN_HORIZONTAL = 1e-3
"""tangent: the path's horizontal heading is undefined where the horizontal share of the
velocity is below this (a vertical path)."""
_MIN_SINE = 1e-3
"""The nose reference must not lie along the thrust axis: |z_b x n| / |n| above this."""


def _jscale(a, v):
    """Scalar jet a times vector jet v."""
    return (a[0][:, None] * v[0], a[1][:, None] * v[0] + a[0][:, None] * v[1],
            a[2][:, None] * v[0] + 2 * a[1][:, None] * v[1] + a[0][:, None] * v[2])


def _jcos_sin(a):
    """Jets of cos(a) and sin(a) for a scalar jet a."""
    c, s = np.cos(a[0]), np.sin(a[0])
    return ((c, -s * a[1], -c * a[1] ** 2 - s * a[2]),
            (s, c * a[1], -s * a[1] ** 2 + c * a[2]))


def _heading_jet(vel, acc, jerk):
    """Jet of the horizontal heading atan2(v_e, v_n) of the velocity, and the horizontal
    share of the speed (where it is small the heading is undefined)."""
    vn, ve, an, ae, jn, je = vel[:, 0], vel[:, 1], acc[:, 0], acc[:, 1], jerk[:, 0], jerk[:, 1]
    D = vn * vn + ve * ve
    share = np.sqrt(D / np.maximum(np.sum(vel * vel, axis=1), 1e-300))
    D = np.maximum(D, 1e-300)
    N = vn * ae - ve * an
    dN = vn * je - ve * jn
    dD = 2 * (vn * an + ve * ae)
    return (np.arctan2(ve, vn), N / D, (dN * D - N * dD) / D ** 2), share


def _nose_reference(mode, yaw_jet, zb, vel, acc, jerk):
    """The jet of the vector the nose is turned towards (projected on the rotor plane)."""
    if mode == "velocity":           # the velocity, turned about the thrust axis by the offset
        V = (vel, acc, jerk)
        c, s = _jcos_sin(yaw_jet)
        return tuple(a + b for a, b in zip(_jscale(c, V), _jscale(s, _jcross(zb, V))))
    if mode == "tangent":            # the path's horizontal heading plus the offset
        heading, share = _heading_jet(vel, acc, jerk)
        if share.min() < _MIN_HORIZONTAL:
            raise FlatnessError("the path is vertical, so its heading is undefined",
                                int(np.argmin(share)),
                                "use yaw mode velocity, or keep the path off the vertical")
        yaw_jet = tuple(a + b for a, b in zip(heading, yaw_jet))
    c, s = _jcos_sin(yaw_jet)
    zero = np.zeros_like(c[0])
    return tuple(np.stack([ci, si, zero], axis=1) for ci, si in zip(c, s))


def _with_drag(T, V, cxy_per_m, cp_per_m):
    """The jet of t / m less the drag's: ``cxy_per_m`` a number or a scalar jet (c_xy / m)."""
    n = _jnorm(V)
    vel, acc, jerk = V
    Vq = (n[0][:, None] * vel, n[1][:, None] * vel + n[0][:, None] * acc,
          n[2][:, None] * vel + 2 * n[1][:, None] * acc + n[0][:, None] * jerk)
    CV = _jscale(cxy_per_m, V) if isinstance(cxy_per_m, tuple) else tuple(cxy_per_m * Vi for Vi in V)
    return tuple(Ti - Ci - cp_per_m * Qi for Ti, Ci, Qi in zip(T, CV, Vq))


_DRAG_ITERATIONS = 6
"""Passes of the fixed point thrust -> c_xy(thrust) -> thrust. Each pass shrinks the change by
about e c_xy |v| / f (a few per cent in a loop at 8 m/s), so six are at rounding."""


def _thrust_dependent_drag(model: QuadrotorModel, T0, vel, acc, jerk):
    r"""The jet of t / m with a rotor-plane drag :math:`c_{xy}(f)` that depends on the thrust
    f it helps to set (:func:`mavreg.model.drag.rotor_plane_scale`), by fixed point on the
    jets: f, its derivatives, then c_xy's and t's; also the samples' c_xy (N,)."""
    m = model.mass_kg
    cxy, cz = model.rotor_drag_n_s_per_m
    cp = model.parasitic_drag_n_s2_per_m2
    V = (vel, acc, jerk)
    one = np.ones(len(vel))
    c = (cxy * one, 0.0 * one, 0.0 * one)
    for _ in range(_DRAG_ITERATIONS):
        T = _with_drag(T0, V, tuple(ci / m for ci in c), cp / m)
        tn = _jnorm(T)
        if np.min(tn[0]) < 1e-6:
            break                      # free fall: flat_nominal says where
        along = _jdot(_jnormalize(T), V)
        cz_minus_c = tuple((cz if k == 0 else 0.0) - ck for k, ck in enumerate(c))
        f = tuple(m * tk - pk for tk, pk in zip(tn, _jmul(cz_minus_c, along)))
        if np.min(f[0]) <= 0.0:
            break
        c = tuple(cxy * sk for sk in rotor_plane_scale_jet(f, model.hover_thrust_n,
                                                            model.rotor_drag_thrust_exponent))
    return _with_drag(T0, V, tuple(ci / m for ci in c), cp / m), c[0]


def _jmul(a, b):
    """Scalar jet a times scalar jet b."""
    return (a[0] * b[0], a[1] * b[0] + a[0] * b[1], a[2] * b[0] + 2 * a[1] * b[1] + a[0] * b[2])


def flat_nominal(model: QuadrotorModel, F, k, dk, ddk, c, v4, yaw4, mode: str = "fixed"):
    r"""Nominal states (N,12), inputs (N,4) and attitudes R (N,3,3) at path samples.

    ``yaw4`` (4,N) is the yaw profile and its s-derivatives: the yaw itself in mode
    ``fixed``, the offset from the path's horizontal heading in ``tangent``, the turn of the
    nose from the velocity about the thrust axis in ``velocity``. The nose reference n (a
    horizontal unit vector at the yaw, or the velocity) gives
    :math:`y_b = z_b\times n/|\cdot|`, :math:`x_b = y_b\times z_b`. Roll, pitch and yaw
    (columns 3-5 of x) are unwrapped along the samples, which must be in increasing s; they
    are singular at pitch +-90 deg, R is not. Raises :class:`FlatnessError` where the thrust
    vanishes (free fall), where n lies along the thrust axis, or (``tangent``) where the path
    is vertical.
    """
    if mode not in YAW_MODES:
        raise ValueError(f"yaw mode must be one of {YAW_MODES}, not {mode!r}")
    vel, acc, jerk, snap = path_derivatives(F, k, dk, ddk, v4)
    g = model.g
    m = model.mass_kg
    T = (g * np.array([0.0, 0.0, 1.0]) - acc, -jerk, -snap)
    cxy, cz = model.rotor_drag_n_s_per_m
    cp = model.parasitic_drag_n_s2_per_m2
    if model.rotor_drag_thrust_exponent and cxy:
        T, cxy_now = _thrust_dependent_drag(model, T, vel, acc, jerk)
    elif cxy or cp:          # t / m = g e3 - a - (c_xy / m) v - (c_p / m) |v| v, as jets
        T = _with_drag(T, (vel, acc, jerk), cxy / m, cp / m)
    tn = np.linalg.norm(T[0], axis=1)
    if np.min(tn) < 1e-6:
        raise FlatnessError("the thrust vanishes (free fall), so the attitude is undefined",
                            int(np.argmin(tn)), "change the speed or the curve there")
    zb = _jnormalize(T)
    v, v1 = v4[0], v4[1]
    yaw_jet = (yaw4[0], v * yaw4[1], v * (v1 * yaw4[1] + v * yaw4[2]))
    n = _nose_reference(mode, yaw_jet, zb, vel, acc, jerk)
    cross = np.linalg.norm(np.cross(zb[0], n[0]), axis=1) / np.linalg.norm(n[0], axis=1)
    if cross.min() < _MIN_SINE:
        if mode == "velocity":
            raise FlatnessError("the thrust axis lies along the velocity, so the nose cannot "
                                "follow it", int(np.argmin(cross)),
                                "in a loop this happens where it is flown slower than sqrt(g r) "
                                "(the top below 1 g): fly it faster or wider, or use yaw mode "
                                "fixed")
        raise FlatnessError("the nose reference lies along the thrust axis, so the yaw is "
                            "undefined", int(np.argmin(cross)),
                            "use yaw mode velocity or tangent (the nose follows the path), "
                            "or another yaw")
    yb = _jnormalize(_jcross(zb, n))
    xb = _jcross(yb, zb)
    R, dR, ddR = (np.stack([x, y, z], axis=2) for x, y, z in zip(xb, yb, zb))
    Rt = np.transpose(R, (0, 2, 1))
    omega = _vee(Rt @ dR)
    domega = _vee(Rt @ ddR)  # vee of the skew part of R^T R'' = omega-dot
    J = np.array(model.inertia_kg_m2)
    torque = J * domega + np.cross(omega, J * omega)
    if model.rotor_drag_thrust_exponent and cxy:
        cxy = cxy_now
    thrust = m * tn - (cz - cxy) * _dot(zb[0], vel)
    rpy = matrix_to_rpy(R)
    rpy = np.unwrap(rpy, axis=0)
    vbody = np.einsum("nji,nj->ni", R, vel)
    x = np.concatenate([c, rpy, vbody, omega], axis=1)
    u = np.concatenate([thrust[:, None], torque], axis=1)
    return x, u, R


def nominal_from_flat(model: QuadrotorModel, F, k, dk, ddk, c, v4, yaw4):
    """:func:`flat_nominal` in mode ``fixed``: states (N,12) and inputs (N,4)."""
    x, u, _ = flat_nominal(model, F, k, dk, ddk, c, v4, yaw4)
    return x, u
