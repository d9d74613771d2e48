"""Deterministic harness for supervisor tests: a fake plan, a fake regulator and a tiny
vehicle on the design model (RK4), all driven by an injected clock (no sockets).

The harness's own check (the vehicle sits still while disarmed) is in
``tests/unit/test_supervisor.py``."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.control.controllers.hover import HoverController, Ramp
from mavreg.control.controllers.regulator import RegulatorOutput
from mavreg.daemon.vehicle.messages import PX4_MAIN_AUTO, PX4_MAIN_OFFBOARD, PX4_SUB_LOITER
from mavreg.daemon.flight.supervisor import Supervisor, SupervisorParams
from mavreg.model.mixer import Mixer
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import rpy_to_quat, rpy_to_matrix
from harness import params

VEHICLE = params.vehicle()
CONTROLLER = params.controller()
"""The paper's controller: no prediction, no disturbance observer (a daemon's config needs one)."""
_PARSER = mavlink2.MAVLink(None)
_PARSER.robust_parsing = True


def wire(msg, sysid=1, compid=1):
    """Pack ``msg`` as (sysid, compid) and decode it, as the link would."""
    mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    return _PARSER.decode(bytearray(msg.pack(mav)))


def att_q(t, rpy=(0.0, 0.0, 0.0), rates=(0.0, 0.0, 0.0)):
    """ATTITUDE_QUATERNION at ``time_boot_ms`` ``t``, as received."""
    return wire(mavlink2.MAVLink_attitude_quaternion_message(t, *rpy_to_quat(*rpy), *rates))


def att_e(t, rpy=(0.0, 0.0, 0.0), rates=(0.0, 0.0, 0.0)):
    """ATTITUDE (Euler angles) at ``time_boot_ms`` ``t``, as received."""
    return wire(mavlink2.MAVLink_attitude_message(t, *rpy, *rates))


def pos(t, p=(0.0, 0.0, 0.0), v=(0.0, 0.0, 0.0)):
    """LOCAL_POSITION_NED at ``time_boot_ms`` ``t``, as received."""
    return wire(mavlink2.MAVLink_local_position_ned_message(t, *p, *v))


@dataclass
class FakePlan:
    """A straight line north at 2 m altitude, flown at ``speed`` m/s."""

    name: str = "line"
    length_m: float = 2.0
    speed: float = 1.0
    start: tuple = (1.0, 0.5, -2.0)
    attitude_error: str = "rpy"
    rotor_time_constant_s: float = 0.02

    @property
    def segments(self):
        return (("line", 0.0, self.length_m),)

    def nominal_state(self, s):
        x = np.zeros(12)
        x[:3] = np.array(self.start) + [s, 0.0, 0.0]
        x[6] = self.speed
        return x

    @property
    def entry_state(self):
        return self.nominal_state(0.0)

    def summary(self):
        return {"name": self.name, "length_m": self.length_m}




class FakeRegulator:
    """Tracks the fake line with the hover LQR about the nominal point at the projected s."""

    def __init__(self, plan, rotor_lag=None, nan_at_s=None):
        """``rotor_lag``: the flight's rotor lag in effect, as a regulator factory is given it
        (the fake has no feedforward to lead)."""
        self.plan = plan
        self.hover = HoverController(VEHICLE)
        self.nan_at_s = nan_at_s
        self.resets = []

    def reset(self, x, s_guess=0.0, rotor_forces_n=None):
        self.resets.append((np.array(x), s_guess))

    def step(self, x, rotor_forces_n=None, disturbance=None):
        s = float(x[0] - self.plan.start[0])
        xn = self.plan.nominal_state(min(max(s, 0.0), self.plan.length_m))
        ramp = Ramp(np.zeros((4, 8)), 0.0, xn[:3], np.array([self.plan.speed, 0, 0]), 0.0)
        ho = self.hover.step(x, ramp, 0.0)
        w = np.concatenate([[x[1] - xn[1], x[2] - xn[2]], ho.error[3:]])
        forces = ho.rotor_forces_n
        if self.nan_at_s is not None and s >= self.nan_at_s:
            forces = forces * np.nan
        return RegulatorOutput(s, w, ho.u, forces, bool(abs(w[0]) < 0.5), s >= self.plan.length_m)


class SimVehicle:
    """A minimal PX4-like vehicle: arms, grants OFFBOARD after 0.5 s of stream, flies RK4.

    ``mass_scale`` makes it heavier than the design; it accepts a disarm in flight only
    with the force code (as PX4 does) and sends a HEARTBEAT at once on an arming change;
    ``ignore_disarm`` commands are dropped unanswered (a lossy uplink). It answers TIMESYNC
    requests with its own clock, as PX4, ArduPilot and firmware_sim do, unless
    ``answer_timesync`` is False. It speaks as ``system_id`` (component 1), announces
    ``autopilot`` in its HEARTBEAT (PX4's mode layout whatever it announces), and ignores
    commands and set-points addressed to another system (counted in ``wrong_target``)."""

    PARAMS = {"COM_OF_LOSS_T": 0.5, "COM_OBL_RC_ACT": 5.0}
    """The parameters it answers PARAM_REQUEST_READ for (as REAL32); ``params`` overrides."""

    def __init__(self, rate_hz=250, mass_scale=1.0, ignore_disarm=0, answer_timesync=True, params=None,
                 system_id=1, autopilot=mavlink2.MAV_AUTOPILOT_PX4):
        self.system_id = system_id
        self.autopilot = autopilot
        self.wrong_target = 0
        self.dt = 1.0 / rate_hz
        self.model = QuadrotorModel.from_vehicle(replace(VEHICLE, mass_kg=VEHICLE.mass_kg * mass_scale))
        self.ignore_disarm = ignore_disarm
        self.answer_timesync = answer_timesync
        self.outbox = []
        self.heartbeat_due = False
        self.acks = []
        self.x = np.zeros(12)
        self.t_ms = 0
        self.armed = False
        self.main = PX4_MAIN_AUTO
        self.sub = PX4_SUB_LOITER
        self.controls = np.zeros(4)
        self.stream_since = None
        self.last_target_ms = None
        self.mixer = Mixer.from_vehicle(VEHICLE)
        self.params = dict(self.PARAMS if params is None else params)

    def heartbeat(self):
        base = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
            mavlink2.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        return wire(mavlink2.MAVLink_heartbeat_message(
            2, self.autopilot, base, (self.main << 16) | (self.sub << 24), 4, 3), sysid=self.system_id)

    def receive(self, msg):
        t = msg.get_type()
        if getattr(msg, "target_system", 0) not in (0, self.system_id):
            self.wrong_target += 1
            return
        if t == "SET_ACTUATOR_CONTROL_TARGET":
            assert all(np.isfinite(msg.controls))
            if self.stream_since is None:
                self.stream_since = self.t_ms
            self.last_target_ms = self.t_ms
            self.controls = np.array(msg.controls[:4])
        elif t == "COMMAND_LONG" and msg.command == 400:
            if msg.param1 == 0.0 and self.ignore_disarm > 0:
                self.ignore_disarm -= 1
                return
            on_ground = self.x[2] >= 0.0
            if msg.param1 == 0.0 and not on_ground and msg.param2 != 21196:
                return
            was = self.armed
            self.armed = msg.param1 == 1.0
            self.heartbeat_due = was != self.armed
            if not self.armed:
                self.main, self.sub = PX4_MAIN_AUTO, PX4_SUB_LOITER
        elif t == "TIMESYNC" and msg.tc1 == 0 and self.answer_timesync:
            self.outbox.append(wire(mavlink2.MAVLink_timesync_message(self.t_ms * 1_000_000, msg.ts1),
                                    sysid=self.system_id))
        elif t == "PARAM_REQUEST_READ":
            name = msg.param_id.decode() if isinstance(msg.param_id, bytes) else msg.param_id
            name = name.split("\0", 1)[0]
            if name in self.params:
                self.outbox.append(wire(mavlink2.MAVLink_param_value_message(
                    name.encode(), float(self.params[name]), mavlink2.MAV_PARAM_TYPE_REAL32,
                    len(self.params), list(self.params).index(name)), sysid=self.system_id))
        elif t == "COMMAND_LONG" and msg.command == 176:
            if self.stream_since is not None and self.t_ms - self.stream_since >= 500:
                self.main, self.sub = PX4_MAIN_OFFBOARD, 0

    def telemetry(self):
        q = rpy_to_quat(*self.x[3:6])
        v_ned = rpy_to_matrix(*self.x[3:6]) @ self.x[6:9]
        r = self.x[9:12]
        return [
            wire(mavlink2.MAVLink_attitude_quaternion_message(self.t_ms, *q, *r), sysid=self.system_id),
            wire(mavlink2.MAVLink_local_position_ned_message(self.t_ms, *self.x[:3], *v_ned), sysid=self.system_id),
        ]

    def physics(self):
        self.t_ms += int(round(self.dt * 1000))
        if not (self.armed and self.main == PX4_MAIN_OFFBOARD):
            return
        forces = self.controls * VEHICLE.max_rotor_thrust_n
        u = self.mixer.to_wrench(forces)
        f = lambda xx: self.model.f(xx, u)  # noqa: E731
        dt = self.dt
        k1 = f(self.x); k2 = f(self.x + dt / 2 * k1); k3 = f(self.x + dt / 2 * k2); k4 = f(self.x + dt * k3)
        self.x = self.x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if self.x[2] > 0.0:  # ground
            self.x[2] = 0.0
            self.x[3:5] = 0.0
            self.x[6:12] = 0.0


def make_supervisor(plan=None, regulator=None, envelope=None, link_health=None, **kw):
    params = SupervisorParams(**kw)
    made = []

    def factory(p, rotor_lag):
        assert rotor_lag is sup.forecaster.rotor_lag       # the flight's one answer, not a copy
        reg = regulator if regulator is not None else FakeRegulator(p)
        made.append(reg)
        return reg

    sup = Supervisor(VEHICLE, params, factory, envelope=envelope, link_health=link_health)
    sup.regulators = made
    if plan is not None:
        sup.offer_plan(plan, 0.0)
    return sup


def run(sup, veh, seconds, on_step=None, clock=None):
    """Drive supervisor and vehicle in lockstep; the injected clock follows vehicle time, or
    ``clock(veh)`` (a vehicle whose clock goes back, e.g. a reboot)."""
    events, logs, sent = [], [], []
    for _ in range(int(round(seconds / veh.dt))):
        now = veh.t_ms / 1000.0 if clock is None else clock(veh)
        due = veh.t_ms % 1000 == 0 or veh.heartbeat_due
        veh.heartbeat_due = False
        msgs = ([veh.heartbeat()] if due else []) + veh.outbox + veh.telemetry()
        veh.outbox = []
        if on_step is not None:
            msgs = on_step(veh, msgs)
        for m in msgs:
            out = sup.handle(m, now)
            events += out.events
            if out.log is not None:
                logs.append(out.log)
            for o in out.messages:
                sent.append((veh.t_ms, o))
                veh.receive(wire(o, 1, 191))
        out = sup.tick(now)
        events += out.events
        veh.physics()
        if sup.finished:
            break
    return events, logs, sent

