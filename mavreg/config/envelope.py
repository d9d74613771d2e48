"""The flight envelope: the bounds the daemon holds a flight to, and how it recovers.

Nested in the controller YAML as an optional ``envelope:`` section (every key optional;
a phase's bounds, when given, are given whole). Every default is the choice of a careful
pilot, with its reason next to it; docs/safety.md states them all with the figures they
were checked against: the clean barrel roll in lockstep and in real time, and a hover
with an estimator's noise (5 mm position, 2 cm/s velocity), a 12 ms delay and 1 % loss,
none of which comes near any bound.

Frames and units: NED, SI inside; angles are radians inside and degrees in the YAML
(``max_attitude_error_deg`` for ``max_attitude_error_rad``). Altitudes and the geofence
are relative to the take-off point.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .ranges import (ACCEL_M_S2, ANGLE_DEG, BODY_RATE_RAD_S, DISTANCE_M, DURATION_S, FORCE_N, GAIN_1_S,
                     MAX_GEOFENCE_M, SHARE, SPEED_M_S, within)

# Every number's range: mavreg.config.ranges (a shared range's reason is given there).

__all__ = ["PhaseBounds", "GateParams", "RecoveryParams", "EnvelopeParams", "MAX_GEOFENCE_M"]



@dataclass(frozen=True)
class PhaseBounds:
    """Tracking bounds of one flight phase (given whole in the YAML: no partial defaults).

    In the maneuver the position error is the distance from the path, ``|(w1, w2)|``;
    elsewhere the distance from the hover LQR's reference point. The attitude error is
    the angle of the rotation from the reference attitude to the vehicle's (from rotation
    matrices, valid at any attitude). The rate error is ``|omega - omega_ref|``.
    """

    max_position_error_m: float = field(metadata=DISTANCE_M)
    max_attitude_error_rad: float = field(metadata=ANGLE_DEG)
    max_rate_error_rad_s: float = field(metadata=BODY_RATE_RAD_S)
    max_saturated_share: float = field(metadata=SHARE)
    """Largest share of control steps with a rotor command clipped (at 0 or at the
    maximum) over ``EnvelopeParams.saturation_window_s``."""


_TAKEOFF = PhaseBounds(1.0, math.radians(20.0), 2.0, 0.2)
_HOLD = PhaseBounds(0.5, math.radians(15.0), 1.5, 0.2)
_RUN_IN = PhaseBounds(0.5, math.radians(20.0), 2.0, 0.2)
_MANEUVER = PhaseBounds(0.5, math.radians(30.0), 3.0, 0.5)
_LAND = PhaseBounds(0.5, math.radians(15.0), 1.5, 0.2)


@dataclass(frozen=True)
class GateParams:
    """The health gate: what the hold before ``run_in`` must show before a maneuver starts."""

    window_s: float = field(default=1.0, metadata=DURATION_S)
    """The gate judges the last second of the hold (after the move to the hold point)."""
    max_position_error_m: float = field(default=0.15, metadata=DISTANCE_M)
    """A hover LQR that cannot hold its point within 15 cm will not hand a clean entry to
    the regulator (clean holds: under 1 cm)."""
    max_attitude_error_rad: float = field(default=math.radians(5.0), metadata=ANGLE_DEG)
    """A level hover is level: 5 deg is far above an estimator's attitude noise."""
    max_rotor_hp_sd_n: float = field(default=0.5, metadata=FORCE_N)
    """High-pass SD of each rotor command (first differences / sqrt 2): chattering.
    Estimator noise gives about 0.15 N (unit test); 0.5 N is about 4 % of the rotor."""
    max_thrust_ratio_error: float = field(default=0.2, metadata=within(1e-3, 10.0))  # 0.1 % to 11 x the weight
    """``|mean collective command / design weight - 1|``: the plan's feasibility was
    checked on the design mass; a hold that needs 20 % more thrust has lost that margin
    (a heavier vehicle or weaker rotors)."""
    timeout_s: float = field(default=5.0, metadata=DURATION_S)
    """How long the hold may take to pass the gate before the maneuver is refused."""
    max_link_delay_s: float = field(default=0.075, metadata=within(1e-4, 1.0))  # a lockstep link to 1 s
    """Sample-to-actuation delay the controller tolerates. With prediction across the delay
    (``predict_delay``, params/controller/realistic.yaml) the barrel roll stays within 2 cm up to
    60 ms of round trip on the design model and on the emulator (docs/robustness.md, delay
    sweep), which TIMESYNC measures as up to 63 ms (period quantization); 75 ms leaves the
    prediction (capped at 0.1 s) room for the estimate's latency. Without prediction a few
    milliseconds already cost centimetres and 20 ms diverges: paper_lqr.yaml sets 5 ms."""
    max_link_jitter_s: float = field(default=0.01, metadata=within(1e-4, 1.0))  # as the delay
    """Delay jitter (SD) the regulator tolerates: 5 control periods at 500 Hz."""


@dataclass(frozen=True)
class RecoveryParams:
    """The recovery controller (:mod:`mavreg.control.controllers.recovery`) and its success criteria."""

    safe_altitude_m: float = field(default=3.0, metadata=DISTANCE_M)
    """Climb to at least this altitude above the take-off point, then hold."""
    max_tilt_rad: float = field(default=math.radians(35.0), metadata=within(1.0, 80.0, deg=True))
    """Largest tilt of the desired thrust direction: keeps 80 % of the thrust vertical."""
    max_climb_m_s: float = field(default=2.0, metadata=SPEED_M_S)
    max_descent_m_s: float = field(default=1.0, metadata=SPEED_M_S)
    max_hold_speed_m_s: float = field(default=1.0, metadata=SPEED_M_S)
    """Horizontal speed while returning to the point where braking ended."""
    max_accel_up_m_s2: float = field(default=12.0, metadata=ACCEL_M_S2)
    """Desired upward acceleration at most: 2.2 g of thrust, half of what the rotors give."""
    max_accel_down_m_s2: float = field(default=6.0, metadata=within(0.1, 9.0))
    """Desired downward acceleration at most: under g, so the thrust stays above 1/3 of the
    weight and the rotors keep their torque authority."""
    position_gain_1_s: float = field(default=1.0, metadata=GAIN_1_S)
    velocity_gain_1_s: float = field(default=3.0, metadata=GAIN_1_S)
    integral_gain_1_s: float = field(default=1.0, metadata=within(0.0, GAIN_1_S["max"]))
    """Integral of the vertical velocity error, integrated only while the vertical demand is
    not saturated (transients do not wind it up): a vehicle 40 % heavier than the design
    still holds its altitude."""
    attitude_bandwidth_rad_s: float = field(default=12.0, metadata=GAIN_1_S)
    """Roll/pitch natural frequency on the design inertia (three times the inertia still
    leaves 7 rad/s, damped 0.58)."""
    attitude_damping: float = field(default=1.0, metadata=within(0.05, 10.0))  # ringing to sluggish
    yaw_bandwidth_rad_s: float = field(default=3.0, metadata=GAIN_1_S)
    """Yaw is weak (drag torque): a slower loop that rarely saturates."""
    brake_speed_m_s: float = field(default=0.5, metadata=SPEED_M_S)
    """Braking ends (and the horizontal hold point is set) below this horizontal speed."""
    settled_attitude_error_rad: float = field(default=math.radians(10.0), metadata=ANGLE_DEG)
    """Settled: within this of the desired attitude (level, or tilted into a steady wind)."""
    settled_rate_rad_s: float = field(default=0.5, metadata=BODY_RATE_RAD_S)
    settled_speed_m_s: float = field(default=0.5, metadata=SPEED_M_S)
    settled_altitude_error_m: float = field(default=0.5, metadata=DISTANCE_M)
    settle_s: float = field(default=1.0, metadata=DURATION_S)
    """Recovered: braked, on its attitude, not rotating, slow and at the altitude for this long."""
    timeout_s: float = field(default=8.0, metadata=DURATION_S)
    """Not recovered within this time (vehicle time): the recovery controller lands where it
    is (docs/safety.md). A recovery is judged over this time, never by one sample: from
    inverted at 8 m/s the controller settles in about 3 s (unit test)."""
    max_body_rate_rad_s: float = field(default=30.0, metadata=BODY_RATE_RAD_S)
    """Absolute body-rate bound during a recovery: turning over at full torque peaks near
    25 rad/s; 2000 deg/s (35 rad/s) is a common gyro's range, past which the rates reported
    are meaningless."""
    geofence_margin_m: float = field(default=10.0, metadata=within(0.0, MAX_GEOFENCE_M))
    """The geofence grows by this much during a recovery: braking from 8 m/s takes 5 m."""
    max_recoveries: int = field(default=2, metadata=within(0, 100))  # 100: a flight of nothing else
    """Recoveries per flight; one more violation in the air: the recovery controller lands."""


@dataclass(frozen=True)
class EnvelopeParams:
    """Every bound of the envelope monitor, the gate and the recovery (see docs/safety.md)."""

    takeoff: PhaseBounds = field(default_factory=lambda: _TAKEOFF)
    """Looser in position: the climb's reference runs ahead of a vehicle that lifts late."""
    hold: PhaseBounds = field(default_factory=lambda: _HOLD)
    run_in: PhaseBounds = field(default_factory=lambda: _RUN_IN)
    maneuver: PhaseBounds = field(default_factory=lambda: _MANEUVER)
    """0.5 m: a third of the barrel roll's radius, 100x the clean flight's 0.4 cm; the
    LQR was linearized about the path. 30 deg and 3 rad/s leave the same kind of margin;
    saturation half of the time is allowed (the paper's runs saturate at 7 N)."""
    land: PhaseBounds = field(default_factory=lambda: _LAND)
    min_altitude_m: float = field(default=1.0, metadata=DISTANCE_M)
    """Altitude floor in hold, run-in and maneuver: 1 m leaves room to brake from a
    2 m/s descent at 2 m/s^2. A plan that goes lower is refused at the gate."""
    geofence_half_width_m: tuple[float, ...] = field(default=(50.0, 50.0), metadata={"length": 2, **DISTANCE_M})
    """North and east half-widths of the box around the take-off point."""
    geofence_ceiling_m: float = field(default=30.0, metadata=DISTANCE_M)
    max_body_rate_rad_s: float = field(default=20.0, metadata=BODY_RATE_RAD_S)
    """Absolute, every phase but the recovery (``recovery.max_body_rate_rad_s``): 1150 deg/s
    is a tumble (the barrel roll peaks at about 6 rad/s)."""
    tube_exit_s: float = field(default=0.05, metadata=DURATION_S)
    """The projection on the path not unique for this long: s is no longer meaningful."""
    min_progress_m_s: float = field(default=0.05, metadata=within(0.0, SPEED_M_S["max"]))
    """ds/dt below this counts as stuck (plans fly at 0.2 m/s or more)."""
    max_stall_s: float = field(default=4.0, metadata=DURATION_S)
    """Stuck (or carried back) for this long: the maneuver is given up. A gust against a slow
    vehicle carries it back along the path by design: the speed governor gives way instead
    of tilting against it, and the vehicle resumes where it is. The paper's 8 N, 1 s gust at
    0.75 m/s carries it back 1.6 m and it resumes 2.5-3 s after the gust began (1 s gave up
    every such flight)."""
    progress_window_s: float = field(default=0.2, metadata=DURATION_S)
    """ds/dt is measured over this window (estimator noise averages out)."""
    saturation_window_s: float = field(default=0.5, metadata=DURATION_S)
    impact_altitude_m: float = field(default=0.2, metadata=DISTANCE_M)
    """'At the ground' for the impact detector (an estimate's altitude error is cm)."""
    impact_descent_m_s: float = field(default=1.5, metadata=SPEED_M_S)
    """Descending faster than this at the ground is an impact (landing sinks at 0.3 m/s)."""
    impact_speed_m_s: float = field(default=3.0, metadata=SPEED_M_S)
    """Moving faster than this at the ground is an impact (the emulator's crash speed)."""
    impact_accel_m_s2: float = field(default=150.0, metadata=ACCEL_M_S2)
    """An acceleration spike: twice what the rotors and gravity can produce on the design
    vehicle (4 x 12 N / 0.749 kg + g = 74 m/s^2)."""
    accel_window_s: float = field(default=0.02, metadata=DURATION_S)
    """Acceleration is measured from velocities at least this far apart (noise / 10)."""
    max_position_jump_m: float = field(default=0.25, metadata=DISTANCE_M)
    """A position change that the reported velocity does not explain, beyond what the
    largest acceleration could add: a jump of the estimate."""
    thrust_window_s: float = field(default=0.1, metadata=DURATION_S)
    thrust_check_min_ratio: float = field(default=1.2, metadata=within(0.1, 100.0))  # of the weight
    """The thrust check applies while the mean collective command is above this
    multiple of the design weight; above the vehicle's thrust-to-weight it never applies (the
    experiments' saturation runs turn it off with 100, :data:`mavreg.experiments.via_sitl.EXPERIMENT_ENVELOPE`)."""
    min_thrust_ratio: float = field(default=0.5, metadata=SHARE)
    """Measured thrust (design mass x specific force along body -z) below this share of
    the commanded: the rotors are not doing what they are told, or the telemetry lies."""
    thrust_mismatch_s: float = field(default=0.3, metadata=DURATION_S)
    maneuver_gap_s: float = field(default=0.1, metadata=DURATION_S)
    """No complete sample for this long in run-in or maneuver (0.8 m of travel at 8 m/s):
    the regulation is given up for the recovery."""
    max_touchdown_speed_m_s: float = field(default=1.0, metadata=SPEED_M_S)
    """A landing is a landing when the descent at touchdown is under this."""
    gate: GateParams = field(default_factory=GateParams)
    recovery: RecoveryParams = field(default_factory=RecoveryParams)

    def bounds(self, phase: str) -> PhaseBounds | None:
        """The tracking bounds of ``phase`` (None where there are none)."""
        return {"takeoff": self.takeoff, "hold": self.hold, "run_in": self.run_in,
                "maneuver": self.maneuver, "land": self.land}.get(phase)
