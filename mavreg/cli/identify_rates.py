"""``mavreg identify`` on a flight of the rates output: the fit's options, the table and the
vehicle file's values (docs/identify.md, *Rate mode*). :mod:`mavreg.cli.identify_cmd` is the
command; it comes here when the flight's commands are SET_ATTITUDE_TARGET."""
from __future__ import annotations

from .identify_cmd import estimate_lines

__all__ = ["fit", "format_result", "vehicle_values"]


def fit(args, vehicle, series):
    """(RateIdentification, a phrase saying where the collective's delay came from): the
    collective's delay as the rotor output's (``--delay``); the rate loop's own delay is D
    less TIMESYNC and the file's estimate latency."""
    from ..identify.fit import FitOptions
    from ..identify.rate_fit import identify_rates
    from .identify_cmd import resolve_delay
    link = series.link_delay_s
    delay, source = resolve_delay(args.delay, link, vehicle.estimate_latency_s)
    options = FitOptions(delay_s=delay, parasitic=args.parasitic, replicates=args.replicates, seed=args.seed,
                         rotor_drag_thrust_exponent=vehicle.rotor_drag_thrust_exponent,
                         rate_window=getattr(args, "rate_window", "auto"))
    link_part = 0.0 if link is None else link + vehicle.estimate_latency_s
    return identify_rates(series, vehicle.mass_kg, options, link_delay_part_s=link_part), source


def format_result(r, vehicle, flight: str, delay_source: str) -> str:
    """The human-readable tables of a RateIdentification: the thrust map and translational
    terms, then the rate loop per axis."""
    ri = vehicle.rate_interface
    lo, hi = r.thrust_range
    lines = [f"mavreg identify: {flight}: {r.duration_s:.1f} s of armed, OFFBOARD, airborne flight "
             f"({r.samples} samples); rates output (SET_ATTITUDE_TARGET body rates + thrust); "
             f"vehicle {vehicle.name} ({vehicle.mass_kg:g} kg)",
             f"thrust map F = F_max ((1 - e) t + e t^2), thrust flown {lo:.2f} .. {hi:.2f} (5-95 %); "
             f"model: {r.model}; collective delay: {delay_source}",
             f"{'parameter':<30}{'value':>13}   {'95 % interval':<22}{'vehicle file':>12}"]
    cxy, cz = vehicle.rotor_drag_n_s_per_m
    rows = [("hover thrust t_h", r.hover_thrust, 1.0, 3, "-" if ri is None else f"{ri.hover_thrust:g}"),
            ("thrust expo e", r.thrust_expo, 1.0, 3, "-" if ri is None else f"{ri.thrust_expo:g}"),
            ("max collective F_max (N)", r.max_thrust_n, 1.0, 2, ""),
            ("collective time const (ms)", r.collective_time_constant_s, 1e3, 1,
             f"{1e3 * vehicle.rotor_time_constant_s:g}"),
            ("collective delay (ms)", r.collective_delay_s, 1e3, 1, "")]
    rows += [(f"drag c_{a} (N s/m)", e, 1.0, 3, f"{cxy if a != 'z' else cz:g}")
             for a, e in zip("xyz", r.drag_n_s_per_m)]
    rows += [("parasitic c_p (N s2/m2)", r.parasitic_n_s2_per_m2, 1.0, 4, f"{vehicle.parasitic_drag_n_s2_per_m2:g}")]
    lines += estimate_lines(rows, delay_source, (30, 13))
    lines.append(f"fit: residual RMS {r.residual_rms_m_s2:.3f} m/s2, R2 {r.r_squared:.4f}; "
                 f"RMS body speed x y z {' '.join(f'{v:.2f}' for v in r.rms_body_speed_m_s)} m/s")
    lines += _rate_table(r, ri)
    if r.link_delay_s is not None:
        lines.append(f"TIMESYNC sample-to-actuation delay {1e3 * r.link_delay_s:.1f} ms; d = D less "
                     f"{1e3 * r.link_delay_part_s:.1f} ms (TIMESYNC + the file's estimate latency)")
    else:
        lines.append("no TIMESYNC in the flight: d is D, from the sample to the response")
    lines.append(f"intervals: {r.intervals}")
    return "\n".join(lines)


def _rate_table(r, ri) -> list[str]:
    """The rate loop's rows: tau, D, d, gain, residual per axis; the file's tau and d last."""
    lines = ["rate loop dw/dt = (w_cmd(t - D) - w)/tau: D from the sample the command answered, "
             "d the loop's own delay, k the gain fitted freely (the model: 1); fitted on "
             f"{r.rate_window}",
             f"{'axis':<24}{'tau (ms)':>9}  {'95 % interval':<15}{'D (ms)':>7}  {'95 % interval':<15}"
             f"{'d (ms)':>7}{'k':>8}{'resid (rad/s)':>15}"]
    for name, label in (("roll", "roll"), ("pitch", "pitch"), ("yaw", "yaw"),
                        ("roll_pitch", "roll + pitch (written)")):
        a = r.rate_axes[name]
        if a.time_constant_s.value is None:
            lines.append(f"{label:<24}{'not identified':>9}  {a.time_constant_s.why}")
            continue
        t, d, loop = a.time_constant_s, a.delay_s, a.loop_delay_s
        tau_s = f"{1e3 * t.value:9.1f}  {f'{1e3 * t.low:.1f} .. {1e3 * t.high:.1f}':<15}"
        d_s = (f"{'-':>7}  {'not identified':<15}{'-':>7}" if d.value is None else
               f"{1e3 * d.value:7.1f}  {f'{1e3 * d.low:.1f} .. {1e3 * d.high:.1f}':<15}{1e3 * loop.value:7.1f}")
        lines.append(f"{label:<24}{tau_s}{d_s}{a.free_gain:8.3f}{a.residual_rms_rad_s:15.4f}")
    if ri is not None:
        lines.append(f"vehicle file: rate_time_constant_s {1e3 * ri.rate_time_constant_s:g} ms, "
                     f"rate_delay_s {1e3 * ri.rate_delay_s:g} ms")
    return lines


def vehicle_values(result, vehicle) -> dict:
    """The vehicle file's keys for the rates output: ``output``, the ``rate_interface:``
    section (the file's ``max_body_rate_rad_s`` and ``attitude_gain_rad_s`` kept), the collective's lag as ``rotor_time_constant_s``, thrust_scale 1 and the drag."""
    from ..config.vehicle import RateInterfaceParams
    from .identify_cmd import drag_values
    old = vehicle.rate_interface or RateInterfaceParams(hover_thrust=0.5)
    rp = result.rate_axes["roll_pitch"]
    tau = rp.time_constant_s.value if rp.time_constant_s.value is not None else old.rate_time_constant_s
    d = rp.loop_delay_s.value if rp.loop_delay_s.value is not None else old.rate_delay_s
    section = {"hover_thrust": round(result.hover_thrust.value, 4),
               "thrust_expo": round(min(max(result.thrust_expo.value, 0.0), 1.0), 4),
               "rate_time_constant_s": round(min(max(tau, 0.001), 0.5), 4),
               "rate_delay_s": round(min(max(d, 0.0), 0.2), 4),
               "max_body_rate_rad_s": list(old.max_body_rate_rad_s),
               "attitude_gain_rad_s": list(old.attitude_gain_rad_s)}
    out = {"output": "rates", "rate_interface": section, "thrust_scale": 1.0}
    if result.collective_time_constant_s.value is not None:
        out["rotor_time_constant_s"] = round(result.collective_time_constant_s.value, 4)
    return {**out, **drag_values(result, vehicle)}
