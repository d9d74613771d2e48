"""Quaternion rigid-body dynamics and a fixed-step RK4, in scalar Python math.

State ``s`` is a 13-tuple of floats::

    (px, py, pz,  qw, qx, qy, qz,  vx, vy, vz,  p, q, r)

position (m, NED), attitude quaternion (scalar first, body FRD to NED), velocity
(m/s, NED) and body rates (rad/s, FRD). Inputs held over a step: total thrust ``T``
(N, along body -z), body torque ``(tx, ty, tz)`` (N m), wind velocity (m/s, NED; it
only acts through the drag) and an external force (N, NED).

Written independently of mavreg's Euler-angle design model: no singularity at any
attitude, full (symmetric, positive definite) inertia matrix. Scalar math on tuples
is an order of magnitude faster than numpy on 13-element arrays.
"""
from __future__ import annotations

import math

__all__ = [
    "G", "RigidBody", "quat_from_euler", "euler_from_quat", "quat_mul", "rotate",
    "rotate_inv", "normalize_quat", "inertia_matrix", "yaw_of",
]

G = 9.81
"""Gravity (m/s^2), along +z of NED."""


def inertia_matrix(diag_kg_m2, offdiag_kg_m2) -> tuple:
    """Symmetric inertia matrix from ``(jx, jy, jz)`` and ``(jxy, jxz, jyz)``.

    The off-diagonal values are the matrix entries themselves (J[0][1] = jxy, ...).

    Raises
    ------
    ValueError
        If the matrix is not positive definite.
    """
    jx, jy, jz = (float(v) for v in diag_kg_m2)
    jxy, jxz, jyz = (float(v) for v in offdiag_kg_m2)
    J = ((jx, jxy, jxz), (jxy, jy, jyz), (jxz, jyz, jz))
    # Sylvester's criterion.
    d1 = jx
    d2 = jx * jy - jxy * jxy
    d3 = _det3(J)
    if not (d1 > 0 and d2 > 0 and d3 > 0):
        raise ValueError(f"inertia matrix {J} is not positive definite")
    return J


def _det3(m) -> float:
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def _inv3(m) -> tuple:
    d = _det3(m)
    a, b, c = m[0]
    dd, e, f = m[1]
    g, h, i = m[2]
    return (
        ((e * i - f * h) / d, (c * h - b * i) / d, (b * f - c * e) / d),
        ((f * g - dd * i) / d, (a * i - c * g) / d, (c * dd - a * f) / d),
        ((dd * h - e * g) / d, (b * g - a * h) / d, (a * e - b * dd) / d),
    )


class RigidBody:
    """Equations of motion of the quadrotor airframe and their RK4 integration.

    Parameters
    ----------
    mass_kg : float
    inertia_kg_m2 : 3x3 nested tuple
        Symmetric positive-definite inertia matrix (see :func:`inertia_matrix`).
    linear_drag_xyz_n_s_per_m : 3 floats
        Body-frame drag coefficients: force = -c * (velocity relative to the air, body).
    parasitic_drag_xyz_n_s2_per_m2 : 3 floats
        Body-frame quadratic drag: force = -c * |v_air| * v_air (body), per axis.
    gravity_m_s2 : float
        Set 0 for torque-free tests.
    """

    def __init__(self, mass_kg: float, inertia_kg_m2, linear_drag_xyz_n_s_per_m,
                 gravity_m_s2: float = G, parasitic_drag_xyz_n_s2_per_m2=(0.0, 0.0, 0.0)):
        self.mass_kg = float(mass_kg)
        self.J = tuple(tuple(float(v) for v in row) for row in inertia_kg_m2)
        self.Jinv = _inv3(self.J)
        self.drag = tuple(float(c) for c in linear_drag_xyz_n_s_per_m)
        self.parasitic = tuple(float(c) for c in parasitic_drag_xyz_n_s2_per_m2)
        self.gravity_m_s2 = float(gravity_m_s2)

    def derivative(self, s, T, tx, ty, tz, wind, fext):
        """Time derivative of state ``s`` (see module docstring for the arguments)."""
        (_, _, _, qw, qx, qy, qz, vx, vy, vz, p, q, r) = s
        # Rotation matrix body -> NED (columns: body axes in NED).
        xx, yy, zz = qx * qx, qy * qy, qz * qz
        xy, xz, yz = qx * qy, qx * qz, qy * qz
        wx, wy, wz = qw * qx, qw * qy, qw * qz
        r00 = 1.0 - 2.0 * (yy + zz); r01 = 2.0 * (xy - wz); r02 = 2.0 * (xz + wy)
        r10 = 2.0 * (xy + wz); r11 = 1.0 - 2.0 * (xx + zz); r12 = 2.0 * (yz - wx)
        r20 = 2.0 * (xz - wy); r21 = 2.0 * (yz + wx); r22 = 1.0 - 2.0 * (xx + yy)
        cx, cy, cz = self.drag
        px, py, pz = self.parasitic
        fbx = 0.0
        fby = 0.0
        fbz = -T
        if cx or cy or cz or px or py or pz:
            ax, ay, az = vx - wind[0], vy - wind[1], vz - wind[2]
            bx = r00 * ax + r10 * ay + r20 * az        # air-relative velocity, body
            by = r01 * ax + r11 * ay + r21 * az
            bz = r02 * ax + r12 * ay + r22 * az
            speed = math.sqrt(ax * ax + ay * ay + az * az)
            fbx -= (cx + px * speed) * bx
            fby -= (cy + py * speed) * by
            fbz -= (cz + pz * speed) * bz
        m = self.mass_kg
        dvx = (r00 * fbx + r01 * fby + r02 * fbz + fext[0]) / m
        dvy = (r10 * fbx + r11 * fby + r12 * fbz + fext[1]) / m
        dvz = (r20 * fbx + r21 * fby + r22 * fbz + fext[2]) / m + self.gravity_m_s2
        dqw = 0.5 * (-qx * p - qy * q - qz * r)
        dqx = 0.5 * (qw * p + qy * r - qz * q)
        dqy = 0.5 * (qw * q + qz * p - qx * r)
        dqz = 0.5 * (qw * r + qx * q - qy * p)
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self.J
        hx = j00 * p + j01 * q + j02 * r
        hy = j10 * p + j11 * q + j12 * r
        hz = j20 * p + j21 * q + j22 * r
        # J w_dot = tau - w x (J w)
        ux = tx - (q * hz - r * hy)
        uy = ty - (r * hx - p * hz)
        uz = tz - (p * hy - q * hx)
        (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = self.Jinv
        return (vx, vy, vz, dqw, dqx, dqy, dqz, dvx, dvy, dvz,
                i00 * ux + i01 * uy + i02 * uz,
                i10 * ux + i11 * uy + i12 * uz,
                i20 * ux + i21 * uy + i22 * uz)

    def rk4_step(self, s, dt_s, T, tx, ty, tz, wind, fext):
        """One classical RK4 step with inputs held; the quaternion is renormalized.

        The same arithmetic, operation for operation, as :meth:`rk4_step_reference` (bit
        for bit: ``tests/firmware_sim/test_fsim_physics.py``), with the four derivative
        evaluations on plain floats: no intermediate 13-tuples, no method calls, no zips.
        It runs twice every 500 Hz control period and is most of the emulator's time.
        """
        m = self.mass_kg
        g = self.gravity_m_s2
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self.J
        (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = self.Jinv
        cx, cy, cz = self.drag
        px_, py_, pz_ = self.parasitic
        drag = bool(cx or cy or cz or px_ or py_ or pz_)
        wx_, wy_, wz_ = wind
        fx, fy, fz = fext

        def d(qw, qx, qy, qz, vx, vy, vz, p, q, r):
            # the body of derivative(), position derivative (= v) left to the caller
            xx, yy, zz = qx * qx, qy * qy, qz * qz
            xy, xz, yz = qx * qy, qx * qz, qy * qz
            wx, wy, wz = qw * qx, qw * qy, qw * qz
            r00 = 1.0 - 2.0 * (yy + zz); r01 = 2.0 * (xy - wz); r02 = 2.0 * (xz + wy)
            r10 = 2.0 * (xy + wz); r11 = 1.0 - 2.0 * (xx + zz); r12 = 2.0 * (yz - wx)
            r20 = 2.0 * (xz - wy); r21 = 2.0 * (yz + wx); r22 = 1.0 - 2.0 * (xx + yy)
            fbx = 0.0
            fby = 0.0
            fbz = -T
            if drag:
                ax, ay, az = vx - wx_, vy - wy_, vz - wz_
                bx = r00 * ax + r10 * ay + r20 * az
                by = r01 * ax + r11 * ay + r21 * az
                bz = r02 * ax + r12 * ay + r22 * az
                speed = math.sqrt(ax * ax + ay * ay + az * az)
                fbx -= (cx + px_ * speed) * bx
                fby -= (cy + py_ * speed) * by
                fbz -= (cz + pz_ * speed) * bz
            hx = j00 * p + j01 * q + j02 * r
            hy = j10 * p + j11 * q + j12 * r
            hz = j20 * p + j21 * q + j22 * r
            ux = tx - (q * hz - r * hy)
            uy = ty - (r * hx - p * hz)
            uz = tz - (p * hy - q * hx)
            return (0.5 * (-qx * p - qy * q - qz * r), 0.5 * (qw * p + qy * r - qz * q),
                    0.5 * (qw * q + qz * p - qx * r), 0.5 * (qw * r + qx * q - qy * p),
                    (r00 * fbx + r01 * fby + r02 * fbz + fx) / m,
                    (r10 * fbx + r11 * fby + r12 * fbz + fy) / m,
                    (r20 * fbx + r21 * fby + r22 * fbz + fz) / m + g,
                    i00 * ux + i01 * uy + i02 * uz,
                    i10 * ux + i11 * uy + i12 * uz,
                    i20 * ux + i21 * uy + i22 * uz)

        (s0, s1, s2, s3, s4, s5, s6, s7, s8, s9, s10, s11, s12) = s
        h2 = 0.5 * dt_s
        a3, a4, a5, a6, a7, a8, a9, a10, a11, a12 = d(s3, s4, s5, s6, s7, s8, s9, s10, s11, s12)
        # k1 = (s7, s8, s9, a3 .. a12); state for k2 = s + h2 k1
        v2x, v2y, v2z = s7 + h2 * a7, s8 + h2 * a8, s9 + h2 * a9
        b3, b4, b5, b6, b7, b8, b9, b10, b11, b12 = d(
            s3 + h2 * a3, s4 + h2 * a4, s5 + h2 * a5, s6 + h2 * a6, v2x, v2y, v2z,
            s10 + h2 * a10, s11 + h2 * a11, s12 + h2 * a12)
        v3x, v3y, v3z = s7 + h2 * b7, s8 + h2 * b8, s9 + h2 * b9
        c3, c4, c5, c6, c7, c8, c9, c10, c11, c12 = d(
            s3 + h2 * b3, s4 + h2 * b4, s5 + h2 * b5, s6 + h2 * b6, v3x, v3y, v3z,
            s10 + h2 * b10, s11 + h2 * b11, s12 + h2 * b12)
        v4x, v4y, v4z = s7 + dt_s * c7, s8 + dt_s * c8, s9 + dt_s * c9
        e3, e4, e5, e6, e7, e8, e9, e10, e11, e12 = d(
            s3 + dt_s * c3, s4 + dt_s * c4, s5 + dt_s * c5, s6 + dt_s * c6, v4x, v4y, v4z,
            s10 + dt_s * c10, s11 + dt_s * c11, s12 + dt_s * c12)
        h6 = dt_s / 6.0
        qw = s3 + h6 * (a3 + 2.0 * (b3 + c3) + e3)
        qx = s4 + h6 * (a4 + 2.0 * (b4 + c4) + e4)
        qy = s5 + h6 * (a5 + 2.0 * (b5 + c5) + e5)
        qz = s6 + h6 * (a6 + 2.0 * (b6 + c6) + e6)
        norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        if norm > 0.0:
            qw = qw / norm; qx = qx / norm; qy = qy / norm; qz = qz / norm
        return (s0 + h6 * (s7 + 2.0 * (v2x + v3x) + v4x),
                s1 + h6 * (s8 + 2.0 * (v2y + v3y) + v4y),
                s2 + h6 * (s9 + 2.0 * (v2z + v3z) + v4z),
                qw, qx, qy, qz,
                s7 + h6 * (a7 + 2.0 * (b7 + c7) + e7),
                s8 + h6 * (a8 + 2.0 * (b8 + c8) + e8),
                s9 + h6 * (a9 + 2.0 * (b9 + c9) + e9),
                s10 + h6 * (a10 + 2.0 * (b10 + c10) + e10),
                s11 + h6 * (a11 + 2.0 * (b11 + c11) + e11),
                s12 + h6 * (a12 + 2.0 * (b12 + c12) + e12))

    def rk4_step_reference(self, s, dt_s, T, tx, ty, tz, wind, fext):
        """One classical RK4 step with inputs held; the quaternion is renormalized (the
        straightforward version: :meth:`derivative` on 13-tuples; the reference of
        :meth:`rk4_step`)."""
        f = self.derivative
        h2 = 0.5 * dt_s
        k1 = f(s, T, tx, ty, tz, wind, fext)
        k2 = f(tuple([a + h2 * b for a, b in zip(s, k1)]), T, tx, ty, tz, wind, fext)
        k3 = f(tuple([a + h2 * b for a, b in zip(s, k2)]), T, tx, ty, tz, wind, fext)
        k4 = f(tuple([a + dt_s * b for a, b in zip(s, k3)]), T, tx, ty, tz, wind, fext)
        h6 = dt_s / 6.0
        n = [a + h6 * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(s, k1, k2, k3, k4)]
        qw, qx, qy, qz = n[3], n[4], n[5], n[6]
        norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        if norm > 0.0:
            n[3] = qw / norm; n[4] = qx / norm; n[5] = qy / norm; n[6] = qz / norm
        return tuple(n)


def normalize_quat(q):
    """Unit quaternion with non-negative scalar part."""
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if w < 0:
        n = -n
    return (w / n, x / n, y / n, z / n)


def quat_mul(a, b):
    """Hamilton product ``a * b`` of ``(w, x, y, z)`` quaternions."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def rotate(q, v):
    """Rotate body vector ``v`` to NED with unit quaternion ``q``."""
    w, x, y, z = q
    vx, vy, vz = v
    # v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)
    cx = y * vz - z * vy
    cy = z * vx - x * vz
    cz = x * vy - y * vx
    return (vx + 2.0 * (w * cx + y * cz - z * cy),
            vy + 2.0 * (w * cy + z * cx - x * cz),
            vz + 2.0 * (w * cz + x * cy - y * cx))


def rotate_inv(q, v):
    """Rotate NED vector ``v`` into the body frame."""
    w, x, y, z = q
    return rotate((w, -x, -y, -z), v)


def quat_from_euler(roll_rad: float, pitch_rad: float, yaw_rad: float):
    """ZYX (yaw, pitch, roll) angles to a body->NED quaternion."""
    cr, sr = math.cos(roll_rad / 2), math.sin(roll_rad / 2)
    cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
    cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    return (cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy)


def euler_from_quat(q):
    """ZYX roll, pitch, yaw (rad) of a body->NED quaternion (singular at pitch +-90 deg)."""
    w, x, y, z = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    sp = 2.0 * (w * y - z * x)
    pitch = math.asin(max(-1.0, min(1.0, sp)))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def yaw_of(q, fallback_rad: float = 0.0) -> float:
    """Heading of the body x axis projected on the horizontal plane (rad).

    Falls back to the body y axis, then to ``fallback_rad``, when x is near vertical.
    """
    w, x, y, z = q
    r00 = 1.0 - 2.0 * (y * y + z * z)
    r10 = 2.0 * (x * y + w * z)
    if r00 * r00 + r10 * r10 > 1e-4:
        return math.atan2(r10, r00)
    r01 = 2.0 * (x * y - w * z)
    r11 = 1.0 - 2.0 * (x * x + z * z)
    if r01 * r01 + r11 * r11 > 1e-4:
        return math.atan2(r11, r01) - math.pi / 2
    return fallback_rad
