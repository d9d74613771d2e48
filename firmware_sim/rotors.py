"""Per-rotor thrust: first-order lag, Gaussian noise, saturation, and the plus mixer.

Rotor layout (conventions.md): 1 front (+l, 0), 2 right (0, +l), 3 back (-l, 0),
4 left (0, -l); thrust along body -z. Body torques::

    roll  = l (f4 - f2)
    pitch = l (f1 - f3)
    yaw   = k (-f1 + f2 - f3 + f4)
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["Rotors", "mix"]

_NOISE_CHUNK = 4096


def mix(f, arm_length_m: float, drag_torque_ratio_m: float):
    """Total thrust (N) and body torques (N m) of rotor forces ``f`` (4 floats)."""
    f1, f2, f3, f4 = f
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
    """

    def __init__(self, max_rotor_thrust_n: float, time_constant_s: float, noise_sd_n: float,
                 dt_s: float, rng: np.random.Generator, thrust_scale: float = 1.0):
        self.max_rotor_thrust_n = float(max_rotor_thrust_n)
        self.thrust_scale = float(thrust_scale)
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
        k = self.thrust_scale
        for i in range(4):
            c = cmd_n[i]
            c = 0.0 if c < 0.0 else (fmax if c > fmax else c)
            lag[i] += a * (k * c - lag[i])
        fmax *= k
        if self.noise_sd_n > 0.0 and armed:
            n = self._next_noise()
            out = []
            for i in range(4):
                v = lag[i] + n[i]
                out.append(0.0 if v < 0.0 else (fmax if v > fmax else v))
            return tuple(out)
        return (lag[0], lag[1], lag[2], lag[3])
