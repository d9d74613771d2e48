"""The disturbance observer's settings: an optional ``disturbance:`` section of the controller YAML.

What the observer estimates and why each default is what it is: docs/robustness.md,
"Disturbances". Units are SI; the names carry them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .ranges import (BODY_RATE_RAD_S, DURATION_S, FORCE_N, LINEAR_DRAG_N_S_PER_M, RATE_NOISE_RAD_S,
                     ROTOR_TIME_CONSTANT_S, SPEED_M_S, TORQUE_N_M, WANDER_TIME_S, within)

__all__ = ["DisturbanceParams", "RotorLagParams", "TorqueBiasParams"]

_LENGTH = within(1e-6, 2.0)
"""A centre-of-mass offset (torque per thrust): a micrometre to the longest arm."""
_DRAG = within(1e-4, LINEAR_DRAG_N_S_PER_M["max"])
"""A drag uncertainty or bound, up to the largest linear drag of a vehicle file."""
_RATE = within(1e-6, 1e4)
"""How fast a compensation may follow its estimate, per second: from hardly at all to at once."""


@dataclass(frozen=True)
class TorqueBiasParams:
    r"""The torque part of the observer (:mod:`mavreg.control.estimation.torque_bias`): a body torque the
    design model does not know, :math:`\tau_b = t_0 + t_1 T` per axis (``torque_bias:``
    inside ``disturbance:``; docs/robustness.md, "Torque bias").

    The collective-proportional :math:`t_1` (N m per N of thrust: a length) models a
    centre-of-mass offset exactly and rotors of unequal thrust to first order, and is
    observable as soon as the rotors lift. The constant :math:`t_0` is off by default: in a
    hover the thrust hardly varies and the two cannot be told apart, and no cause the mismatch
    draws is constant in thrust.
    """

    enabled: bool = False
    """Estimate the torque bias, predict with it and subtract it from the commanded torques."""
    per_thrust_sd_m: float = field(default=0.01, metadata=_LENGTH)
    """:math:`t_1`, per axis: a 1 cm centre-of-mass offset is 0.01 m; 8 % of thrust between
    opposite rotors on 0.3 m arms is 0.006 m."""
    constant_sd_n_m: float = field(default=0.0, metadata=TORQUE_N_M)
    """:math:`t_0`, per axis (0: not estimated)."""
    tau_s: float = field(default=10000.0, metadata=WANDER_TIME_S)
    """Both wander by their SD over this time. A build's biases do not change in flight, so
    the estimate is in effect the average of all it has learned: about 0.1 mm of noise on
    :math:`t_1` after the take-off and hold. At 20 s it wandered by 0.4 mm on the nominal
    airframe, 0.015 N m at the loop's thrust, which flew the realistic barrel roll's loop
    3.9 cm off instead of 2.5 (2.7 at 10000 s)."""
    rate_noise_rad_s: float = field(default=0.01, metadata=RATE_NOISE_RAD_S)
    """SD of the error of one body-rate sample's change over one period, the measurement
    (a gyro's 0.005 rad/s of white noise per sample, twice)."""
    learning_max_rate_rad_s: float = field(default=1.0, metadata=BODY_RATE_RAD_S)
    """The bias is learned only while the body rate is under this. Faster, the rate
    innovations are mostly what the file's inertia and rotor lag get wrong (they scale with
    the torques commanded and their changes), not a bias: learned through the barrel roll's
    loop, the estimate followed them and left the run-out 12 cm off the path."""
    max_per_thrust_m: float = field(default=0.03, metadata=_LENGTH)
    """Bound of each :math:`t_1`."""
    max_constant_n_m: float = field(default=0.2, metadata=within(1e-6, TORQUE_N_M["max"]))
    """Bound of each :math:`t_0`."""
    max_per_thrust_rate_m_per_s: float = field(default=0.01, metadata=_RATE)
    """The compensation follows :math:`t_1` at most this fast (the prediction uses the
    estimate as it is): 0.01 m/s is 0.07 N m per second in a hover."""
    max_constant_rate_n_m_per_s: float = field(default=0.07, metadata=_RATE)


@dataclass(frozen=True)
class RotorLagParams:
    r"""The rotor-lag part of the observer (:mod:`mavreg.control.estimation.lag_observer`): the rotors'
    time constant :math:`\tau`, learned in flight from the body rates (``rotor_lag:`` inside
    ``disturbance:``; docs/robustness.md, "Rotor lag"). The prediction lags the commands by
    the estimate; the regulator's feedforward leads by its follower. The gains stay those the
    plan was designed with.
    """

    enabled: bool = False
    """Estimate the time constant and predict and lead with it (False: the vehicle file's)."""
    sd_s: float = field(default=0.02, metadata=within(1e-4, ROTOR_TIME_CONSTANT_S["max"]))
    """The file's value is this uncertain (motors of 10 to 50 ms around a file's 20 to 30)."""
    tau_s: float = field(default=10000.0, metadata=WANDER_TIME_S)
    """The time constant wanders by ``sd_s`` over this time: a build's motors do not change
    in flight, so the estimate is the average of all it has learned."""
    rate_noise_rad_s: float = field(default=0.01, metadata=RATE_NOISE_RAD_S)
    """SD of the error of one body-rate sample's change over one period (as the torque
    part's)."""
    learning_max_rate_rad_s: float = field(default=1.0, metadata=BODY_RATE_RAD_S)
    """Learned only while the body rate is under this (faster, the rate innovations are
    mostly what the file's inertia gets wrong)."""
    bounds_s: tuple[float, ...] = field(default=(0.005, 0.1), metadata={"length": 2, **ROTOR_TIME_CONSTANT_S})
    """The estimate stays within these (s)."""
    max_rate_s_per_s: float = field(default=0.02, metadata=_RATE)
    """The regulator's lead follows the estimate at most this fast (20 ms per second)."""

    def __post_init__(self):
        lo, hi = self.bounds_s
        if not lo < hi:
            raise ValueError(f"rotor_lag bounds_s {self.bounds_s} must be increasing")


@dataclass(frozen=True)
class DisturbanceParams:
    """A Kalman filter on the airframe's unknown force model (:mod:`mavreg.control.estimation.disturbance`).

    Each parameter is a random walk that wanders by its ``*_sd`` over its ``*_tau_s``; the
    initial uncertainty is the same SD. The estimate is bounded by the ``max_*`` values.
    """

    enabled: bool = False
    """Estimate, predict with, and compensate the disturbance (False: the design model only)."""
    force_sd_n: float = field(default=1.0, metadata=FORCE_N)
    """A constant horizontal external force (the steady part of a wind), per axis."""
    vertical_force_sd_n: float = field(default=0.0, metadata=within(0.0, FORCE_N["max"]))
    """A constant vertical force. 0 (the default) leaves it out: in hover it cannot be told
    from a thrust scale error, and a battery's sag or a payload is far more common than a
    steady vertical wind; the thrust scale, learned in hover, then holds at 4 g in a loop."""
    force_tau_s: float = field(default=10.0, metadata=WANDER_TIME_S)
    drag_sd_n_s_per_m: float = field(default=0.3, metadata=_DRAG)
    """Linear body drag, (c_xy, c_z), on top of the vehicle file's."""
    drag_tau_s: float = field(default=20.0, metadata=WANDER_TIME_S)
    thrust_scale_sd: float = field(default=0.05, metadata=within(1e-4, 0.5))  # 0.01 % to half the thrust
    """The rotors' thrust per unit commanded, on top of the vehicle file's calibration."""
    thrust_scale_tau_s: float = field(default=20.0, metadata=WANDER_TIME_S)
    velocity_noise_m_s: float = field(default=0.004, metadata=within(1e-5, 1.0))  # 10 um/s to 1 m/s a period
    """SD of the error of one velocity sample's change over one period, the filter's
    measurement (an estimate's velocity error of 2 cm/s correlated over 0.2 s changes by
    about 3 mm/s per 2 ms period)."""
    drag_learning_min_speed_m_s: float = field(default=2.0, metadata=within(0.0, SPEED_M_S["max"]))
    """The drag is learned only above this speed. Slower, the velocity is mostly the
    estimator's error and the controller's answer to it, which biases a closed-loop fit
    (in hover the drag estimate doubled in 20 s); the drag's force is small there anyway."""
    thrust_scale_learning_max_axial_speed_m_s: float = field(default=0.5, metadata=within(0.0, SPEED_M_S["max"]))
    """The thrust scale is learned only while the velocity along the thrust axis is under
    this. Along that axis a thrust scale error and the axial drag push alike: in a 2 m/s
    take-off climb (under ``drag_learning_min_speed_m_s``, so the drag is not learned) the
    axial drag read as a thrust scale of 0.86 (truth 1.00), the commands grew by 16 % and
    the attitude loop rang until the rate bound fired at 9 m. Hover and level flight, where
    the scale is learned, are well under it."""
    max_force_rate_n_per_s: float = field(default=2.5, metadata=_RATE)
    """The compensation follows the estimate at most this fast (the prediction uses the
    estimate as it is): a force estimate that settles in 0.1 s would tilt the hover
    reference by 8 deg per newton at once, a rate error the envelope stops."""
    max_drag_rate_n_s_per_m_per_s: float = field(default=0.5, metadata=_RATE)
    max_thrust_scale_rate_per_s: float = field(default=0.1, metadata=_RATE)
    max_compensation_turn_rad: float = field(default=math.radians(15.0),
                                             metadata=within(0.1, 90.0, deg=True))
    """The compensation turns the nominal attitude by at most this much (YAML
    ``max_compensation_turn_deg``); the rest of the force is left to the feedback. The gains
    hold near the attitude they were designed at: in a 3 m/s crosswind the barrel roll's
    exit, at 5.8 N of thrust against 3.4 N of drag and wind, would turn 30 deg, and the
    run-out lost the path."""
    max_force_n: float = field(default=4.0, metadata=FORCE_N)
    """Bound of each force component."""
    max_drag_n_s_per_m: float = field(default=1.5, metadata=_DRAG)
    thrust_scale_bounds: tuple[float, ...] = field(default=(0.7, 1.3),  # a tenth to ten times
                                                  metadata={"length": 2, **within(0.1, 10.0)})
    max_sample_gap_s: float = field(default=0.05, metadata=DURATION_S)
    """Samples further apart than this are not compared (a gap restarts the comparison)."""
    torque_bias: TorqueBiasParams = field(default_factory=TorqueBiasParams)
    """The torque part (:class:`TorqueBiasParams`); off by default."""
    rotor_lag: RotorLagParams = field(default_factory=RotorLagParams)
    """The rotor-lag part (:class:`RotorLagParams`); off by default."""

    def __post_init__(self):
        lo, hi = self.thrust_scale_bounds
        if not lo < 1.0 < hi:
            raise ValueError(f"thrust_scale_bounds {self.thrust_scale_bounds} must bracket 1")
