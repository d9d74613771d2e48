"""``firmware-sim`` / ``python -m firmware_sim``: the emulator on its own."""
from __future__ import annotations

import argparse
import dataclasses
import os
import signal
import sys
import textwrap

from .argtypes import (add_deprecated_alias, checked, float_within, input_file, nonneg_float, nonneg_int,
                       output_file, positive_float, positive_int, probability, unit_scale)
from .autopilot import AUTOPILOTS, Autopilot, AutopilotConfig
from .clock import StopRun, run_lockstep, run_realtime
from .engine import Engine
from .link import LISTEN_FORMS, open_link, parse_listen_url, parse_remote_url
from mavreg.transport.signing import Signing
from .mismatch import airframe_arrays, airframe_meta, apply_mismatch, describe_airframe, draw_mismatch
from mavreg.config.vehicle import EmulatorParams, load_vehicle

from .params import START_KEYS, build_sim_params, default_vehicle_path, parse_start
from .physics import G
from .recorder import Recorder
from .sim import Simulation
from .stabilizer import Stabilizer
from .status import ExitCode, SimStop
from .wind import Wind, WindItem, parse_wind
from .faults import link_faults_from_args
from .px4_args import add_identity_args, add_px4_args, print_rate_response, px4_services, rate_loop_config
from .reboot import Reboots, add_reboot_args
from .world import MAX_DELAY_S, PRESET_NAMES, PRESETS, build_world

__all__ = ["main", "build_parser", "build_engine", "BadInput"]


class BadInput(ValueError):
    """A bad flag value or vehicle file, found while the run is built: one line, exit 2.

    Any other exception while building or running is a bug (a traceback, exit 1)."""

DESCRIPTION = """\
A software-in-the-loop quadrotor that speaks MAVLink 2 over UDP, a pseudo-terminal, a serial
port or TCP (--listen): quaternion rigid body
with the full inertia matrix (RK4), rotor lag, noise, saturation, drag, wind, ground
contact, and a small autopilot (arming, HOLD/LAND/OFFBOARD modes, offboard-loss
failsafe). SET_ACTUATOR_CONTROL_TARGET group 0 is a pass-through mixer: controls[0..3]
are rotors 1..4 (front, right, back, left) as a fraction of the maximum rotor thrust;
SET_ATTITUDE_TARGET with type_mask 128 gives body rates (rad/s) and a collective thrust
(0..1), flown by its PX4-like rate loop (--print-rate-response shows its true response).

By default the world is realistic: the telemetry is a state estimate, late and noisy,
sent over a link with delay, jitter and loss, and commands arrive late (all in sim time,
seeded by --seed, deterministic in lockstep). --world ideal sends the exact true state
with no delay and no loss. Motor lag and rotor noise come from the vehicle YAML in both.

The first stdout line is 'firmware_sim listening on URL' (udpin:HOST:PORT with the real port,
serial:/dev/pts/N for --listen pty, tcpin:HOST:PORT); the second one
('firmware_sim world: ...') names the world, its values and any overrides; with
--mismatch-seed a third one ('firmware_sim airframe: key=value ...') gives the true
airframe drawn around the vehicle file.
Exit status: 0 done or signalled, 1 internal error (a bug: a traceback
and a request to report it), 2 bad input (a flag, a file; checked before the run), 3 crash,
4 non-finite state, 5 speed or body rate limit. See docs/firmware_sim.md."""


def _presets_epilog() -> str:
    lines = ["worlds (--world):"]
    for name in PRESET_NAMES:
        text = PRESETS[name].describe(EmulatorParams()).replace("world: preset ", "", 1)
        lines.extend(textwrap.wrap(text, 88, initial_indent="  ", subsequent_indent="      "))
    lines.extend(textwrap.wrap(
        "Delays are uniform in [delay - jitter, delay + jitter]. Telemetry is released at "
        "control-period boundaries (every 2 ms at 500 Hz), commands act at the physics step "
        "where they fall due (1 ms at 1 kHz). In lockstep the loop waits for a target only "
        "in a period that released a complete sample (ATTITUDE_QUATERNION and "
        "LOCAL_POSITION_NED of one time) to the peers. The airframe values shown for a "
        "default vehicle file; 'ideal' keeps the vehicle file's drag and thrust scale.", 88))
    return "\n".join(lines)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):        # one line, exit 2
        self.exit(int(ExitCode.USAGE), f"firmware-sim: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="firmware-sim", description=DESCRIPTION, epilog=_presets_epilog(),
                formatter_class=argparse.RawDescriptionHelpFormatter)
    a = p.add_argument
    a("--listen", default="udpin:127.0.0.1:14540", metavar="URL", type=checked(parse_listen_url, "URL"),
      help=f"where to listen: {LISTEN_FORMS}. udpin: port 0 picks a free port; pty: a new "
           "pseudo-terminal, announced as serial:/dev/pts/N (a flight controller's TELEM port); "
           "serial: an existing device (baud 921600 if left out); tcpin: one TCP client at a time, "
           "port 0 a free one (default %(default)s)")
    # Old spellings (--vehicle, --rate-hz, --lockstep-timeout, --lockstep-stall-speed,
    # --offboard-loss-timeout, --preset, the delays' -ms and --rate-latency-ms)
    # are hidden aliases for one release; the dest names are kept (docs/cli.md).
    add_deprecated_alias(p, "--vehicle", a(
        "--vehicle-params", dest="vehicle", default=None, metavar="YAML", type=input_file,
        help="vehicle parameter file (default params/vehicles/mk_quadro.yaml, bundled with mavreg)"))
    add_deprecated_alias(p, "--rate-hz", a(
        "--control-rate-hz", dest="rate_hz", type=positive_int, default=500, metavar="HZ",
        help="control and telemetry rate (default %(default)s)"))
    a("--physics-hz", type=positive_int, default=1000,
      help="RK4 physics rate, an integer multiple of --control-rate-hz (default %(default)s)")
    a("--lockstep", action="store_true", help="advance one control period per offboard target, "
      "SET_ACTUATOR_CONTROL_TARGET or SET_ATTITUDE_TARGET (deterministic) instead of the wall clock")
    add_deprecated_alias(p, "--lockstep-timeout", a(
        "--lockstep-timeout-s", dest="lockstep_timeout", type=positive_float, default=0.1, metavar="S",
        help="wall seconds to wait for a period's command before it counts as lost (default %(default)s)"))
    add_deprecated_alias(p, "--lockstep-stall-speed", a(
        "--lockstep-stall-factor", type=nonneg_float, default=1.0, metavar="X",
        help="while no commands stream in lockstep, run at X times real time; 0 = as fast "
             "as possible (default %(default)s)"))
    a("--seed", type=nonneg_int, default=0, metavar="N", help="seed of the rotor noise and perturbations (default 0)")
    a("--start", default=None, metavar="STATE", type=checked(parse_start, "STATE"),
      help="start in flight, armed and in OFFBOARD, e.g. 'z_m=-5,vy_m_s=8,roll_deg=120'. "
           f"Keys (missing = 0): {', '.join(START_KEYS)}. Position and velocity NED, "
           "attitude ZYX, body rates FRD. Default: on the ground, disarmed, HOLD")
    a("--wind", action="append", default=None, metavar="SPEC", type=checked(parse_wind, "SPEC"),
      help="repeatable: velocity:VN,VE,VD or force:FN,FE,FD (m/s or N, NED), optionally "
           "@T0:T1 for a gust window in sim seconds, e.g. force:0,2,0@3:3.5")
    a("--record", default=None, metavar="FILE.npz", type=output_file,
      help="write the true state and rotor forces of every physics step to FILE.npz")
    add_deprecated_alias(p, "--offboard-loss-timeout", a(
        "--offboard-loss-timeout-s", dest="offboard_loss_timeout", type=positive_float, default=0.25,
        metavar="S", help="sim seconds without a valid offboard target or set-point before the failsafe "
        "(default %(default)s)"))
    a("--failsafe-hold-s", type=nonneg_float, default=1.5, metavar="S",
      help="failsafe: seconds of level/hold-altitude before landing (default %(default)s)")
    add_identity_args(p)
    a("--signing-key", default=None, metavar="FILE",
      help="MAVLink 2 signing: sign every message and take only validly signed ones (FILE: 32 "
      "bytes as 64 hex characters or base64, mode 0600; the timestamp state is kept beside it "
      "in FILE.firmware-sim-state.json). Default: signing off")
    a("--no-timesync", action="store_true",
      help="ignore TIMESYNC requests (a vehicle that does not implement it): the peer cannot measure the link")
    a("--mass-kg", type=positive_float, default=None, help="override the vehicle mass")
    a("--inertia-kg-m2", type=positive_float, nargs=3, default=None, metavar=("JX", "JY", "JZ"),
      help="override the diagonal of the inertia matrix")
    a("--inertia-scale", type=positive_float, default=None, help="multiply the inertia diagonal")
    a("--inertia-perturb-sd-kg-m2", type=nonneg_float, default=None, metavar="SD",
      help="add Gaussian noise of this SD to each principal moment (drawn from --seed)")
    a("--rotor-time-constant-s", type=nonneg_float, default=None, help="override the motor lag")
    a("--rotor-noise-sd-n", type=nonneg_float, default=None, metavar="SD", help="override the thrust noise SD, N")
    a("--angular-drag-n-m-s-per-rad", type=nonneg_float, default=None, metavar="C",
      help="angular damping, a body torque -C omega, 0..10 (PX4 SIH's SIH_KDW, 0.025; default 0)")
    a("--max-rotor-thrust-n", type=positive_float, default=None,
      help="override the rotor saturation and the thrust a control value of 1 asks for")
    a("--rotor-saturation-n", type=positive_float, default=None, metavar="F",
      help="the rotors give at most F N while a control value of 1 still asks for the maximum "
      "rotor thrust: a limit the offboard controller does not know of (the paper's 8.5 N and 7 N runs)")
    a("--duration-s", type=positive_float, default=None, metavar="S",
      help="stop after this much simulation time (default: run until signalled)")
    a("--quiet", action="store_true", help="no status line every second")
    _add_mismatch_args(p)
    _add_world_args(p)
    add_px4_args(p)
    add_reboot_args(p)
    return p


def _add_mismatch_args(p: argparse.ArgumentParser) -> None:
    """``--mismatch-seed``, ``--mismatch-scale`` (:mod:`firmware_sim.mismatch`)."""
    p.add_argument(
        "--mismatch-seed", type=nonneg_int, default=None, metavar="N",
        help="fly a vehicle that is not its file: draw the true mass (+-15 %%), moments of "
             "inertia (+-30 %% each), rotor thrust constants (+-10 %% each), yaw-torque "
             "coefficient (+-30 %%), arm length (+-5 %%), rotor time constant (10-50 ms) and a "
             "centre-of-mass offset (within 1 cm) from seed N, independent of --seed; explicit "
             "--mass-kg, --inertia-*, --rotor-time-constant-s win over the draw. Default: the "
             "file's airframe")
    p.add_argument(
        "--mismatch-scale", type=unit_scale, default=None, metavar="X",
        help="with --mismatch-seed: multiply every deviation from the file by X in (0, 1] "
             "(default 1)")

_delay_s = float_within(0.0, MAX_DELAY_S, "s")      # a delay, a jitter, a latency


def _add_world_args(p: argparse.ArgumentParser) -> None:
    """The world's flags: link, estimator, air and battery (:mod:`firmware_sim.world`)."""
    w = p.add_argument_group("world", "link effects and estimator errors; each flag overrides the preset's value")
    for flag, what in (("--link-faults", "both directions"), ("--uplink-faults", "commands (to the vehicle)"),
                       ("--downlink-faults", "telemetry (from the vehicle)")):
        w.add_argument(flag, action="append", default=[], metavar="SPEC",
                       help=f"link faults of {what} after the preset's link, in simulation time: "
                       "KEY=VALUE[,...], e.g. loss=0.1,jitter_s=0.005,outage=15:0.5 (repeatable; "
                       "docs/reliability.md)")
    w.add_argument("--serial-byte-loss", type=probability, default=0.0, metavar="P",
                   help="a pty, serial or tcpin --listen: each byte lost with probability P, each way "
                   "(seeded by --seed; a UART line that drops bytes)")
    add_deprecated_alias(w, "--preset", w.add_argument(
        "--world", dest="preset", choices=PRESET_NAMES, default="realistic",
        help="named world (default %(default)s; values below)"))
    # The delays were in ms until issue 31; the -ms spellings are aliases for one release that
    # convert exactly (--telemetry-delay-ms 20 is --telemetry-delay-s 0.020, the same double).
    for flag, text in (
            ("--telemetry-delay", "mean delay of the telemetry (vehicle to peers), sim time"),
            ("--telemetry-jitter", "half-width of the uniform telemetry delay spread (<= the delay)"),
            ("--command-delay", "mean delay of commands (peers to vehicle), sim time"),
            ("--command-jitter", "half-width of the uniform command delay spread (<= the delay)")):
        add_deprecated_alias(w, f"{flag}-ms", w.add_argument(
            f"{flag}-s", type=_delay_s, default=None, metavar="S", help=f"{text}, 0..1 s"),
            scale="1e-3", unit="s")
    w.add_argument("--loss", type=probability, default=None, metavar="P",
                   help="probability that a telemetry message or a command datagram is lost (0..1)")
    add_deprecated_alias(w, "--estimate-latency-ms", w.add_argument(
        "--estimate-latency-s", type=_delay_s, default=None, metavar="S",
        help="the telemetry of time t describes the true state of t - S, 0..1 s"), scale="1e-3", unit="s")
    w.add_argument("--estimator-scale", type=nonneg_float, default=None, metavar="X",
                   help="multiply every estimator error SD; 0 turns the errors off (latency kept)")
    w.add_argument("--wind-speed-m-s", type=nonneg_float, default=None, metavar="V",
                   help="steady horizontal wind speed (acts through the drag)")
    w.add_argument("--wind-from-deg", type=float, default=None, metavar="DEG",
                   help="compass direction the steady wind blows from (0 north, 90 east)")
    w.add_argument("--thrust-scale", type=positive_float, default=None, metavar="X",
                   help="thrust the rotors give per unit commanded, 0.5..1.5 (0.9: a sagging battery)")
    w.add_argument("--drag-n-s-per-m", type=nonneg_float, nargs=3, default=None,
                   metavar=("CX", "CY", "CZ"), help="body-frame linear drag coefficients")
    w.add_argument("--parasitic-drag-n-s2-per-m2", type=nonneg_float, nargs=3, default=None,
                   metavar=("CX", "CY", "CZ"), help="body-frame quadratic drag coefficients")


def build_engine(args) -> tuple[Engine, Recorder | None]:
    """Everything the run needs, from parsed arguments. Raises :class:`BadInput` (a
    ValueError) on bad input: a value the validators of the world, the vehicle file, the
    parameters, --start, --wind or --mismatch-* refuse, or a --listen that cannot be bound."""
    try:
        world, vehicle_path, vehicle, nominal, params, start, items = _read_inputs(args)
    except ValueError as exc:     # every ValueError of the validators: ConfigError included
        raise BadInput(str(exc)) from None
    return _assemble(args, world, vehicle_path, vehicle, nominal, params, start, items)


def _read_inputs(args):
    """Validate the flags and the vehicle file (each validator raises ValueError)."""
    vehicle_path = args.vehicle if args.vehicle is not None else default_vehicle_path()
    world = build_world(args.preset, telemetry_delay_s=args.telemetry_delay_s,
                        telemetry_jitter_s=args.telemetry_jitter_s,
                        command_delay_s=args.command_delay_s, command_jitter_s=args.command_jitter_s,
                        loss=args.loss, estimate_latency_s=args.estimate_latency_s,
                        estimator_scale=args.estimator_scale, wind_speed_m_s=args.wind_speed_m_s,
                        wind_from_deg=args.wind_from_deg, thrust_scale=args.thrust_scale,
                        linear_drag_xyz_n_s_per_m=args.drag_n_s_per_m,
                        parasitic_drag_xyz_n_s2_per_m2=args.parasitic_drag_n_s2_per_m2)
    vehicle = load_vehicle(vehicle_path)
    vehicle = dataclasses.replace(vehicle, emulator=world.airframe.apply(vehicle.emulator))
    nominal, params = _sim_params(args, vehicle)
    start = parse_start(args.start) if args.start is not None else None
    items = [parse_wind(w) for w in (args.wind or ())]
    return world, vehicle_path, vehicle, nominal, params, start, items


def _assemble(args, world, vehicle_path, vehicle, nominal, params, start, items):
    """The engine from validated inputs (an exception here is a bug, but for --listen)."""
    command_scale_n = (args.max_rotor_thrust_n if args.max_rotor_thrust_n is not None
                       else vehicle.max_rotor_thrust_n)     # thrust asked for by a control of 1
    if world.airframe.wind_speed_m_s:
        items.append(WindItem("velocity", world.airframe.wind_ned_m_s))
    wind = Wind(items)
    v = params.vehicle
    if wind.has_velocity and not (any(v.emulator.linear_drag_xyz_n_s_per_m)
                                  or any(v.emulator.parasitic_drag_xyz_n_s2_per_m2)):
        print("firmware-sim: warning: wind velocity has no effect with zero drag "
              "(emulator.linear_drag_xyz_n_s_per_m); use force: or a vehicle with drag", file=sys.stderr)
    recorder = Recorder(args.record) if args.record else None
    if recorder is not None:
        recorder.meta.update(vehicle=str(vehicle_path), params=repr(params), seed=args.seed,
                             rate_hz=args.rate_hz, physics_hz=args.physics_hz,
                             lockstep=args.lockstep, start=args.start, wind=args.wind,
                             command_scale_n=command_scale_n,
                             world=dataclasses.asdict(world), airframe=airframe_meta(params))
        recorder.arrays.update(airframe_arrays(params))
    sim = Simulation(params, start, wind, recorder)
    n = nominal.vehicle        # the autopilot is tuned on the file, as the offboard controller
    stab = Stabilizer(n.mass_kg, nominal.inertia_matrix_kg_m2, n.arm_length_m,
                      n.drag_torque_ratio_m, n.max_rotor_thrust_n)
    cfg = AutopilotConfig(system_id=args.system_id, peer_system_ids=tuple(args.peer_system_ids),
                          autopilot=AUTOPILOTS[args.autopilot],
                          answer_timesync=not args.no_timesync,
                          max_rotor_thrust_n=command_scale_n,
                          offboard_loss_timeout_s=args.offboard_loss_timeout,
                          failsafe_hold_s=args.failsafe_hold_s)
    ap = Autopilot(cfg, stab, n.mass_kg * G / 4, px4_services(args), rate_loop_config(args))
    try:     # a bad --signing-key or --*-faults, a --listen that cannot be bound
        signing = Signing(args.signing_key, "firmware-sim") if args.signing_key is not None else None
        faults = link_faults_from_args(args.link_faults, args.uplink_faults, args.downlink_faults, args.seed)
        link = open_link(args.listen, args.system_id, cfg.component_id,
                    peer_system_ids=(args.system_id, *args.peer_system_ids), signing=signing,
                    remote=parse_remote_url(args.remote) if args.remote is not None else None,
                    byte_loss=args.serial_byte_loss, seed=args.seed)
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    engine = Engine(sim, ap, link, world, faults, Reboots(args.reboot_time_s, tuple(args.reboot_at_s)),
                    log=lambda line: print(f"firmware_sim: {line}", file=sys.stderr, flush=True))
    if start is not None:
        link.send(ap.start_in_flight(0.0))
    sim.record_initial(ap.armed, ap.mode)
    return engine, recorder


def _sim_params(args, vehicle):
    """``(nominal, true)`` :class:`SimParams`: the file with the flags, and that with the
    airframe mismatch of ``--mismatch-seed`` (the same object without one)."""
    nominal = build_sim_params(
        vehicle, rate_hz=args.rate_hz, physics_hz=args.physics_hz, seed=args.seed,
        angular_drag_n_m_s_per_rad=args.angular_drag_n_m_s_per_rad, mass_kg=args.mass_kg,
        inertia_kg_m2=args.inertia_kg_m2, inertia_scale=args.inertia_scale,
        inertia_perturb_sd_kg_m2=args.inertia_perturb_sd_kg_m2,
        rotor_time_constant_s=args.rotor_time_constant_s, rotor_noise_sd_n=args.rotor_noise_sd_n,
        max_rotor_thrust_n=(args.max_rotor_thrust_n if args.rotor_saturation_n is None
                            else args.rotor_saturation_n))
    seed = getattr(args, "mismatch_seed", None)
    scale = getattr(args, "mismatch_scale", None)
    if seed is None:
        if scale is not None:
            raise ValueError("--mismatch-scale needs --mismatch-seed")
        return nominal, nominal
    kept = [name for name, given in (
        ("mass_kg", args.mass_kg is not None),
        ("inertia_kg_m2", any(x is not None for x in (args.inertia_kg_m2, args.inertia_scale,
                                                      args.inertia_perturb_sd_kg_m2))),
        ("rotor_time_constant_s", args.rotor_time_constant_s is not None)) if given]
    draw = draw_mismatch(seed, 1.0 if scale is None else scale)
    return nominal, apply_mismatch(nominal, draw, kept)


def _print_rate_response(args) -> int:
    try:
        world, _, vehicle, nominal, params, _, _ = _read_inputs(args)
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    scale = args.max_rotor_thrust_n if args.max_rotor_thrust_n is not None else vehicle.max_rotor_thrust_n
    print_rate_response(args, world, nominal, params, scale)
    return int(ExitCode.OK)


def _raise_stop(signum, frame):
    raise StopRun(signal.Signals(signum).name)


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (see :class:`firmware_sim.status.ExitCode`); a
    closed pipe exits 141 and a Ctrl-C before the run starts 130, without a traceback."""
    try:
        code = _main(argv)
        sys.stdout.flush()
        return code
    except BrokenPipeError:          # a closed pipe: quiet, as a shell expects (mavreg.cli.guard)
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except OSError:
            pass
        return 128 + signal.SIGPIPE
    except KeyboardInterrupt:        # before the run's own signal handlers are in place
        print("firmware-sim: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.print_rate_response:         # the figures of the run's world and airframe, no socket
            return _print_rate_response(args)
        engine, recorder = build_engine(args)
    except (BadInput, OSError) as exc:   # a bad value or file; OSError: a file it cannot read or write
        print(f"firmware-sim: error: {' '.join(str(exc).split())[:400]}", file=sys.stderr)
        return int(ExitCode.USAGE)
    except Exception:                     # a bug: not the user's input
        import traceback
        traceback.print_exc()
        print("firmware-sim: this is a bug in firmware_sim: please report it with the command line and "
              f"the traceback above (exit {int(ExitCode.INTERNAL)})", file=sys.stderr)
        return int(ExitCode.INTERNAL)
    print(f"firmware_sim listening on {engine.link.url}", flush=True)
    print(f"firmware_sim {engine.world.describe(engine.sim.params.vehicle.emulator)}", flush=True)
    if engine.sim.params.mismatch is not None:
        print(f"firmware_sim {describe_airframe(engine.sim.params)}", flush=True)
    code, reason = ExitCode.OK, "done"
    old = {s: signal.signal(s, _raise_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        if args.lockstep:
            run_lockstep(engine, args.lockstep_timeout, args.duration_s, args.quiet,
                         args.lockstep_stall_factor)
        else:
            run_realtime(engine, args.rate_hz, args.duration_s, args.quiet)
    except StopRun as exc:
        reason = f"stopped by {exc}"
    except SimStop as exc:
        code, reason = exc.code, exc.reason
        engine.announce_stop(reason)
        print(f"firmware_sim: {reason}", file=sys.stderr, flush=True)
    except Exception as exc:             # a bug: keep the recording, report, exit 1
        import traceback
        traceback.print_exc()
        code, reason = ExitCode.INTERNAL, f"internal error: {exc!r}"
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        if recorder is not None:
            recorder.meta.update(stop_reason=reason, exit_code=int(code), **engine.run_meta())
            recorder.save()
        engine.link.close()
    if not args.quiet:
        print(f"firmware_sim: {reason} at t={engine.sim.t_s:.3f} s; {engine.status_line()}", flush=True)
    return int(code)
