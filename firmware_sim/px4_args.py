"""The command-line options of the PX4-facing side (:mod:`firmware_sim.px4`): who the vehicle
is on the link and whom it sends to, what a ground station sees, and the rate mode
(:mod:`firmware_sim.rate_loop`)."""
from __future__ import annotations

import argparse
import dataclasses

from .argtypes import add_deprecated_alias, checked, float_within, probability, sysid
from .autopilot import AUTOPILOTS
from .link import parse_remote_url
from .px4 import PARAMS, Px4Config, Px4Services
from .rate_loop import RateLoopConfig

__all__ = ["add_identity_args", "add_px4_args", "px4_services", "parse_home", "rate_loop_config",
           "print_rate_response"]

MAX_RATE_LATENCY_S = 0.1


def parse_home(text: str) -> tuple[float, float, float]:
    """``LAT,LON,ALT`` (degrees, degrees, m AMSL) -> a tuple. Raises ValueError."""
    parts = text.split(",")
    if len(parts) != 3:
        raise ValueError(f"--home {text!r}: expected LAT,LON,ALT (degrees, degrees, m AMSL)")
    try:
        lat, lon, alt = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"--home {text!r}: LAT, LON and ALT must be numbers") from None
    if not (-85.0 <= lat <= 85.0 and -180.0 <= lon <= 180.0 and -500.0 <= alt <= 10000.0):
        raise ValueError(f"--home {text!r}: LAT in -85..85, LON in -180..180, ALT in -500..10000 m")
    return lat, lon, alt


def _home_type(text: str):
    try:
        return parse_home(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_identity_args(p: argparse.ArgumentParser) -> None:
    """``--vehicle-system-id``, ``--autopilot``, ``--remote``, ``--peer-system-id``: who the
    vehicle is on the link, what it announces, whom it sends to and takes commands from."""
    a = p.add_argument
    add_deprecated_alias(p, "--system-id", a(
        "--vehicle-system-id", dest="system_id", type=sysid, default=1, metavar="N",
        help="the vehicle's (our) MAVLink system id, 1..255, as PX4's MAV_SYS_ID; commands are taken "
        "from it (the daemon flies with the vehicle's id) and any --peer-system-id (default 1)"))
    a("--autopilot", choices=AUTOPILOTS, default="px4",
      help="the autopilot its HEARTBEAT announces: 'px4' (MAV_AUTOPILOT_PX4, 12) or 'generic' "
      "(MAV_AUTOPILOT_GENERIC, 0: custom firmware); it speaks PX4's modes either way (default %(default)s)")
    a("--remote", default=None, metavar="URL", type=checked(parse_remote_url, "URL"),
      help="udpout:HOST:PORT: also send everything there from the start, before hearing from it, "
      "as PX4 SITL sends to an offboard computer's port (which listens: mavreg's udpin:HOST:PORT "
      "vehicle URL). Default: send only to the peers heard")
    a("--peer-system-id", dest="peer_system_ids", type=sysid, action="append", default=[],
      metavar="N", help="also take commands from system N (repeatable; a ground station, e.g. 255 "
      "QGroundControl/MAVProxy, 245 MAVSDK), once it has sent a HEARTBEAT. Default: only our own "
      "system id, which the daemon uses")
    a("--gcs-system-id", dest="peer_system_ids", type=sysid, action="append", help=argparse.SUPPRESS)


def add_px4_args(p: argparse.ArgumentParser) -> None:
    """``--home`` (docs/firmware_sim.md, 'Talking to it like a PX4 vehicle')."""
    g = p.add_argument_group("PX4 vehicle", "what a ground station or MAVSDK sees (docs/firmware_sim.md)")
    g.add_argument("--home", type=_home_type, default=None, metavar="LAT,LON,ALT",
                   help="where the local NED origin is on earth, degrees and m AMSL (default "
                   "PX4 SITL's home, 47.397742,8.545594,488); GLOBAL_POSITION_INT and "
                   "HOME_POSITION are converted around it")
    r = p.add_argument_group("rate mode", "SET_ATTITUDE_TARGET body rates and thrust in OFFBOARD "
                             "(docs/firmware_sim.md, 'Rate mode, as PX4 OFFBOARD')")
    add_deprecated_alias(r, "--rate-latency-ms", r.add_argument(
        "--rate-latency-s", type=float_within(0.0, MAX_RATE_LATENCY_S, "s"), default=None, metavar="S",
        help="from the receipt of a rate set-point to the rate loop that uses it, 0..0.1 s "
        f"(default {RateLoopConfig.latency_s:g})"), scale="1e-3", unit="s")
    r.add_argument("--thr-mdl-fac", type=probability, default=None, metavar="E",
                   help="thrust model: collective t gives F = 4 f_max ((1 - E) t + E t^2), E in 0..1 "
                   f"(parameter THR_MDL_FAC; default {RateLoopConfig.thr_mdl_fac:g})")
    r.add_argument("--rate-param", action="append", default=[], type=_rate_param, metavar="NAME=VALUE",
                   help="a rate loop parameter at start, as a PARAM_SET would set it (repeatable): "
                   "MC_ROLLRATE_P, _I, _D, _FF (PITCH, YAW too), MC_RR_INT_LIM (PR, YR), IMU_GYRO_CUTOFF, "
                   "IMU_DGYRO_CUTOFF, THR_MDL_FAC; e.g. a stock PX4's gains (docs/firmware_sim.md, 'PX4's "
                   "SIH quadrotor')")
    r.add_argument("--print-rate-response", action="store_true",
                   help="print the true rate-mode figures and exit: the thrust map and the hover "
                   "collective (MPC_THR_HOVER), then for roll, pitch (1 rad/s steps) and yaw (0.1 rad/s) "
                   "the closed-loop step response of the true airframe in the chosen world, from the "
                   "receipt of the set-point: 10/50/90 %% times, overshoot, final value and a "
                   "first-order-plus-delay fit (tau, delay). Nothing is listened on")


def _rate_param(text: str) -> tuple[str, float]:
    """``NAME=VALUE`` of a rate loop parameter (:data:`firmware_sim.px4.PARAMS`, ``rates.``) ->
    ``(RateLoopConfig field, value)``, within the parameter's bounds."""
    name, _, value = text.partition("=")
    params = {p.name: p for p in PARAMS if p.attribute.startswith("rates.")}
    p = params.get(name.strip())
    if p is None:
        raise argparse.ArgumentTypeError(f"{name.strip()!r} is not a rate loop parameter: one of "
                                         f"{', '.join(sorted(params))}")
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: want NAME=VALUE with a number") from None
    if not p.low <= v <= p.high:
        raise argparse.ArgumentTypeError(f"{p.name} {v:g} out of [{p.low:g}, {p.high:g}]")
    return p.attribute[len("rates."):], v


def rate_loop_config(args) -> RateLoopConfig:
    """The rate loop's settings of the parsed arguments (the defaults for the others):
    ``--rate-param`` in order, then ``--rate-latency-s`` and ``--thr-mdl-fac``."""
    changes = dict(getattr(args, "rate_param", None) or ())
    if getattr(args, "rate_latency_s", None) is not None:
        changes["latency_s"] = args.rate_latency_s
    if getattr(args, "thr_mdl_fac", None) is not None:
        changes["thr_mdl_fac"] = args.thr_mdl_fac
    return dataclasses.replace(RateLoopConfig(), **changes)


def print_rate_response(args, world, nominal, params, max_rotor_thrust_n: float) -> None:
    """``--print-rate-response``: print :func:`firmware_sim.rate_response.describe_rate_mode`."""
    from .rate_response import describe_rate_mode
    for line in describe_rate_mode(params, world, rate_loop_config(args), nominal, max_rotor_thrust_n):
        print(f"firmware_sim {line}", flush=True)


def px4_services(args) -> Px4Services:
    """The services of the parsed arguments."""
    home = getattr(args, "home", None)
    cfg = Px4Config() if home is None else Px4Config(*home)
    return Px4Services(cfg, args.rate_hz)
