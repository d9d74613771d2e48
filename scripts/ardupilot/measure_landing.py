#!/usr/bin/env python3
"""How a body-rate-and-thrust flight of a stock ArduCopter SITL can end on the ground.

Three take-offs to 2 m and landings (descent at 0.5 m/s by thrust, GUIDED), each ending
differently after touchdown:

- ``zero``: thrust 0 at once; wait for the land detector (EXTENDED_SYS_STATE ON_GROUND),
  then ARM_DISARM 0;
- ``low_then_zero``: thrust 0.02 for 3 s, then 0 for 8 s; then ARM_DISARM 0;
- ``low_then_land_mode``: thrust 0.02 for 3 s, then DO_SET_MODE LAND (mode 9) and no more
  set-points; how long until ArduCopter disarms by itself.

Test setup only: GUID_OPTIONS = 8. Prints one JSON document. Uses the Flight helper of
``measure_flight.py``.

    python scripts/ardupilot/measure_landing.py [--slow-take-off]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from measure_flight import GUIDED, LAND, M, Flight, arm  # noqa: E402
from measure_flight import ArduPilotSitl  # noqa: E402

ON_GROUND = M.MAV_LANDED_STATE_ON_GROUND


def take_off(f: Flight, z_ground: float, height_m: float = 2.0) -> None:
    if f.mode != GUIDED:
        f.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED)
    if not f.armed:
        arm(f)
    f.hover = 0.118
    f.fly(3.0, lambda t: (-4 * f.roll, -4 * f.pitch, 0.0, 0.1 * t), until=lambda: f.z < z_ground - 0.1)
    f.fly(7.0, f.hold(lambda t: z_ground - min(height_m, 0.2 + 0.5 * t)))


def touch_down(f: Flight, z_ground: float) -> float:
    """Descend at 0.5 m/s until on the ground and still; returns the host time of touchdown."""
    z0 = f.z
    f.fly(12.0, f.hold(lambda t: min(z_ground + 0.3, z0 + 0.5 * t)),
          until=lambda: f.z > z_ground - 0.05 and abs(f.vz) < 0.1)
    return f.now()


def wait_state(f: Flight, cond, seconds: float, law=None) -> float | None:
    """Seconds until ``cond()`` holds (None if not within ``seconds``), sending ``law`` if any."""
    t0 = f.now()
    f.fly(seconds, law if law is not None else (lambda t: None), until=cond)
    return round(f.now() - t0, 2) if cond() else None


def slow_take_off(f: Flight, z_ground: float, per_s: float = 0.02) -> dict:
    """DISARM_DELAY 3 s (test setup), then a thrust ramp of ``per_s`` a second from 0: does the
    auto-disarm fire before the vehicle leaves the ground?"""
    f.s.set_param("DISARM_DELAY", 3)
    f.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED)
    arm(f)
    t_arm = f.now()
    seen = {"armed": False}

    def done():                      # the heartbeat (1 Hz) says "armed" only some time after the ACK
        seen["armed"] |= f.armed
        return f.z < z_ground - 0.1 or (seen["armed"] and not f.armed)
    f.fly(12.0, lambda t: (-4 * f.roll, -4 * f.pitch, 0.0, per_s * t), until=done)
    r = {"ramp_per_s": per_s, "armed": f.armed, "after_s": round(f.now() - t_arm, 2),
         "left_ground": f.z < z_ground - 0.1}
    if f.armed:
        f.fly(4.0, f.hold(lambda t: z_ground - 1.0))
        touch_down(f, z_ground)
        f.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, LAND)
        r["land_mode_disarmed_after_s"] = wait_state(f, lambda: not f.armed, 15.0)
    f.s.set_param("DISARM_DELAY", 0)
    return r


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slow-take-off", action="store_true",
                    help="only: does DISARM_DELAY (3 s) disarm during a slow thrust ramp (0.02/s)?")
    args = ap.parse_args()
    res: dict = {}
    rates = {31: 50, 32: 50, 245: 20}
    with ArduPilotSitl(frame="freestyle", params={"GUID_OPTIONS": 8}, rates_hz=rates, timeout_s=120) as s:
        f = Flight(s)
        f.pump(f.now() + 1.0)
        z_ground = f.z
        if args.slow_take_off:
            res["slow_take_off"] = slow_take_off(f, z_ground)
            res["events"] = f.events
            print(json.dumps(res, indent=1, default=float))
            return 0

        take_off(f, z_ground)
        touch_down(f, z_ground)
        zero = (lambda t: (0.0, 0.0, 0.0, 0.0))
        r = {"on_ground_after_s": wait_state(f, lambda: f.landed == ON_GROUND, 10.0, zero)}
        r["disarm_ack"] = f.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        r["disarmed_after_s"] = wait_state(f, lambda: not f.armed, 3.0, zero)
        res["zero"] = r

        take_off(f, z_ground)
        touch_down(f, z_ground)
        low = (lambda t: (0.0, 0.0, 0.0, 0.02))
        r = {"on_ground_within_3s_at_0.02": wait_state(f, lambda: f.landed == ON_GROUND, 3.0, low)}
        r["on_ground_after_s_at_0"] = wait_state(f, lambda: f.landed == ON_GROUND, 8.0, zero)
        r["disarm_ack"] = f.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        r["disarmed_after_s"] = wait_state(f, lambda: not f.armed, 3.0, zero)
        if f.armed:
            r["land_mode_ack"] = f.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, LAND)
            r["then_land_mode_disarmed_after_s"] = wait_state(f, lambda: not f.armed, 15.0)
        res["low_then_zero"] = r

        take_off(f, z_ground)
        touch_down(f, z_ground)
        r = {"on_ground_within_3s_at_0.02": wait_state(f, lambda: f.landed == ON_GROUND, 3.0, low)}
        r["land_mode_ack"] = f.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, LAND)
        r["disarmed_after_s"] = wait_state(f, lambda: not f.armed, 15.0)
        r["mode_after"] = f.mode
        res["low_then_land_mode"] = r
        res["events"] = f.events
    print(json.dumps(res, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
