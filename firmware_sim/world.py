"""The world around the airframe: link, estimator, air and battery, as named presets.

The presets (see docs/firmware_sim.md, "Realistic world", for the sources of every value):

``realistic`` (the default)
    Telemetry 10 ms +- 3 ms late, commands 5 ms +- 3 ms late, 1 % of the messages lost
    each way, and the telemetry an estimate 4 ms old with Gauss-Markov errors of a
    motion-capture-aided EKF and a noisy, slowly biased gyro. The airframe has drag of
    RotorPy's size (:data:`ROTORPY_DRAG`).
``wind3``, ``wind6``
    ``realistic`` in a steady horizontal wind of 3 or 6 m/s from the north (turn it with
    ``--wind-from-deg``).
``thrust90``
    ``realistic`` with rotors that give 90 % of the commanded thrust (a sagging battery).
``ideal``
    No link effects, no estimator, no drag: the telemetry is the true state of the period
    it is stamped with and every command acts at once (the emulator's behaviour before
    the realistic world existed).

Motor lag and rotor noise are the vehicle YAML's (``emulator.*``) in all of them; the
drag and thrust scale are the vehicle YAML's in ``ideal``.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

__all__ = ["LinkParams", "EstimatorParams", "AirframeParams", "ROTORPY_DRAG", "WorldPreset",
           "PRESETS", "PRESET_NAMES", "build_world", "MAX_DELAY_S"]

MAX_DELAY_S = 1.0
"""Upper bound of every delay, jitter and latency (s; 1000 ms before the options were in seconds)."""


@dataclass(frozen=True)
class LinkParams:
    """Delay, jitter and loss of the MAVLink link, each way (sim time).

    Delays are uniform in ``[delay - jitter, delay + jitter]``; ``jitter_s <= delay_s``.
    """

    telemetry_delay_s: float = 0.0
    telemetry_jitter_s: float = 0.0
    command_delay_s: float = 0.0
    command_jitter_s: float = 0.0
    loss_probability: float = 0.0
    """Probability that one message (telemetry) or one datagram (commands) is lost."""

    @property
    def ideal(self) -> bool:
        """No delay, no jitter, no loss."""
        return not (self.telemetry_delay_s or self.telemetry_jitter_s or self.command_delay_s
                    or self.command_jitter_s or self.loss_probability)


@dataclass(frozen=True)
class EstimatorParams:
    """Errors and latency of the published state estimate.

    Position, velocity and attitude errors are first-order Gauss-Markov processes per
    axis (stationary SD and correlation time); the attitude error is a small rotation
    in the body frame. The gyro rates carry a Gauss-Markov bias plus white noise per
    published sample. ``latency_s``: the estimate published at t describes the true
    state at t - latency.
    """

    latency_s: float = 0.0
    position_sd_m: float = 0.0
    position_tau_s: float = 0.5
    velocity_sd_m_s: float = 0.0
    velocity_tau_s: float = 0.2
    attitude_sd_deg: float = 0.0
    attitude_tau_s: float = 0.5
    gyro_noise_sd_rad_s: float = 0.0
    gyro_bias_sd_rad_s: float = 0.0
    gyro_bias_tau_s: float = 30.0

    @property
    def has_errors(self) -> bool:
        """Whether any error SD is non-zero."""
        return bool(self.position_sd_m or self.velocity_sd_m_s or self.attitude_sd_deg
                    or self.gyro_noise_sd_rad_s or self.gyro_bias_sd_rad_s)

    def scaled(self, factor: float) -> "EstimatorParams":
        """The same estimator with every error SD multiplied by ``factor`` (latency kept)."""
        return dataclasses.replace(
            self, position_sd_m=self.position_sd_m * factor,
            velocity_sd_m_s=self.velocity_sd_m_s * factor,
            attitude_sd_deg=self.attitude_sd_deg * factor,
            gyro_noise_sd_rad_s=self.gyro_noise_sd_rad_s * factor,
            gyro_bias_sd_rad_s=self.gyro_bias_sd_rad_s * factor)


@dataclass(frozen=True)
class AirframeParams:
    """What the air and the battery do to the airframe, on top of the vehicle file.

    ``None`` keeps the vehicle file's ``emulator.*`` value. The wind is steady, horizontal,
    ``wind_speed_m_s`` blowing *from* the compass direction ``wind_from_deg`` (0: from the
    north, 90: from the east); it acts through the drag.
    """

    linear_drag_xyz_n_s_per_m: tuple | None = None
    parasitic_drag_xyz_n_s2_per_m2: tuple | None = None
    wind_speed_m_s: float = 0.0
    wind_from_deg: float = 0.0
    thrust_scale: float | None = None

    @property
    def wind_ned_m_s(self) -> tuple[float, float, float]:
        """The wind velocity (where the air goes), NED."""
        a = math.radians(self.wind_from_deg)
        return (-self.wind_speed_m_s * math.cos(a), -self.wind_speed_m_s * math.sin(a), 0.0)

    def apply(self, emulator):
        """``emulator`` (:class:`mavreg.config.vehicle.EmulatorParams`) with these values."""
        changes = {name: getattr(self, name) for name in
                   ("linear_drag_xyz_n_s_per_m", "parasitic_drag_xyz_n_s2_per_m2", "thrust_scale")
                   if getattr(self, name) is not None}
        return dataclasses.replace(emulator, **changes)

    def describe(self, emulator) -> str:
        """The effective airframe values, given the vehicle file's ``emulator``."""
        e = self.apply(emulator)
        text = (f"drag {'/'.join(f'{c:g}' for c in e.linear_drag_xyz_n_s_per_m)} N s/m, parasitic "
                f"{'/'.join(f'{c:g}' for c in e.parasitic_drag_xyz_n_s2_per_m2)} N s^2/m^2, "
                f"thrust scale {e.thrust_scale:g}")
        if self.wind_speed_m_s:
            text += f", wind {self.wind_speed_m_s:g} m/s from {self.wind_from_deg:g} deg"
        return text


# RotorPy's (UPenn) multirotor aerodynamics scaled to the MK-Quadro's mass: rotor drag of a
# hover drag rate 0.45 1/s in the rotor plane and 0.87 1/s along the thrust axis, and its
# parasitic drag coefficients (0.5e-2, 0.5e-2, 1e-2 for 0.5 kg) times 0.749/0.5.
ROTORPY_DRAG = AirframeParams(linear_drag_xyz_n_s_per_m=(0.337, 0.337, 0.652),
                              parasitic_drag_xyz_n_s2_per_m2=(0.0075, 0.0075, 0.015))


@dataclass(frozen=True)
class WorldPreset:
    """A named world: the link, the estimator and the airframe's surroundings."""

    name: str
    link: LinkParams
    estimator: EstimatorParams
    airframe: AirframeParams = AirframeParams()
    overrides: tuple = ()
    """``(flag, value)`` pairs applied on top of the named preset, for the start-up line."""

    def describe(self, emulator=None) -> str:
        """One line: preset name, its effective values and the overrides (the airframe's
        too, given the vehicle file's ``emulator`` parameters)."""
        lk, es = self.link, self.estimator
        text = (f"world: preset {self.name}: telemetry {lk.telemetry_delay_s:g}+-{lk.telemetry_jitter_s:g} s, "
                f"commands {lk.command_delay_s:g}+-{lk.command_jitter_s:g} s, "
                f"loss {100.0 * lk.loss_probability:g} %, estimate latency {es.latency_s:g} s, ")
        if es.has_errors:
            text += (f"estimator errors (SD, tau): position {1000.0 * es.position_sd_m:g} mm "
                     f"{es.position_tau_s:g} s, velocity {100.0 * es.velocity_sd_m_s:g} cm/s "
                     f"{es.velocity_tau_s:g} s, attitude {es.attitude_sd_deg:g} deg {es.attitude_tau_s:g} s, "
                     f"gyro bias {es.gyro_bias_sd_rad_s:g} rad/s {es.gyro_bias_tau_s:g} s, "
                     f"gyro noise {es.gyro_noise_sd_rad_s:g} rad/s per sample")
        else:
            text += "no estimator errors"
        if emulator is not None:
            text += "; airframe: " + self.airframe.describe(emulator)
        if self.overrides:
            text += "; overrides: " + " ".join(f"{flag} {value:g}" for flag, value in self.overrides)
        return text


_REAL_LINK = LinkParams(telemetry_delay_s=0.010, telemetry_jitter_s=0.003, command_delay_s=0.005,
                        command_jitter_s=0.003, loss_probability=0.01)
_REAL_ESTIMATOR = EstimatorParams(
    latency_s=0.004, position_sd_m=0.005, position_tau_s=0.5, velocity_sd_m_s=0.02,
    velocity_tau_s=0.2, attitude_sd_deg=0.3, attitude_tau_s=0.5, gyro_noise_sd_rad_s=0.005,
    gyro_bias_sd_rad_s=0.003, gyro_bias_tau_s=30.0)

PRESETS = {
    "realistic": WorldPreset("realistic", _REAL_LINK, _REAL_ESTIMATOR, ROTORPY_DRAG),
    "wind3": WorldPreset("wind3", _REAL_LINK, _REAL_ESTIMATOR,
                         dataclasses.replace(ROTORPY_DRAG, wind_speed_m_s=3.0)),
    "wind6": WorldPreset("wind6", _REAL_LINK, _REAL_ESTIMATOR,
                         dataclasses.replace(ROTORPY_DRAG, wind_speed_m_s=6.0)),
    "thrust90": WorldPreset("thrust90", _REAL_LINK, _REAL_ESTIMATOR,
                            dataclasses.replace(ROTORPY_DRAG, thrust_scale=0.9)),
    "ideal": WorldPreset("ideal", LinkParams(), EstimatorParams()),
}
PRESET_NAMES = tuple(PRESETS)


def _check_s(flag: str, value: float) -> float:
    if not (math.isfinite(value) and 0.0 <= value <= MAX_DELAY_S):
        raise ValueError(f"{flag} must be a number in [0, {MAX_DELAY_S:g}] s, got {value!r}")
    return float(value)


def build_world(name: str, *, telemetry_delay_s: float | None = None,
                telemetry_jitter_s: float | None = None, command_delay_s: float | None = None,
                command_jitter_s: float | None = None, loss: float | None = None,
                estimate_latency_s: float | None = None,
                estimator_scale: float | None = None, wind_speed_m_s: float | None = None,
                wind_from_deg: float | None = None, thrust_scale: float | None = None,
                linear_drag_xyz_n_s_per_m=None, parasitic_drag_xyz_n_s2_per_m2=None) -> WorldPreset:
    """The preset ``name`` with the command-line overrides applied (``None`` keeps the preset's).

    Raises
    ------
    ValueError
        One line, naming the flag: unknown preset, a value out of range, or a jitter
        larger than its delay (the delay would go negative).
    """
    if name not in PRESETS:
        raise ValueError(f"--preset {name!r}: expected one of {', '.join(PRESET_NAMES)}")
    base = PRESETS[name]
    given = (("--telemetry-delay-s", telemetry_delay_s), ("--telemetry-jitter-s", telemetry_jitter_s),
             ("--command-delay-s", command_delay_s), ("--command-jitter-s", command_jitter_s),
             ("--loss", loss), ("--estimate-latency-s", estimate_latency_s),
             ("--estimator-scale", estimator_scale), ("--wind-speed-m-s", wind_speed_m_s),
             ("--wind-from-deg", wind_from_deg), ("--thrust-scale", thrust_scale))
    overrides = tuple((flag, float(v)) for flag, v in given if v is not None)
    for flag, vec in (("--drag-n-s-per-m", linear_drag_xyz_n_s_per_m),
                      ("--parasitic-drag-n-s2-per-m2", parasitic_drag_xyz_n_s2_per_m2)):
        if vec is not None:
            overrides += tuple((f"{flag}[{i}]", float(v)) for i, v in enumerate(vec))
    link_changes = {}
    for flag, field, value in (("--telemetry-delay-s", "telemetry_delay_s", telemetry_delay_s),
                               ("--telemetry-jitter-s", "telemetry_jitter_s", telemetry_jitter_s),
                               ("--command-delay-s", "command_delay_s", command_delay_s),
                               ("--command-jitter-s", "command_jitter_s", command_jitter_s)):
        if value is not None:
            link_changes[field] = _check_s(flag, value)
    if loss is not None:
        if not (math.isfinite(loss) and 0.0 <= loss <= 1.0):
            raise ValueError(f"--loss must be a probability in [0, 1], got {loss!r}")
        link_changes["loss_probability"] = float(loss)
    link = dataclasses.replace(base.link, **link_changes)
    for what, delay, jitter in (("telemetry", link.telemetry_delay_s, link.telemetry_jitter_s),
                                ("command", link.command_delay_s, link.command_jitter_s)):
        if jitter > delay:
            raise ValueError(f"--{what}-jitter-s {jitter:g} exceeds --{what}-delay-s {delay:g} "
                             "(the delay would go negative)")
    est = base.estimator
    if estimate_latency_s is not None:
        est = dataclasses.replace(est, latency_s=_check_s("--estimate-latency-s", estimate_latency_s))
    if estimator_scale is not None:
        if not (math.isfinite(estimator_scale) and 0.0 <= estimator_scale <= 100.0):
            raise ValueError(f"--estimator-scale must be a number in [0, 100], got {estimator_scale!r}")
        est = est.scaled(float(estimator_scale))
    return WorldPreset(name, link, est, _airframe(base.airframe, wind_speed_m_s, wind_from_deg,
                                                  thrust_scale, linear_drag_xyz_n_s_per_m,
                                                  parasitic_drag_xyz_n_s2_per_m2), overrides)


def _airframe(base: AirframeParams, wind_speed_m_s, wind_from_deg, thrust_scale,
              linear_drag, parasitic_drag) -> AirframeParams:
    changes = {}
    if wind_speed_m_s is not None:
        if not (math.isfinite(wind_speed_m_s) and 0.0 <= wind_speed_m_s <= 30.0):
            raise ValueError(f"--wind-speed-m-s must be a number in [0, 30], got {wind_speed_m_s!r}")
        changes["wind_speed_m_s"] = float(wind_speed_m_s)
    if wind_from_deg is not None:
        if not math.isfinite(wind_from_deg):
            raise ValueError(f"--wind-from-deg must be a finite number, got {wind_from_deg!r}")
        changes["wind_from_deg"] = float(wind_from_deg) % 360.0
    if thrust_scale is not None:
        if not (math.isfinite(thrust_scale) and 0.5 <= thrust_scale <= 1.5):
            raise ValueError(f"--thrust-scale must be a number in [0.5, 1.5], got {thrust_scale!r}")
        changes["thrust_scale"] = float(thrust_scale)
    for flag, field, vec in (("--drag-n-s-per-m", "linear_drag_xyz_n_s_per_m", linear_drag),
                             ("--parasitic-drag-n-s2-per-m2", "parasitic_drag_xyz_n_s2_per_m2", parasitic_drag)):
        if vec is not None:
            vec = tuple(float(v) for v in vec)
            if len(vec) != 3 or not all(math.isfinite(v) and 0.0 <= v <= 100.0 for v in vec):
                raise ValueError(f"{flag} needs three numbers in [0, 100], got {vec!r}")
            changes[field] = vec
    return dataclasses.replace(base, **changes)
