"""PX4's roll and pitch rate step on SIH, measured as the emulator's ``--print-rate-response``
defines its own (:mod:`firmware_sim.rate_response`): the true body rate after the step.

PX4 hovers in OFFBOARD on body rates and thrust (``SET_ATTITUDE_TARGET``, type_mask 128) at
:data:`SEND_HZ`, held level by a small stabilizer of this module's own (:class:`Hover`: a P loop
from ATTITUDE's angles to rates, a weak velocity damping, a PI altitude loop on
LOCAL_POSITION_NED). Then, per repetition and axis, the axis' rate command is held at 0 for
:data:`QUIET_S`, stepped to ``+-step`` for ``step_s`` and to ``-+step`` for as long (the doublet
brings the attitude back), and the stabilizer resumes. The response is SIH's true body rate
(``HIL_STATE_QUATERNION``'s rollspeed/pitchspeed on its display link, stamped on arrival by the
wall clock) from the wall-clock time the step's first set-point was SENT, less the rate at that
moment, over ``step_s``, as a fraction of the step, averaged over the repetitions (the signs
alternate). The same from ATTITUDE's rates (PX4's filtered gyro, also stamped on arrival) is
reported beside it. The figures come from :func:`firmware_sim.rate_response.step_figures`.

PX4 SIH runs in lockstep, at real-time speed where the machine keeps up: the samples are
stamped by the wall clock, and the response is read on PX4's own clock, which ran at
``sim_speed`` (its ``time_boot_ms`` in ATTITUDE against the wall clock over the steps) times
it (0.96 on a loaded 2-core machine).
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np

from firmware_sim.rate_response import step_figures

from .autopilot_baseline_flight import _read_params
from .px4_sitl import Px4Sitl
from .sitl_link import M, SitlError

__all__ = ["measure_px4_rate_step", "READ_PARAMS", "Hover", "mean_response", "SEND_HZ"]

SEND_HZ = 200.0
QUIET_S = 0.15
"""The stepped axis' command is 0 this long before its step (the step starts from 0)."""
RECOVER_S = 1.2
HOVER_THRUST = 0.49
TAKEOFF_M = 2.5
TRUTH_HZ = 200.0
READ_PARAMS = tuple(f"MC_{a}RATE_{k}" for a in ("ROLL", "PITCH", "YAW") for k in ("P", "I", "D", "K", "FF")) + (
    "MC_RR_INT_LIM", "MC_PR_INT_LIM", "MC_YR_INT_LIM", "IMU_GYRO_CUTOFF", "IMU_DGYRO_CUTOFF", "IMU_GYRO_RATEMAX", "IMU_INTEG_RATE",
    "MC_AIRMODE", "THR_MDL_FAC", "MPC_THR_HOVER", "CA_AIRFRAME", "CA_ROTOR_COUNT", "CA_ROTOR0_PX", "CA_ROTOR0_PY",
    "CA_ROTOR0_CT", "CA_ROTOR0_KM", "SIH_MASS", "SIH_IXX", "SIH_IYY", "SIH_T_MAX", "SIH_Q_MAX", "SIH_T_TAU",
    "SIH_L_ROLL", "SIH_L_PITCH", "SIH_KDW", "SIH_KDV")
"""What the rate step depends on, read back over MAVLink (None where PX4 has no such parameter)."""
OFFBOARD = (6, 0)


class Hover:
    """The script's own stabilizer: body rates and a collective from the latest ATTITUDE and
    LOCAL_POSITION_NED. Level (P on roll and pitch towards a small tilt that damps the
    horizontal velocity), the heading of the start, and the height ``z_ref`` (NED) by PI+D."""

    K_ATT, K_VEL, K_YAW = 3.0, 0.12, 1.0
    K_Z, K_VZ, K_IZ = 0.12, 0.08, 0.04

    def __init__(self):
        self.att = None
        self.pos = None
        self.yaw0 = None
        self.z_ref = None
        self.iz = 0.0
        self.acks: dict = {}
        self.hb = None
        self.boot: list[tuple[float, float]] = []
        """(wall clock, PX4's time_boot_ms in s) of each ATTITUDE."""
        self.att_rates: list[tuple] = []

    def update(self, m) -> None:
        t = m.get_type()
        if t == "ATTITUDE":
            self.att = m
            now = time.time()
            self.boot.append((now, m.time_boot_ms * 1e-3))
            self.att_rates.append((now, m.rollspeed, m.pitchspeed, m.yawspeed))
            if self.yaw0 is None:
                self.yaw0 = m.yaw
        elif t == "LOCAL_POSITION_NED":
            self.pos = m
        elif t == "COMMAND_ACK":
            self.acks[m.command] = m.result
        elif t == "HEARTBEAT" and m.get_srcComponent() == 1:
            self.hb = m

    def command(self, dt: float, thrust_on: bool = True) -> list:
        """``[p, q, r, thrust]``; zero rates and thrust before ATTITUDE and position arrive."""
        a, s = self.att, self.pos
        if a is None or s is None or not thrust_on:
            return [0.0, 0.0, 0.0, 0.0]
        cy, sy = math.cos(a.yaw), math.sin(a.yaw)
        v_fwd, v_right = cy * s.vx + sy * s.vy, -sy * s.vx + cy * s.vy
        roll_sp = max(-0.2, min(0.2, -self.K_VEL * v_right))
        pitch_sp = max(-0.2, min(0.2, self.K_VEL * v_fwd))
        yaw_err = math.remainder(a.yaw - self.yaw0, 2 * math.pi)
        ez = s.z - self.z_ref
        self.iz = max(-0.1, min(0.1, self.iz + self.K_IZ * ez * dt))
        tilt = max(0.7, math.cos(a.roll) * math.cos(a.pitch))
        thrust = (HOVER_THRUST + self.K_Z * ez + self.K_VZ * s.vz + self.iz) / tilt
        return [self.K_ATT * (roll_sp - a.roll), self.K_ATT * (pitch_sp - a.pitch), -self.K_YAW * yaw_err,
                max(0.05, min(0.9, thrust))]

    @property
    def armed(self) -> bool:
        return self.hb is not None and bool(self.hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)

    @property
    def offboard(self) -> bool:
        return self.hb is not None and (self.hb.custom_mode >> 16) & 0xFF == OFFBOARD[0]


class _Flight:
    """The set-point stream of one measurement: a hover, and the steps when asked for."""

    def __init__(self, px4: Px4Sitl):
        self.px4, self.hover = px4, Hover()
        self.t0 = time.monotonic()
        self.thrust_on = False
        self.override = None
        """``(axis, rate)``: the stepped axis' command while a step runs."""
        self.mark = None
        self.steps: list[tuple[float, int, int]] = []
        """(wall clock when the step's first set-point was sent, axis, sign)."""

    def run(self, until, timeout_s: float, what: str, schedule=None) -> None:
        """Send set-points at :data:`SEND_HZ` and receive in between until ``until()``;
        ``schedule(seconds since the call)`` may set :attr:`override` first."""
        period, start = 1.0 / SEND_HZ, time.monotonic()
        next_send, deadline = start, start + timeout_s
        while not until():
            now = time.monotonic()
            if now > deadline:
                raise self.px4._timeout(what, timeout_s)
            if now >= next_send:
                if schedule is not None:
                    schedule(now - start)
                self._send(period)
                next_send = max(next_send + period, now)
                self.px4._check_alive(what)
            m = self.px4.recv(max(0.0005, next_send - time.monotonic()))
            while m is not None:
                self.hover.update(m)
                m = self.px4.recv(0.0) if time.monotonic() < next_send else None

    def _send(self, dt: float) -> None:
        sp = self.hover.command(dt, self.thrust_on)
        if self.override is not None:
            sp[self.override[0]] = self.override[1]
        t_ms = int(1e3 * (time.monotonic() - self.t0)) & 0xFFFFFFFF
        self.px4.conn.mav.set_attitude_target_send(t_ms, self.px4.sysid, self.px4.compid, 128,
                                                   [1.0, 0.0, 0.0, 0.0], sp[0], sp[1], sp[2], sp[3])
        if self.mark is not None:
            self.steps.append((time.time(), *self.mark))
            self.mark = None

    def command(self, command: int, *params: float) -> None:
        self.hover.acks.pop(command, None)
        p = [float(v) for v in params] + [0.0] * (7 - len(params))
        self.px4.conn.mav.command_long_send(self.px4.sysid, self.px4.compid, command, 0, *p)
        self.run(lambda: command in self.hover.acks, 3.0, f"COMMAND_ACK of {command}")
        if self.hover.acks[command] != M.MAV_RESULT_ACCEPTED:
            texts = "; ".join(t for _, t in self.px4.texts[-3:])
            raise SitlError(f"PX4: command {command} {params} refused ({self.hover.acks[command]}; {texts})")

    def wait(self, seconds: float, what: str) -> None:
        t_end = time.monotonic() + seconds
        self.run(lambda: time.monotonic() >= t_end, seconds + 5.0, what)

    def take_off(self) -> None:
        """Zero set-points streaming, OFFBOARD, arm, climb to :data:`TAKEOFF_M`, settle."""
        h = self.hover
        self.run(lambda: h.att is not None and h.pos is not None, 10.0, "ATTITUDE and LOCAL_POSITION_NED")
        self.wait(1.0, "the stream before OFFBOARD")
        self.command(M.MAV_CMD_DO_SET_MODE, 1, *OFFBOARD)
        self.run(lambda: h.offboard, 5.0, "OFFBOARD in the HEARTBEAT")
        self.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        self.run(lambda: h.armed, 5.0, "armed in the HEARTBEAT")
        z0 = h.pos.z
        h.z_ref, self.thrust_on = z0, True

        def climb(t):
            h.z_ref = z0 - TAKEOFF_M * min(1.0, t / 3.0)
        t_end = time.monotonic() + 6.0
        self.run(lambda: time.monotonic() >= t_end, 10.0, "the climb", climb)

    def steps_of(self, axes, reps: int, step_rad_s: float, step_s: float) -> None:
        """The doublets, each from a quiet command on its axis, then :data:`RECOVER_S` of hover."""
        for rep in range(reps):
            for axis in axes:
                sign = 1 if rep % 2 == 0 else -1
                state = {"phase": 0}

                def schedule(t, axis=axis, sign=sign, state=state):
                    if t < QUIET_S:
                        self.override = (axis, 0.0)
                    elif t < QUIET_S + step_s:
                        if state["phase"] == 0:
                            state["phase"], self.mark = 1, (axis, sign)
                        self.override = (axis, sign * step_rad_s)
                    elif t < QUIET_S + 2 * step_s:
                        self.override = (axis, -sign * step_rad_s)
                    else:
                        self.override = None
                t_end = time.monotonic() + QUIET_S + 2 * step_s + RECOVER_S
                self.run(lambda t_end=t_end: time.monotonic() >= t_end, 10.0, "a step", schedule)


def mean_response(samples, steps, axis: int, step_rad_s: float, step_s: float, dt_s: float = 1e-3,
                  speed: float = 1.0):
    """``(t, w, n)``: the rate of ``axis`` (rad/s) after each of its ``n`` steps' send time, less
    its value then, signed as the step (a response to ``+step_rad_s``), averaged; ``samples``
    rows (wall clock, p, q, r) interpolated onto a ``dt_s`` grid over ``[0, step_s)`` of PX4's
    clock, which runs at ``speed`` times the wall clock."""
    s = np.asarray(samples, dtype=float)
    t = np.arange(0.0, step_s - 1e-9, dt_s)
    ys = []
    for t_send, ax, sign in steps:
        if ax != axis or t_send + step_s / speed > s[-1, 0]:
            continue
        w = np.interp(t_send + t / speed, s[:, 0], s[:, 1 + axis])
        ys.append((w - w[0]) / sign)
    if not ys:
        raise SitlError(f"no step of axis {axis} with samples after it")
    return t, np.mean(ys, axis=0), len(ys)


def _rate_hz(samples) -> float:
    s = np.asarray(samples, dtype=float)
    return float((len(s) - 1) / (s[-1, 0] - s[0, 0])) if len(s) > 1 else 0.0


def measure_px4_rate_step(axes=(0, 1), reps: int = 6, step_rad_s: float = 1.0, step_s: float = 0.4,
                          params: dict | None = None, instance: int | None = None, log=None) -> dict:
    """Start a fresh PX4 SIH, hover, step; ``{"params": read back, "truth": {axis: StepResponse},
    "attitude": {axis: StepResponse}, "steps": n per axis, "truth_hz", "attitude_hz", "sim_speed"}``."""
    log = log or (lambda text: print(text, file=sys.stderr, flush=True))
    with Px4Sitl(params=params, instance=instance) as px4:
        px4.truth.rate_hz = TRUTH_HZ
        read = _read_params(px4, READ_PARAMS)
        px4.set_rate(M.MAVLINK_MSG_ID_ATTITUDE, 200.0)
        px4.set_rate(M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 50.0)
        fl = _Flight(px4)
        log("PX4 ready: OFFBOARD, arm, climb")
        fl.take_off()
        log(f"hovering {-fl.hover.pos.z:.2f} m above EKF2's origin; {reps} steps per axis")
        t_steps = len(fl.hover.boot)
        fl.steps_of(axes, reps, step_rad_s, step_s)
        boot = np.asarray(fl.hover.boot[t_steps:])
        truth, att = list(px4.truth.rates), fl.hover.att_rates
    px4.cleanup()
    speed = float((boot[-1, 1] - boot[0, 1]) / (boot[-1, 0] - boot[0, 0]))
    out = {"params": read, "truth": {}, "attitude": {}, "steps": {}, "truth_hz": _rate_hz(truth),
           "attitude_hz": _rate_hz(att), "sim_speed": speed}
    for axis in axes:
        for key, samples in (("truth", truth), ("attitude", att)):
            t, w, n = mean_response(samples, fl.steps, axis, step_rad_s, step_s, speed=speed)
            out[key][axis] = step_figures(axis, step_rad_s, t, w)
            out["steps"][axis] = n
    return out
