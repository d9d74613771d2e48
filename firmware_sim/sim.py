"""The simulated airframe: rigid body, rotors, wind, ground, limits and recorder together.

No I/O, no clock: :meth:`Simulation.advance` runs the physics steps of one control
period (or part of one) with the rotor command held.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from .ground import Ground, Limits, check_limits
from .params import SimParams
from .physics import G, RigidBody
from .rotors import Rotors, mix
from .wind import Wind

__all__ = ["Simulation", "GROUND_STATE"]

GROUND_STATE = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
"""Resting on the ground at the origin, level, heading north."""


class Simulation:
    """Physics of the vehicle, stepped at ``params.physics_hz``.

    Parameters
    ----------
    params : SimParams
    state : 13-tuple, optional
        Initial state (see :mod:`firmware_sim.physics`); default on the ground.
    wind : Wind, optional
    recorder : Recorder, optional
        Receives one row per physics step (and the initial state).
    limits : Limits, optional
    gravity_m_s2 : float
        Only tests change it.
    """

    def __init__(self, params: SimParams, state=None, wind: Wind | None = None,
                 recorder=None, limits: Limits | None = None, gravity_m_s2: float = G):
        v = params.vehicle
        self.params = params
        self.dt_s = 1.0 / params.physics_hz
        self.substeps = params.substeps
        self.rng = np.random.default_rng(params.seed)
        self.body = RigidBody(v.mass_kg, params.inertia_matrix_kg_m2,
                              v.emulator.linear_drag_xyz_n_s_per_m, gravity_m_s2,
                              v.emulator.parasitic_drag_xyz_n_s2_per_m2)
        self.rotors = Rotors(v.max_rotor_thrust_n, v.true_rotor_time_constant_s,
                             v.emulator.rotor_noise_sd_n, self.dt_s, self.rng,
                             v.emulator.thrust_scale, params.rotor_gain)
        self.ground = Ground(v.emulator.crash_speed_m_s)
        self.wind = wind if wind is not None else Wind()
        self.limits = limits if limits is not None else Limits()
        self.recorder = recorder
        self.arm_length_m = v.arm_length_m
        self.k_m = v.drag_torque_ratio_m
        self.angular_drag = params.angular_drag_n_m_s_per_rad
        self.com_offset_m = tuple(float(c) for c in params.com_offset_m)
        self.state = tuple(float(x) for x in (state if state is not None else GROUND_STATE))
        self.step_count = 0
        self.t_s = 0.0
        self.applied_n = (0.0, 0.0, 0.0, 0.0)
        self._history: deque | None = None
        self.state = self.ground.apply(self.state, 0.0) if self.state[2] >= 0 else self.state
        if state is not None and self.state[2] < 0:
            # Start in flight with rotors already spinning at hover.
            hover = v.mass_kg * G / 4
            self.rotors.lagged_n = [hover] * 4
            self.applied_n = (hover,) * 4

    @property
    def on_ground(self) -> bool:
        """Whether the vehicle rests on the ground."""
        return self.ground.on_ground

    def keep_history(self, n_steps: int) -> None:
        """Keep the true states of the last ``n_steps`` physics steps (for :attr:`lagged_state`).

        Before the start the vehicle is taken to have been in its initial state.
        """
        self._history = deque([self.state] * (int(n_steps) + 1), maxlen=int(n_steps) + 1)

    @property
    def lagged_state(self):
        """The true state ``n_steps`` physics steps ago (see :meth:`keep_history`)."""
        return self._history[0] if self._history is not None else self.state

    def record_initial(self, armed: bool, mode: int) -> None:
        """Write the initial state as the recorder's first row."""
        if self.recorder is not None:
            self.recorder.record(self.t_s, self.state, (0.0,) * 4, self.applied_n, armed, mode,
                                 self.ground.on_ground)

    def advance(self, cmd_n, armed: bool, mode: int, steps: int | None = None) -> None:
        """Run ``steps`` physics steps (default: one control period) with ``cmd_n`` held.

        Raises
        ------
        SimStop
            On a crash, a non-finite state or a limit exceeded.
        """
        body, rotors, ground, wind, rec = self.body, self.rotors, self.ground, self.wind, self.recorder
        hist = self._history
        l, k, dt = self.arm_length_m, self.k_m, self.dt_s
        cx, cy = self.com_offset_m[0], self.com_offset_m[1]
        s = self.state
        n0 = self.step_count
        pdt = self.params.physics_hz
        steps = self.substeps if steps is None else steps
        for i in range(1, steps + 1):
            t0 = (n0 + i - 1) / pdt
            applied = rotors.step(cmd_n, armed)
            T, tx, ty, tz = mix(applied, l, k, cx, cy)
            if self.angular_drag:
                tx, ty, tz = (tx - self.angular_drag * s[10], ty - self.angular_drag * s[11],
                              tz - self.angular_drag * s[12])
            w, f = wind.at(t0)
            if ground.on_ground and T < 1e-9 and not wind.items:
                pass       # resting, nothing acts that could lift it
            else:
                s = body.rk4_step(s, dt, T, tx, ty, tz, w, f)
            t1 = (n0 + i) / pdt
            check_limits(s, t1, self.limits)
            s = ground.apply(s, t1)
            self.state = s
            self.applied_n = applied
            if rec is not None:
                rec.record(t1, s, cmd_n, applied, armed, mode, ground.on_ground)
            if hist is not None:
                hist.append(s)
        self.step_count = n0 + steps
        self.t_s = self.step_count / pdt
