"""Per-rotor thrust: first-order lag, Gaussian noise, saturation, and the plus mixer.

Rotor layout (docs/conventions.md): 1 front (+l, 0), 2 right (0, +l), 3 back (-l, 0),
4 left (0, -l); thrust along body -z. Body torques::

    roll  = l (f4 - f2)
    pitch = l (f1 - f3)
    yaw   = k (-f1 + f2 - f3 + f4)

With the centre of mass at ``c = (cx, cy, cz)`` from the rotors' centre, each thrust acts
at its rotor position minus ``c``; summed, ``sum (p_i - c) x (0, 0, -f_i)`` adds
``(cy T, -cx T, 0)`` to the torques above (``T`` the total thrust; ``cz`` gives none,
the thrusts being parallel to body z).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["Rotors", "mix"]

_NOISE_CHUNK = 4096


def mix(f, arm_length_m: float, drag_torque_ratio_m: float, com_x_m: float = 0.0,
        com_y_m: float = 0.0):
    """Total thrust (N) and body torques (N m) about the centre of mass of rotor forces
    ``f`` (4 floats); the centre of mass at ``(com_x_m, com_y_m)`` in the body x-y plane."""
    f1, f2, f3, f4 = f
    if com_x_m or com_y_m:
        T = f1 + f2 + f3 + f4
        return (T,
                arm_length_m * (f4 - f2) + com_y_m * T,
                arm_length_m * (f1 - f3) - com_x_m * T,
                drag_torque_ratio_m * (-f1 + f2 - f3 + f4))
    return (f1 + f2 + f3 + f4,
            arm_length_m * (f4 - f2),
            arm_length_m * (f1 - f3),
            drag_torque_ratio_m * (-f1 + f2 - f3 + f4))


class Rotors:
    """Four rotors with a first-order thrust lag, sampled at the physics step.

    The lag is discretized exactly: ``f += (1 - exp(-dt/tau)) (cmd - f)``, so sampled
    step responses equal ``cmd (1 - exp(-t/tau))``. The command is clipped to
    ``[0, max]`` before the lag; noise is added after it, only while armed, and the
    applied thrust is clipped to ``[0, max]`` again.

    Parameters
    ----------
    max_rotor_thrust_n : float
    time_constant_s : float
        0 for ideal actuators.
    noise_sd_n : float
        Standard deviation of the Gaussian noise on each applied thrust.
    dt_s : float
        Physics step.
    rng : numpy.random.Generator
        The simulation's noise generator (seeded once).
    thrust_scale : float
        Thrust given per unit commanded (a sagging battery: 0.9); it scales the lagged
        thrust, so the saturation becomes ``thrust_scale * max_rotor_thrust_n``.
    rotor_gain : 4 floats
        Each rotor's own thrust per unit commanded (its thrust constant against the
        file's), on top of ``thrust_scale``: rotor i gives ``thrust_scale * rotor_gain[i]``
        times its command and saturates at that times ``max_rotor_thrust_n``.
    """

    def __init__(self, max_rotor_thrust_n: float, time_constant_s: float, noise_sd_n: float,
                 dt_s: float, rng: np.random.Generator, thrust_scale: float = 1.0,
                 rotor_gain=(1.0, 1.0, 1.0, 1.0)):
        self.max_rotor_thrust_n = float(max_rotor_thrust_n)
        self.thrust_scale = float(thrust_scale)
        self.rotor_gain = tuple(float(g) for g in rotor_gain)
        if len(self.rotor_gain) != 4 or not all(g > 0.0 for g in self.rotor_gain):
            raise ValueError(f"rotor_gain needs four positive numbers, got {rotor_gain!r}")
        # thrust per unit commanded, per rotor (exactly thrust_scale when the gains are 1)
        self.gain = tuple(self.thrust_scale * g for g in self.rotor_gain)
        self.alpha = 1.0 if time_constant_s <= 0 else 1.0 - math.exp(-dt_s / time_constant_s)
        self.noise_sd_n = float(noise_sd_n)
        self.rng = rng
        self.lagged_n = [0.0, 0.0, 0.0, 0.0]
        self._noise: list = []
        self._noise_i = 0

    def _next_noise(self):
        if self._noise_i >= len(self._noise):
            self._noise = (self.rng.standard_normal((_NOISE_CHUNK, 4)) * self.noise_sd_n).tolist()
            self._noise_i = 0
        row = self._noise[self._noise_i]
        self._noise_i += 1
        return row

    def step(self, cmd_n, armed: bool):
        """Advance one physics step toward ``cmd_n``; return the applied thrusts (tuple)."""
        fmax = self.max_rotor_thrust_n
        a = self.alpha
        lag = self.lagged_n
        k = self.gain
        for i in range(4):
            c = cmd_n[i]
            c = 0.0 if c < 0.0 else (fmax if c > fmax else c)
            lag[i] += a * (k[i] * c - lag[i])
        if self.noise_sd_n > 0.0 and armed:
            n = self._next_noise()
            out = []
            for i in range(4):
                v = lag[i] + n[i]
                m = fmax * k[i]
                out.append(0.0 if v < 0.0 else (m if v > m else v))
            return tuple(out)
        return (lag[0], lag[1], lag[2], lag[3])
