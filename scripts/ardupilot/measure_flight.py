#!/usr/bin/env python3
"""Fly a stock ArduCopter SITL by body rates and thrust, and measure what mavreg relies on.

One session, in order: GUIDED by DO_SET_MODE; arming (time to acceptance, STATUSTEXTs);
auto-disarm on the ground with zero thrust (DISARM_DELAY set to 3 s for this check only);
take-off by SET_ATTITUDE_TARGET type_mask 128 with the thrust ramped from 0 (no
NAV_TAKEOFF); hover thrust; 30 deg/s roll-rate steps seen from the host; what happens when
set-points stop (GUID_TIMEOUT); landing with low thrust (land detector, disarm); an
ordinary and a forced disarm in flight. Test setup only: GUID_OPTIONS = 8 (thrust is a
thrust). Prints one JSON document. Needs the SITL (see ``harness/ardupilot_sitl.py``).

    python scripts/ardupilot/measure_flight.py [--frame freestyle] [--steps 6]
"""
from __future__ import annotations

import argparse
import json
import math
import struct
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from harness.ardupilot_sitl import ArduPilotSitl, SitlError  # noqa: E402
from pymavlink import mavutil  # noqa: E402

M = mavutil.mavlink
G = 9.80665
GUIDED, LAND = 4, 9


class Flight:
    """Latest vehicle state, a command stream at 100 Hz, and logs of both."""

    def __init__(self, sitl: ArduPilotSitl):
        self.s = sitl
        self.roll = self.pitch = 0.0
        self.z = self.vz = 0.0
        self.p = 0.0
        self.armed = False
        self.mode = -1
        self.landed = 0
        self.hover = 0.125
        self.att_log: list = []      # (host s, time_boot_ms, rollspeed)
        self.pos_log: list = []      # (host s, time_boot_ms, z)
        self.cmd_log: list = []      # (host s, p cmd, thrust)
        self.events: list = []
        self.timesync_requests = 0
        self.recording: list | None = None
        """(wall time s, raw bytes) of every message while not None (for a .tlog)."""

    def now(self) -> float:
        return self.s.elapsed_s()

    def note(self, what: str) -> None:
        self.events.append(f"{self.now():.2f} {what}")

    def pump(self, until: float) -> None:
        while self.now() < until:
            m = self.s.recv(max(0.0, min(0.01, until - self.now())))
            if m is None:
                continue
            t = m.get_type()
            if self.recording is not None and t in ("ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", "HEARTBEAT",
                                                    "EXTENDED_SYS_STATE"):
                self.recording.append((time.time(), bytes(m.get_msgbuf())))
            if t == "ATTITUDE_QUATERNION":
                w, x, y, z = m.q1, m.q2, m.q3, m.q4
                self.roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
                self.pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
                self.p = m.rollspeed
                self.att_log.append((self.now(), m.time_boot_ms, m.rollspeed))
            elif t == "LOCAL_POSITION_NED":
                self.z, self.vz = m.z, m.vz
                self.pos_log.append((self.now(), m.time_boot_ms, m.z))
            elif t == "HEARTBEAT" and m.get_srcComponent() == self.s.compid:
                armed = bool(m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
                if armed != self.armed or m.custom_mode != self.mode:
                    self.note(f"heartbeat armed={armed} custom_mode={m.custom_mode}")
                self.armed, self.mode = armed, m.custom_mode
            elif t == "EXTENDED_SYS_STATE":
                if m.landed_state != self.landed:
                    self.note(f"landed_state {self.landed} -> {m.landed_state}")
                self.landed = m.landed_state
            elif t == "STATUSTEXT":
                self.note(f"STATUSTEXT {m.text}")
            elif t == "TIMESYNC" and m.tc1 == 0:
                self.timesync_requests += 1

    def send(self, p: float, q: float, r: float, thrust: float) -> None:
        self.s.conn.mav.set_attitude_target_send(int(self.now() * 1000), self.s.sysid, self.s.compid, 128,
                                                 [1, 0, 0, 0], p, q, r, thrust)
        self.cmd_log.append((self.now(), p, thrust))

    def fly(self, seconds: float, law, period_s: float = 0.01, until=None) -> None:
        """Send ``law(t) -> (p, q, r, thrust) or None`` every period for ``seconds`` (or until
        ``until()`` holds)."""
        t0 = self.now()
        while self.now() - t0 < seconds and not (until is not None and until()):
            tick = self.now()
            cmd = law(tick - t0)
            if cmd is not None:
                self.send(*cmd)
            self.pump(tick + period_s)

    def hold(self, z_ref, level: bool = True, p_override=None):
        """A law: altitude by thrust (PD on the upward acceleration, slow integral on the hover
        thrust estimate), level by rates. ``z_ref`` is a number or a function of time (NED, m)."""
        ref = z_ref if callable(z_ref) else (lambda t: z_ref)

        def law(t):
            err = self.z - ref(t)                              # > 0: too low (NED)
            acc = 1.5 * err + 2.0 * self.vz                    # m/s^2 upward wanted
            self.hover = min(0.3, max(0.05, self.hover + 0.0002 * err))
            thrust = min(1.8 * self.hover, max(0.5 * self.hover, self.hover * (1 + acc / G)))
            p = -4.0 * self.roll if p_override is None else p_override(t)
            return (p, -4.0 * self.pitch if level else 0.0, 0.0, thrust)
        return law

    def hover_stats(self, seconds: float) -> dict:
        """Mean commanded thrust and the telemetry rates over the last ``seconds``."""
        t_end = self.now()
        cmds = np.array([c[2] for c in self.cmd_log if c[0] >= t_end - seconds])
        att = [a for a in self.att_log if a[0] >= t_end - seconds]
        pos = [p for p in self.pos_log if p[0] >= t_end - seconds]
        pos_t = {int(p[1]) for p in pos}
        return {"thrust_mean": float(cmds.mean()), "thrust_std": float(cmds.std()),
                "att_hz": len(att) / seconds, "pos_hz": len(pos) / seconds,
                "att_with_equal_time_pos": sum(int(a[1]) in pos_t for a in att)}

    def command(self, cmd: int, *params: float):
        ack = self.s.command_long(cmd, *params)
        self.note(f"COMMAND_ACK {cmd} result={ack.result}")
        return int(ack.result)


def arm(f: Flight, limit_s: float = 60.0) -> float:
    t0 = f.now()
    while f.now() - t0 < limit_s:
        if f.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED:
            f.pump(f.now() + 0.3)
            return f.now() - t0
        f.pump(f.now() + 1.0)
    raise SitlError("not armed")


def stop_setpoints(f: Flight, fraction_of_hover: float, seconds: float) -> list:
    """Send 0.3 s of zero rates at ``fraction_of_hover`` times the hover thrust, then nothing:
    (t, height gained, climb rate, mode, armed) every 0.25 s."""
    thrust = fraction_of_hover * f.hover
    f.fly(0.3, lambda t: (0.0, 0.0, 0.0, thrust))
    z0, t0 = f.z, f.now()
    trace = []
    while f.now() - t0 < seconds:
        f.pump(f.now() + 0.25)
        trace.append((round(f.now() - t0, 2), round(z0 - f.z, 2), round(-f.vz, 2), f.mode, f.armed))
    return trace


def crossings(t_cmd: float, log: np.ndarray, target: float, base: float) -> list:
    """Host times (ms after t_cmd) at which the rate first passes 10/50/90 % of the step."""
    out = []
    for frac in (0.1, 0.5, 0.9):
        level = base + frac * (target - base)
        idx = np.nonzero((log[:, 0] >= t_cmd) & (log[:, 2] >= level))[0]
        out.append(round(1000 * (log[idx[0], 0] - t_cmd), 1) if idx.size else None)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frame", default="freestyle")
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--tlog", help="write 2 s of the 100 Hz hover's telemetry to this .tlog")
    args = ap.parse_args()
    res: dict = {}
    rates = {31: 200, 32: 200, 108: 50, 245: 10}
    with ArduPilotSitl(frame=args.frame, params={"GUID_OPTIONS": 8}, rates_hz=rates, timeout_s=120) as s:
        f = Flight(s)
        res["ready_s"] = round(f.now(), 1)
        res["guided_ack"] = f.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED)
        f.pump(f.now() + 1.5)
        res["mode_after"] = f.mode
        res["arm_after_s"] = round(arm(f), 2)

        # auto-disarm on the ground: zero thrust, DISARM_DELAY 3 s (the frame's own value is 0)
        s.set_param("DISARM_DELAY", 3)
        f.fly(6.0, lambda t: (0.0, 0.0, 0.0, 0.0))
        res["armed_after_6s_zero_thrust_disarm_delay_3"] = f.armed
        s.set_param("DISARM_DELAY", 0)
        if not f.armed:
            arm(f)
        f.fly(5.0, lambda t: (0.0, 0.0, 0.0, 0.0))
        res["armed_after_5s_zero_thrust_disarm_delay_0"] = f.armed

        # take-off by thrust ramp from 0 (0.1 per second) until the vehicle climbs
        z_ground = f.z
        t_ramp = f.now()
        lift: dict = {}

        def ramp(t):
            if not lift and (f.z < z_ground - 0.1 or f.vz < -0.2):
                lift.update(t_s=round(t, 2), thrust=round(0.1 * t, 4), landed_state=f.landed)
            return (-4 * f.roll, -4 * f.pitch, 0.0, 0.1 * t)
        f.fly(3.0, ramp, until=lambda: bool(lift))
        f.cmd_log.append((f.now(), 0.0, lift.get("thrust", 0.125)))
        f.hover = lift.get("thrust", 0.125)
        res["takeoff"] = {"ground_z": z_ground, "ramp_start_s": round(t_ramp, 1), "liftoff": lift}
        f.fly(10.0, f.hold(lambda t: z_ground - min(3.0, 0.2 + 0.5 * t)))
        res["hover_200hz"] = dict(f.hover_stats(4.0), z=f.z, hover_estimate=f.hover)

        # roll-rate steps, 30 deg/s for 0.25 s then -30 deg/s for 0.25 s, from level hover
        step = math.radians(30.0)
        results = []
        for _ in range(args.steps):
            f.fly(1.5, f.hold(z_ground - 3.0))
            base = f.p
            t_cmd = f.now()
            f.fly(0.25, f.hold(z_ground - 3.0, p_override=lambda t: step))
            f.fly(0.25, f.hold(z_ground - 3.0, p_override=lambda t: -step))
            log = np.array(f.att_log)
            log = log[log[:, 0] >= t_cmd - 0.05]
            peak = float(log[(log[:, 0] >= t_cmd) & (log[:, 0] <= t_cmd + 0.25), 2].max())
            results.append({"ms_10_50_90": crossings(t_cmd, log, step, base),
                            "peak_deg_s": round(math.degrees(peak), 1)})
        ok = [r["ms_10_50_90"] for r in results if None not in r["ms_10_50_90"]]
        res["roll_steps"] = {"each": results,
                             "median_ms_10_50_90": np.median(np.array(ok), axis=0).tolist() if ok else None}

        # telemetry at 100 Hz in flight
        for i in (31, 32):
            s.set_rate(i, 100)
        f.fly(3.0, f.hold(z_ground - 3.0))
        f.recording = []
        f.fly(2.0, f.hold(z_ground - 3.0))
        if args.tlog:
            with open(args.tlog, "wb") as out:
                for t, buf in f.recording:
                    out.write(struct.pack(">Q", int(t * 1e6)) + buf)
        f.recording = None
        res["hover_100hz"] = dict(f.hover_stats(4.0), z=f.z, hover_estimate=f.hover)

        # set-points stop: the default GUID_TIMEOUT (3 s) at 5 m, the last thrust 5 % below hover
        f.fly(6.0, f.hold(lambda t: z_ground - min(5.0, 3.0 + 0.5 * t)))
        res["no_setpoints_guid_timeout_3_last_0.95_hover"] = stop_setpoints(f, 0.95, 6.0)
        f.fly(6.0, f.hold(lambda t: z_ground - min(3.0, 1.0 + 0.5 * t)))
        # GUID_TIMEOUT 1 s (test setup), the last thrust 10 % below hover
        s.set_param("GUID_TIMEOUT", 1.0)
        res["no_setpoints_guid_timeout_1_trace_t_rise_climbrate_mode_armed"] = stop_setpoints(f, 0.9, 4.0)
        f.fly(4.0, f.hold(z_ground - 3.0))

        # ordinary disarm in flight (ACK only)
        res["disarm_in_flight_ack"] = f.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        f.fly(0.5, f.hold(z_ground - 3.0))
        res["armed_after_disarm_in_flight"] = f.armed

        # landing: descend at 0.5 m/s to the ground, then thrust 0 on the ground
        z_start, t_land = f.z, f.now()
        f.fly(8.0, f.hold(lambda t: min(z_ground + 0.3, z_start + 0.5 * t)))
        res["landing"] = {"height_m": round(z_ground - f.z, 2), "landed_state_on_ground": f.landed,
                          "armed": f.armed}
        f.fly(5.0, lambda t: (0.0, 0.0, 0.0, 0.02))
        res["landing"]["landed_state_after_5s_thrust_0.02"] = f.landed
        res["landing"]["disarm_ack_at_thrust_0.02"] = f.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        f.fly(0.5, lambda t: (0.0, 0.0, 0.0, 0.02))
        t_zero = f.now()
        f.fly(8.0, lambda t: (0.0, 0.0, 0.0, 0.0))
        res["landing"]["armed_after_8s_zero_thrust"] = f.armed
        res["landing"]["landed_state_after"] = f.landed
        res["landing"]["zero_thrust_from_s"] = round(t_zero, 2)
        res["landing"]["descent_from_s"] = round(t_land, 2)
        if f.armed:
            res["landing"]["disarm_ack_on_ground"] = f.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
            f.pump(f.now() + 1.5)
            res["landing"]["armed_after_disarm"] = f.armed

        # forced disarm in flight at about 1.5 m
        if not f.armed:
            arm(f)
        lift.clear()
        f.fly(3.0, ramp, until=lambda: bool(lift))
        f.fly(4.0, f.hold(lambda t: z_ground - min(1.5, 0.2 + 0.5 * t)))
        res["forced_disarm_height_m"] = z_ground - f.z
        res["forced_disarm_ack"] = f.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196)
        f.pump(f.now() + 2.0)
        res["armed_after_forced"] = f.armed

        att = np.array(f.att_log)
        pos_t = {int(r[1]) for r in f.pos_log}
        res["flight_pairing_same_time_boot_ms"] = [int(sum(int(a) in pos_t for a in att[:, 1])), len(att),
                                                   len(f.pos_log)]
        lone = [round(a[0], 2) for a in att if int(a[1]) not in pos_t]
        spans, start = [], None
        for i, t in enumerate(lone):
            start = t if start is None else start
            if i + 1 == len(lone) or lone[i + 1] - t > 0.1:
                spans.append((start, t))
                start = None
        res["attitudes_without_position_spans_s"] = spans[:20]
        res["vehicle_timesync_requests"] = f.timesync_requests
        res["events"] = f.events
    print(json.dumps(res, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
