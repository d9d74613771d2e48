"""The flight envelope monitor: numbers in, the first violated bound out (sans-I/O).

The supervisor calls it on every complete state sample, in this order:

1. :meth:`EnvelopeMonitor.check_state` with the telemetry alone: impact (ground contact at
   speed, acceleration spike), a position jump the velocity does not explain, thrust that
   the measured acceleration contradicts, absolute body rate, altitude floor, geofence;
2. :meth:`EnvelopeMonitor.check_tracking` with the controller's errors: distance from the
   path or the hover reference, attitude error, rate error, the regulation tube, progress
   along s, and the share of clipped rotor commands;
3. :meth:`EnvelopeMonitor.record_command` with every rotor command sent.

Each check returns a :class:`~mavreg.daemon.flight.records.BoundViolation` (or None): which bound, where (phase, s, t), the
value, the limit, and whether the vehicle has hit something (``impact``: stop the motors).
Bounds come from :class:`mavreg.config.envelope.EnvelopeParams`; docs/safety.md lists them.
Altitudes and the geofence are relative to the take-off point (:meth:`set_origin`).

The sliding windows are :class:`~mavreg.daemon.flight.series.Series`.
"""
from __future__ import annotations

import collections
import math
from bisect import bisect_right
from dataclasses import dataclass

from ...config.envelope import EnvelopeParams
from ...config.vehicle import G
from .phases import AIRBORNE, Phase
from .records import BoundViolation
from .series import Series

__all__ = ["Tracking", "EnvelopeMonitor"]

_FLOOR = (Phase.HOLD, Phase.RUN_IN, Phase.MANEUVER)
_KEYS: dict = {}       # phase -> the peak names of its tracking bounds
PEAK_UNITS = {"impact_descent": "m/s", "impact_speed": "m/s", "impact_accel": "m/s^2", "position_jump": "m",
              "body_rate": "rad/s", "altitude_floor": "m", "geofence": "ratio", "thrust_mismatch": "ratio",
              "position_error": "m", "attitude_error": "rad", "rate_error": "rad/s", "progress": "s",
              "saturation": "share"}
"""The unit of each peak's value and limit (``status.envelope_peaks`` in summary.json), by
the bound's name before its phase suffix (``attitude_error.maneuver``)."""


@dataclass(frozen=True)
class Tracking:
    """The controller's errors at one step (see :class:`~mavreg.config.envelope.PhaseBounds`)."""

    position_error_m: float
    attitude_error_rad: float
    rate_error_rad_s: float
    s_m: float = math.nan
    in_tube: bool = True


class EnvelopeMonitor:
    """Sliding-window checks of one flight.

    Parameters
    ----------
    params : EnvelopeParams
    mass_kg, max_rotor_thrust_n : float
        Design mass and rotor limit: the weight the thrust check compares with, the
        largest acceleration the rotors can produce, what counts as a clipped command.
    """

    def __init__(self, params: EnvelopeParams, mass_kg: float, max_rotor_thrust_n: float):
        self.p = params
        self.mass_kg = float(mass_kg)
        self.fmax = float(max_rotor_thrust_n)
        self.max_accel_m_s2 = 4.0 * self.fmax / self.mass_kg + G
        self.origin: tuple[float, float, float] | None = None
        self._states = Series()       # (t, p, v)
        self._commands = Series()     # (t, clipped, collective)
        self._phase = Phase.PREFLIGHT
        self._phase_t0 = 0.0
        self._progress: collections.deque = collections.deque()   # (t, s)
        self._stall_since: float | None = None
        self._out_of_tube_since: float | None = None
        self._mismatch_since: float | None = None
        self._bounds = {ph: params.bounds(ph) for ph in AIRBORNE}
        self.peaks: dict[str, dict] = {}
        """Per bound, the closest the flight came to it: value / limit (limit / value for
        lower bounds), with the value, the limit, the phase and the time. Over 1 fires."""

    def _peak(self, bound: str, value: float, limit: float, phase: str, t_s: float, lower: bool = False) -> None:
        if lower:
            ratio = limit / value if value > 0 else (0.0 if limit <= 0 else math.inf)
        else:
            ratio = value / limit if limit > 0 else (0.0 if value <= 0 else math.inf)
        p = self.peaks.get(bound)
        if p is None or ratio > p["ratio"]:
            self.peaks[bound] = {"ratio": ratio, "value": value, "limit": limit,
                                 "unit": PEAK_UNITS.get(bound.split(".", 1)[0], ""), "phase": phase, "t_s": t_s}

    # ------------------------------------------------------------------ context
    def set_origin(self, position_m) -> None:
        """The take-off point (NED): altitude floor, geofence and impact are relative to it."""
        self.origin = (float(position_m[0]), float(position_m[1]), float(position_m[2]))

    def altitude_m(self, position_m) -> float:
        return math.nan if self.origin is None else self.origin[2] - float(position_m[2])

    def phase_changed(self, phase: str, t_s: float) -> None:
        """Windows that belong to one phase (saturation, progress, tube) start again."""
        self._phase = phase
        self._phase_t0 = t_s
        self._commands.clear()
        self._progress.clear()
        self._stall_since = None
        self._out_of_tube_since = None

    # ------------------------------------------------------------------ telemetry
    def check_state(self, t_s: float, phase: str, s_m: float, p, v, R, omega,
                    disturbance=None) -> BoundViolation | None:
        """Telemetry-only bounds of a sample (NED position and velocity, body-to-NED R, body rates).

        ``disturbance`` is the observer's estimate
        (:class:`~mavreg.control.estimation.disturbance.DisturbanceEstimate`: body drag, a constant
        force), or None: the thrust check counts the external force it explains, so that a
        gust or a wind is not read as a thrust failure."""
        prm = self.p
        px, py, pz = float(p[0]), float(p[1]), float(p[2])
        vx, vy, vz = float(v[0]), float(v[1]), float(v[2])
        states = self._states
        prev = states.newest() if len(states) else None
        states.add(t_s, (px, py, pz), (vx, vy, vz))
        states.drop_older(t_s, 0.5)
        if phase not in AIRBORNE:
            return None

        speed = math.sqrt(vx * vx + vy * vy + vz * vz)
        alt = math.nan if self.origin is None else self.origin[2] - pz
        # 1. a sample that contradicts the one before (an estimate that jumped) is judged as such
        # before anything is concluded from it: one absurd sample is a recovery, never an impact
        if prev is not None and 0.0 < t_s - prev[0] <= 0.5:
            dt = t_s - prev[0]
            (qx, qy, qz), (ux, uy, uz) = prev[1], prev[2]
            ex = px - qx - 0.5 * (ux + vx) * dt
            ey = py - qy - 0.5 * (uy + vy) * dt
            ez = pz - qz - 0.5 * (uz + vz) * dt
            jump = math.sqrt(ex * ex + ey * ey + ez * ez)
            limit = prm.max_position_jump_m + 0.5 * self.max_accel_m_s2 * dt * dt
            self._peak("position_jump", jump, limit, phase, t_s)
            if jump > limit:
                return self._fail(phase, t_s, s_m, "position_jump", jump, limit, "m",
                                  f"position moved {jump:.2f} m more than the velocity explains over "
                                  f"{dt * 1e3:.0f} ms")
        # impact: at the ground at speed, or an acceleration no rotor can produce
        if alt <= prm.impact_altitude_m:
            self._peak("impact_descent", vz, prm.impact_descent_m_s, phase, t_s)
            self._peak("impact_speed", speed, prm.impact_speed_m_s, phase, t_s)
            if vz > prm.impact_descent_m_s:
                return self._fail(phase, t_s, s_m, "impact", vz, prm.impact_descent_m_s, "m/s",
                                  f"descending at {vz:.2f} m/s at {alt:.2f} m above the take-off point", True)
            if speed > prm.impact_speed_m_s:
                return self._fail(phase, t_s, s_m, "impact", speed, prm.impact_speed_m_s, "m/s",
                                  f"moving at {speed:.2f} m/s at {alt:.2f} m above the take-off point", True)
        acc = self._acceleration(t_s, prm.accel_window_s)
        if acc is not None:
            a = math.sqrt(acc[0] ** 2 + acc[1] ** 2 + acc[2] ** 2)
            self._peak("impact_accel", a, prm.impact_accel_m_s2, phase, t_s)
            if a > prm.impact_accel_m_s2:
                # an impact only where there is ground to hit; in the air a spike (a collision,
                # an estimate that jumped) is a violation like any other: a recovery
                at_ground = alt <= prm.impact_altitude_m
                return self._fail(phase, t_s, s_m, "impact" if at_ground else "accel_spike", a,
                                  prm.impact_accel_m_s2, "m/s^2",
                                  f"acceleration spike {a:.0f} m/s^2 from the reported velocity", at_ground)
        # 2. telemetry that contradicts itself or the commands
        v_bad = self._thrust_check(t_s, R, v, disturbance)
        if v_bad is not None:
            measured, commanded, lasted = v_bad
            near_ground = alt <= prm.impact_altitude_m
            return self._fail(phase, t_s, s_m, "thrust_mismatch", measured / commanded, prm.min_thrust_ratio,
                              "ratio",
                              f"measured thrust {measured:.1f} N against {commanded:.1f} N commanded for "
                              f"{lasted:.2f} s" + (" at the ground" if near_ground else ""), near_ground)
        # 3. where the vehicle may be
        return self._check_envelope(t_s, phase, s_m, px, py, alt, omega)

    def _check_envelope(self, t_s: float, phase: str, s_m: float, px: float, py: float, alt: float,
                        omega) -> BoundViolation | None:
        """Where the vehicle may be and how fast it may turn: body rate, altitude floor,
        geofence (the last checks of :meth:`check_state`, in its order)."""
        prm = self.p
        w = math.sqrt(float(omega[0]) ** 2 + float(omega[1]) ** 2 + float(omega[2]) ** 2)
        w_max = prm.recovery.max_body_rate_rad_s if phase == Phase.RECOVER else prm.max_body_rate_rad_s
        self._peak("body_rate", w, w_max, phase, t_s)
        if w > w_max:
            return self._fail(phase, t_s, s_m, "body_rate", w, w_max, "rad/s", "body rate beyond the envelope")
        if phase in _FLOOR:
            self._peak("altitude_floor", alt, prm.min_altitude_m, phase, t_s, lower=True)
        if phase in _FLOOR and alt < prm.min_altitude_m:
            return self._fail(phase, t_s, s_m, "altitude_floor", alt, prm.min_altitude_m, "m",
                              "below the altitude floor")
        if self.origin is not None:
            margin = prm.recovery.geofence_margin_m if phase == Phase.RECOVER else 0.0
            dn, de = abs(px - self.origin[0]), abs(py - self.origin[1])
            hn, he = prm.geofence_half_width_m[0] + margin, prm.geofence_half_width_m[1] + margin
            self._peak("geofence", max(dn / hn, de / he, alt / (prm.geofence_ceiling_m + margin)), 1.0, phase, t_s)
            if dn > hn:
                return self._fail(phase, t_s, s_m, "geofence", dn, hn, "m",
                                  "north of or south of the geofence box")
            if de > he:
                return self._fail(phase, t_s, s_m, "geofence", de, he, "m",
                                  "east of or west of the geofence box")
            if alt > prm.geofence_ceiling_m + margin:
                return self._fail(phase, t_s, s_m, "geofence", alt, prm.geofence_ceiling_m + margin, "m",
                                  "above the geofence ceiling")
        return None

    @staticmethod
    def _fail(phase, t_s, s_m, bound, value, limit, unit, detail, impact=False) -> BoundViolation:
        return BoundViolation(bound, phase, t_s, s_m, float(value), float(limit), unit, detail, impact=impact)

    def _acceleration(self, t_s: float, window_s: float):
        """NED acceleration from the newest velocity and the newest one at least ``window_s``
        older (None without one within 0.1 s more)."""
        st = self._states
        times, vel = st.t, st.b
        n = len(times)
        t1, v1 = times[-1], vel[-1]
        lim = window_s - 1e-9
        # the newest row with t1 - t0 >= lim (times are increasing: samples are never late)
        k = bisect_right(times, t1 - lim, st.head) - 1
        while k + 1 < n and t1 - times[k + 1] >= lim:
            k += 1
        while k >= st.head and not t1 - times[k] >= lim:
            k -= 1
        if k < st.head:
            return None
        dt = t1 - times[k]
        if dt > window_s + 0.1:
            return None
        v0 = vel[k]
        return ((v1[0] - v0[0]) / dt, (v1[1] - v0[1]) / dt, (v1[2] - v0[2]) / dt)

    def _thrust_check(self, t_s: float, R, v, disturbance=None):
        r"""(measured N, commanded N, lasted s) when the mismatch has lasted long enough.

        With :math:`m a = m g e_3 - T b_3 + F` (NED, :math:`b_3` the body z axis, :math:`F`
        the external force the observer estimates), the thrust the telemetry implies is
        :math:`T = m g R_{33} - m\,b_3^T a + b_3^T F`. Of the observer's force model
        (:mod:`mavreg.control.estimation.disturbance`) only the constant force and the drag along
        :math:`b_3` project on it: :math:`b_3^T F = b_3^T F_w - c_z\,b_3^T v`. The commanded
        collective is what the controller asked the rotors to give (the thrust-scale
        calibration is applied after it), so it is compared as it is."""
        prm = self.p
        c = self._commands
        k = c.within(t_s, prm.thrust_window_s, strict=False)
        n = len(c.t) - k
        total = sum(c.b[k:]) if n else 0.0
        acc = self._acceleration(t_s, prm.thrust_window_s)
        if not n or acc is None:
            self._mismatch_since = None
            return None
        commanded = total / n
        if commanded < prm.thrust_check_min_ratio * self.mass_kg * G:
            self._mismatch_since = None
            return None
        # specific force along the thrust axis (-body z) times the design mass, plus what the
        # external force the observer explains adds along it
        b3x, b3y, b3z = float(R[0][2]), float(R[1][2]), float(R[2][2])
        measured = self.mass_kg * (G * b3z - (b3x * acc[0] + b3y * acc[1] + b3z * acc[2]))
        if disturbance is not None:
            fw = disturbance.force_ned_n
            along_v = b3x * float(v[0]) + b3y * float(v[1]) + b3z * float(v[2])
            measured += (b3x * fw[0] + b3y * fw[1] + b3z * fw[2]
                         - disturbance.drag_n_s_per_m[1] * along_v)
        self._peak("thrust_mismatch", measured / commanded, prm.min_thrust_ratio, self._phase, t_s, lower=True)
        if measured >= prm.min_thrust_ratio * commanded:
            self._mismatch_since = None
            return None
        if self._mismatch_since is None:
            self._mismatch_since = t_s
        lasted = t_s - self._mismatch_since
        return (measured, commanded, lasted) if lasted >= prm.thrust_mismatch_s else None

    # ------------------------------------------------------------------ control
    def check_tracking(self, t_s: float, phase: str, tr: Tracking) -> BoundViolation | None:
        """The phase's tracking bounds, the tube, progress along s, the saturation share."""
        b = self._bounds[phase] if phase in self._bounds else self.p.bounds(phase)
        if b is None:
            return None
        s_m = tr.s_m

        def fail(bound, value, limit, unit, detail):
            return BoundViolation(bound, phase, t_s, s_m, float(value), float(limit), unit, detail)

        what = "distance from the path" if phase == Phase.MANEUVER else "distance from the reference"
        keys = _KEYS.get(phase)
        if keys is None:
            keys = _KEYS[phase] = (f"position_error.{phase}", f"attitude_error.{phase}", f"rate_error.{phase}")
        self._peak(keys[0], tr.position_error_m, b.max_position_error_m, phase, t_s)
        self._peak(keys[1], tr.attitude_error_rad, b.max_attitude_error_rad, phase, t_s)
        self._peak(keys[2], tr.rate_error_rad_s, b.max_rate_error_rad_s, phase, t_s)
        if tr.position_error_m > b.max_position_error_m:
            return fail("position_error", tr.position_error_m, b.max_position_error_m, "m", what)
        if tr.attitude_error_rad > b.max_attitude_error_rad:
            return fail("attitude_error", tr.attitude_error_rad, b.max_attitude_error_rad, "rad",
                        "angle from the reference attitude")
        if tr.rate_error_rad_s > b.max_rate_error_rad_s:
            return fail("rate_error", tr.rate_error_rad_s, b.max_rate_error_rad_s, "rad/s",
                        "body rate error from the reference")
        if phase == Phase.MANEUVER:
            v = self._maneuver_checks(t_s, tr, fail)
            if v is not None:
                return v
        return self._saturation(t_s, b.max_saturated_share, fail)

    def _maneuver_checks(self, t_s: float, tr: Tracking, fail):
        prm = self.p
        if tr.in_tube:
            self._out_of_tube_since = None
        else:
            if self._out_of_tube_since is None:
                self._out_of_tube_since = t_s
            if t_s - self._out_of_tube_since >= prm.tube_exit_s:
                return fail("tube", t_s - self._out_of_tube_since, prm.tube_exit_s, "s",
                            "outside the regulation tube (nearest point on the path not unique)")
        q = self._progress
        q.append((t_s, tr.s_m))
        while len(q) > 2 and t_s - q[1][0] >= prm.progress_window_s:
            q.popleft()
        dt = t_s - q[0][0]
        if dt >= prm.progress_window_s:
            rate = (tr.s_m - q[0][1]) / dt
            if rate >= prm.min_progress_m_s:
                self._stall_since = None
            else:
                if self._stall_since is None:
                    self._stall_since = t_s - dt
                # how close: the time stalled against max_stall_s (what fires), not the rate,
                # whose ratio is infinite as soon as a gust carries the vehicle back
                self._peak("progress", t_s - self._stall_since, prm.max_stall_s, Phase.MANEUVER, t_s)
                if t_s - self._stall_since >= prm.max_stall_s:
                    return fail("progress", rate, prm.min_progress_m_s, "m/s",
                                f"ds/dt under the bound for {t_s - self._stall_since:.2f} s")
        return None

    def _saturation(self, t_s: float, share_limit: float, fail):
        win = self.p.saturation_window_s
        c = self._commands
        if t_s - self._phase_t0 < win or not len(c):
            return None
        recent = c.a[c.within(t_s, win, strict=True):]
        if not len(recent):           # no command for a window (a gap, judged by the gap policy)
            return None
        share = sum(recent) / len(recent)
        self._peak(f"saturation.{self._phase}", share, share_limit, self._phase, t_s)
        if share > share_limit:
            return fail("saturation", share, share_limit, "share",
                        f"{100 * share:.0f} % of the rotor commands of the last {win:g} s clipped")
        return None

    def record_command(self, t_s: float, demand_n) -> None:
        """A rotor command about to be sent: the controller's forces, before clipping."""
        fmax = self.fmax
        f0, f1, f2, f3 = demand_n.tolist() if hasattr(demand_n, "tolist") else (float(x) for x in demand_n)
        lo, hi = -1e-9, fmax + 1e-9
        clipped = f0 < lo or f0 > hi or f1 < lo or f1 > hi or f2 < lo or f2 > hi or f3 < lo or f3 > hi
        collective = (min(max(f0, 0.0), fmax) + min(max(f1, 0.0), fmax) + min(max(f2, 0.0), fmax)
                      + min(max(f3, 0.0), fmax))
        self._commands.add(t_s, clipped, collective)
        self._commands.drop_older(t_s, max(self.p.saturation_window_s, self.p.thrust_window_s))
