"""``mavreg identify``: calibrate the vehicle file from one flight (docs/identify.md)."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

from ..errors import UsageError
from .common import DEFAULT_VEHICLE, input_file, nonneg_int, output_file

HELP = ("fit thrust scale, drag and rotor time constant (or, flown with --output rates, the autopilot's "
        "thrust map and rate loop) to a flight; optionally write a vehicle YAML")
DESCRIPTION = """\
Calibrate a vehicle from one flight. FLIGHT is a 'mavreg fly' output directory (its
flight.tlog is read) or any .tlog of a vehicle flown by the daemon: the vehicle's
LOCAL_POSITION_NED and ATTITUDE_QUATERNION, its HEARTBEAT (armed, OFFBOARD), the daemon's
SET_ACTUATOR_CONTROL_TARGET rotor commands (each paired with the sample it answered) and
TIMESYNC. Only armed, OFFBOARD, airborne samples are used.

Model (NED, R body to NED, v velocity, f_i rotor commands):

  m dv/dt = s_T (sum f_i)(-R e3) + m g e3 - R diag(c_x, c_y, c_z) R^T v  [- c_p |v| v]

with the commands delayed by D (sample time to the rotors) and lagged by a first-order
rotor time constant tau. Fitted: the thrust scale s_T (actual thrust per unit commanded;
a vehicle heavier than its file shows as s_T = m_file / m_true), the body drag c_x, c_y,
c_z (N s/m), tau, the parasitic c_p when significant, and D with --delay search. The
acceleration is a Savitzky-Golay derivative of the velocity; the same filter is applied
to the model's integral, so neither side lags the other. For each (tau, D) the rest is
linear least squares; (tau, D) minimize the residual.

The delay: by default (--delay auto) the flight's TIMESYNC measurement (sample to
actuation) plus the vehicle file's estimate_latency_s; with no TIMESYNC it is searched
jointly with tau. A joint search of a closed-loop flight with estimator errors trades
some delay for lag (docs/identify.md: 34 ms instead of 30 on the realistic emulator).

95 % intervals come from a moving-block bootstrap (blocks of at least 1 s; the residuals
are correlated in time, so plain least-squares intervals would be far too narrow). A drag
axis the flight did not move along (RMS body speed < 0.5 m/s), or a rotor lag the flight
did not excite, is reported as not identified and keeps the vehicle file's value.

--write-vehicle OUT.yaml writes a copy of the vehicle file with the identified values:
thrust_scale, rotor_time_constant_s (the controller's estimate; where the emulator's rotors
followed the file's lag, emulator.true_rotor_time_constant_s keeps the old value for them),
rotor_drag_n_s_per_m [c_xy, c_z] (c_xy the inverse-variance mean of c_x and
c_y) and parasitic_drag_n_s2_per_m2 (0 when the linear model was fitted).

Rates output (a flight of 'mavreg fly --output rates': the daemon's SET_ATTITUDE_TARGET
body rates and thrust, detected from the tlog): the autopilot's thrust map
F = F_max ((1 - e) t + e t^2), with the hover thrust t_h holding the file's mass, is fitted
on the same model with the lagged t and t^2 in place of the rotor sum (t_h, e, and the
collective's time constant, written as rotor_time_constant_s), and its rate loop, a delay D
then first order, dw/dt = (w_cmd(t - D) - w)/tau, per axis from the body rates: the rate
integrated over each sample against the exact integral of the delayed, lagged command
(gain and offset linear, (tau, D) on a grid). D runs from the sample to the response; the
rate loop's own delay d is D less TIMESYNC and the file's estimate latency. The collective's
delay is taken as for the rotor output (--delay). --write-vehicle then writes
output: rates, a rate_interface: section (hover_thrust, thrust_expo, the roll and pitch
rate_time_constant_s and rate_delay_s) and thrust_scale 1 (the map is absolute).

Exit status: 0 identified; 2 bad path, a flight without usable data, bad arguments.
"""


def _delay(text: str):
    if text in ("auto", "timesync", "search"):
        return text
    try:
        v = float(text)
    except ValueError:
        raise _arg_error(f"expected auto, timesync, search or a delay in ms, got {text!r}") from None
    if not (math.isfinite(v) and 0.0 <= v <= 200.0):
        raise _arg_error(f"a delay must be 0..200 ms, got {text!r}")
    return v * 1e-3


def _replicates(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise _arg_error(f"expected a whole number, got {text!r}") from None
    if not 50 <= n <= 5000:
        raise _arg_error(f"must be 50..5000, got {n}")
    return n


def _arg_error(msg: str):
    import argparse
    return argparse.ArgumentTypeError(msg)


def add_arguments(p):
    p.add_argument("flight", metavar="FLIGHT", help="a 'mavreg fly' output directory or a .tlog file")
    p.add_argument("--vehicle-params", metavar="YAML", type=input_file, default=str(DEFAULT_VEHICLE),
                   help="the vehicle file the flight was flown with: mass, maximum rotor thrust, "
                   "estimate latency (default: %(default)s)")
    p.add_argument("--write-vehicle", metavar="OUT.yaml", type=output_file, default=None,
                   help="write a copy of the vehicle file with the identified values filled in")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--delay", type=_delay, default="auto", metavar="auto|timesync|search|MS",
                   help="sample-to-rotor (or collective) delay: auto (TIMESYNC if the flight has it, else "
                   "search), timesync, search (jointly with tau), or a value in ms (default: auto)")
    p.add_argument("--parasitic", choices=("auto", "yes", "no"), default="auto",
                   help="quadratic parasitic drag: auto keeps it when its 95 %% interval excludes 0 "
                   "(default: auto)")
    p.add_argument("--rate-window", choices=("auto", "all"), default="auto",
                   help="rates output: the samples the rate loop is fitted on: auto (the identification "
                   "excitation's doublets when the flight has them, 'mavreg fly --identify-excitation', "
                   "else the whole flight) or all (default: auto)")
    p.add_argument("--replicates", type=_replicates, default=300, metavar="N",
                   help="bootstrap replicates for the intervals (default: %(default)s)")
    p.add_argument("--seed", type=nonneg_int, default=0, metavar="N", help="bootstrap seed (default: %(default)s)")


def run(args) -> int:
    from ..config.vehicle import load_vehicle
    from ..identify.fit import FitOptions, identify
    from ..identify.flightlog import read_flight
    vehicle = load_vehicle(args.vehicle_params)
    series = read_flight(args.flight)
    if series.output == "rates":
        from . import identify_rates
        result, source = identify_rates.fit(args, vehicle, series)
    else:
        delay, source = resolve_delay(args.delay, series.link_delay_s, vehicle.estimate_latency_s)
        result = identify(series, vehicle.mass_kg, vehicle.max_rotor_thrust_n,
                          FitOptions(delay_s=delay, parasitic=args.parasitic, replicates=args.replicates,
                                     seed=args.seed,
                                     rotor_drag_thrust_exponent=vehicle.rotor_drag_thrust_exponent))
    written = None
    if args.write_vehicle is not None:
        written = write_vehicle(Path(args.vehicle_params), Path(args.write_vehicle), result)
    if args.json:
        out = {"flight": str(args.flight), "vehicle": str(args.vehicle_params), "delay_source": source,
               **result.as_dict(), "written": None if written is None else
               {"path": str(args.write_vehicle), "values": written}}
        print(json.dumps(out, indent=1))
    else:
        if series.output == "rates":
            print(identify_rates.format_result(result, vehicle, str(args.flight), source))
        else:
            print(format_result(result, vehicle, str(args.flight), source))
        if written is not None:
            print(f"wrote {args.write_vehicle}: " + ", ".join(f"{k} {v}" for k, v in written.items()))
    return 0


def resolve_delay(spec, link_delay_s, estimate_latency_s):
    """(delay for the fit or None to search, a phrase saying where it came from)."""
    if isinstance(spec, float):
        return spec, f"given ({1e3 * spec:.1f} ms)"
    if spec == "search" or (spec == "auto" and link_delay_s is None):
        return None, "searched jointly with tau" + (" (the flight has no TIMESYNC)" if spec == "auto" else "")
    if link_delay_s is None:
        raise UsageError("--delay timesync: the flight has no TIMESYNC replies; use --delay search or MS")
    d = link_delay_s + estimate_latency_s
    return d, (f"TIMESYNC {1e3 * link_delay_s:.1f} ms + the vehicle file's estimate latency "
               f"{1e3 * estimate_latency_s:.1f} ms")


def estimate_lines(rows, delay_source: str, widths: tuple[int, int] = (28, 15)) -> list[str]:
    """The table lines of ``rows`` (name, Estimate, scale, digits, the vehicle file's value):
    value, 95 % interval and file value; a given value says where it came from, one not
    identified says why. ``widths``: of the name and value columns."""
    nw, vw = widths
    lines = []
    for name, e, scale, digits, file_value in rows:
        value, interval = format_estimate(e, scale, digits)
        if e.why == "given":
            lines.append(f"{name:<{nw}}{value:>{vw}}   (not fitted: {delay_source})")
        elif e.value is None:
            lines.append(f"{name:<{nw}}{value:>{vw}}   {interval}")
        else:
            lines.append(f"{name:<{nw}}{value:>{vw}}   {interval:<22}{file_value:>12}")
    return lines


def format_estimate(e, scale=1.0, digits=3) -> tuple[str, str]:
    """(value, 95 % interval) of an Estimate as text (or "not identified" and why)."""
    if e.value is None:
        return "not identified", e.why
    f = f"{{:.{digits}f}}"
    return f.format(e.value * scale), f"{f.format(e.low * scale)} .. {f.format(e.high * scale)}"


def format_result(r, vehicle, flight: str, delay_source: str) -> str:
    """The human-readable table of an Identification."""
    lines = [f"mavreg identify: {flight}: {r.duration_s:.1f} s of armed, OFFBOARD, airborne flight "
             f"({r.samples} samples); vehicle {vehicle.name} ({vehicle.mass_kg:g} kg, "
             f"{vehicle.max_rotor_thrust_n:g} N rotors)",
             f"model: {r.model}; delay: {delay_source}",
             f"{'parameter':<28}{'value':>15}   {'95 % interval':<22}{'vehicle file':>12}"]
    cxy, cz = vehicle.rotor_drag_n_s_per_m
    rows = [("thrust scale", r.thrust_scale, 1.0, 3, f"{vehicle.thrust_scale:g}")]
    rows += [(f"drag c_{a} (N s/m)", e, 1.0, 3, f"{cxy if a != 'z' else cz:g}")
             for a, e in zip("xyz", r.drag_n_s_per_m)]
    rows += [("parasitic c_p (N s2/m2)", r.parasitic_n_s2_per_m2, 1.0, 4,
              f"{vehicle.parasitic_drag_n_s2_per_m2:g}"),
             ("rotor time constant (ms)", r.rotor_time_constant_s, 1e3, 1,
              f"{1e3 * vehicle.rotor_time_constant_s:g}"),
             ("delay (ms)", r.delay_s, 1e3, 1, "")]
    lines += estimate_lines(rows, delay_source)
    lines.append(f"fit: residual RMS {r.residual_rms_m_s2:.3f} m/s2, R2 {r.r_squared:.4f}; "
                 f"RMS body speed x y z {' '.join(f'{v:.2f}' for v in r.rms_body_speed_m_s)} m/s")
    if r.link_delay_s is not None:
        lines.append(f"TIMESYNC sample-to-actuation delay {1e3 * r.link_delay_s:.1f} ms")
    lines.append(f"intervals: {r.intervals}")
    return "\n".join(lines)


def vehicle_values(result, vehicle) -> dict:
    """The vehicle file's keys the flight identified, with their new values."""
    if getattr(result, "output", "rotors") == "rates":
        from .identify_rates import vehicle_values as rate_values
        return rate_values(result, vehicle)
    out = {"thrust_scale": round(result.thrust_scale.value, 4)}
    if result.rotor_time_constant_s.value is not None:
        out["rotor_time_constant_s"] = round(result.rotor_time_constant_s.value, 4)
    return {**out, **drag_values(result, vehicle)}


def drag_values(result, vehicle) -> dict:
    """The drag keys of the vehicle file a flight identified (either output)."""
    out = {}
    cxy, cz = vehicle.rotor_drag_n_s_per_m
    xy, z = result.drag_xy_n_s_per_m.value, result.drag_n_s_per_m[2].value
    if xy is not None or z is not None:
        out["rotor_drag_n_s_per_m"] = [round(max(0.0, cxy if xy is None else xy), 4),
                                       round(max(0.0, cz if z is None else z), 4)]
        p = result.parasitic_n_s2_per_m2.value
        out["parasitic_drag_n_s2_per_m2"] = round(max(0.0, p), 5) if p is not None else 0.0
    return out


def write_vehicle(src: Path, dst: Path, result) -> dict:
    """Copy the vehicle file ``src`` to ``dst`` with the identified top-level values replaced
    (a key's whole block: its line and the indented lines under it) or appended, in flow
    style; the copy is checked by the validating loader before it is written."""
    from ..config.loader import load_text
    from ..config.vehicle import VehicleParams, load_vehicle
    original = load_vehicle(src)
    values = vehicle_values(result, original)
    text = _keep_the_emulated_lag(src.read_text(), original, values)
    for key, value in values.items():
        line = f"{key}: {json.dumps(value)}   # mavreg identify"
        pattern = re.compile(rf"^{re.escape(key)}\s*:[^\n]*(?:\n(?:[ \t]+[^\n]*|[ \t]*(?=\n)))*",
                             re.MULTILINE)
        if pattern.search(text):
            text = pattern.sub(lambda _m: line, text, count=1)
        else:
            text = text.rstrip("\n") + "\n" + line + "\n"
    load_text(text, VehicleParams, source=str(dst), kind="vehicle")   # ConfigError: one line
    dst.write_text(text)
    return values


def _keep_the_emulated_lag(text: str, original, values: dict) -> str:
    """``text`` with the emulator's rotor lag pinned where identify changes the file's
    ``rotor_time_constant_s`` and the emulator followed it: the emulator keeps flying the
    rotors it flew (``emulator.true_rotor_time_constant_s``), the controller gets the estimate."""
    tau = values.get("rotor_time_constant_s")
    if (tau is None or tau == original.rotor_time_constant_s
            or original.emulator.true_rotor_time_constant_s is not None):
        return text
    pinned = f"true_rotor_time_constant_s: {original.rotor_time_constant_s!r}   # the emulator's, before identify"
    block = re.search(r"^emulator:[ \t]*(?:#[^\n]*)?\n([ \t]+)", text, re.MULTILINE)
    if block is not None:
        at = block.start(1)     # the section's first line, indented as it is
        return text[:at] + block.group(1) + pinned + "\n" + text[at:]
    if re.search(r"^emulator\s*:", text, re.MULTILINE):
        return text             # a flow-style section: left as it is
    return text.rstrip("\n") + "\nemulator:\n  " + pinned + "\n"

