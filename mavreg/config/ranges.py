"""The physical ranges of the vehicle and controller files' numbers (issue 32, item 4).

Every number of a vehicle or controller file has a lower and an upper bound from what a
multirotor this service flies can be, not only a sign: a ``mass_kg`` of 1e-300 passed the
sign check and ended in a Riccati solver's traceback. The bounds are field metadata
(``min``/``max``, each element of a vector), so the one loader checks them in one place
(:func:`mavreg.config.loader.load_text`) and its message names the file, the key, the value
and the range. Cross-field physics (thrust-to-weight, the inertia's triangle inequality,
two-sided bounds in order) stays in each schema's ``__post_init__``.

A range used by more than one field lives here, with why; a field's own range is written
beside it with :func:`within` and a comment. Bounds are generous on purpose: they refuse
what no airframe can be and what would break the numerics, never a plausible vehicle.
"""
from __future__ import annotations

__all__ = ["within", "MAX_GEOFENCE_M", "MAX_SPEED_M_S", "MASS_KG", "INERTIA_KG_M2",
           "INERTIA_PRODUCT_KG_M2", "ARM_M", "DRAG_TORQUE_RATIO_M", "ROTOR_THRUST_N",
           "ROTOR_TIME_CONSTANT_S", "LINEAR_DRAG_N_S_PER_M", "PARASITIC_DRAG_N_S2_PER_M2",
           "FORCE_N", "TORQUE_N_M", "BODY_RATE_RAD_S", "LQR_WEIGHT", "LQR_WEIGHT_OR_ZERO",
           "DURATION_S", "WANDER_TIME_S", "DISTANCE_M", "SPEED_M_S", "ACCEL_M_S2", "GAIN_1_S",
           "ANGLE_DEG", "SHARE", "RATE_NOISE_RAD_S"]


def within(lo: float, hi: float, **more) -> dict:
    """Field metadata bounding a number (each element of a vector) to ``[lo, hi]``."""
    assert lo < hi, (lo, hi)
    return {"min": lo, "max": hi, **more}


MAX_GEOFENCE_M = 1000.0
"""The widest geofence (half width and ceiling) a controller file may set: beyond a
kilometre the local NED frame of a maneuver and an offboard link's range both stop
making sense. Maneuver files are bounded by it too (:mod:`mavreg.config.maneuver`)."""
MAX_SPEED_M_S = 50.0
"""180 km/h: above any quadrotor's top speed."""

# -- the airframe -------------------------------------------------------------------------

MASS_KG = within(0.01, 100.0)
"""10 g (under the lightest flying micro quadrotors, 20-30 g) to 100 kg (heavy-lift)."""
ARM_M = within(0.02, 2.0)
"""2 cm (a 65 mm-wheelbase micro's arms are 3 cm) to 2 m (a 4 m heavy-lift frame)."""
INERTIA_KG_M2 = within(1e-7, 400.0)
"""Up to all of 100 kg at the tips of 2 m arms (m l^2 = 400); down to a 10 g frame on 2 cm
arms with a fortieth of its mass at the tips (a Crazyflie's 27 g: 1.4e-5)."""
INERTIA_PRODUCT_KG_M2 = within(-400.0, 400.0)
"""No larger than the largest principal moment (the emulator also requires the whole
matrix positive definite: firmware_sim.physics.inertia_matrix)."""
DRAG_TORQUE_RATIO_M = within(5e-4, 0.2)
"""k = c_Q / c_T, about 0.06 propeller diameters: 2 mm for 31 mm propellers, 0.016 m for
10-inch ones, 0.1 m for 1.5 m ones; below 0.5 mm the yaw has no authority to design on."""
ROTOR_THRUST_N = within(0.05, 500.0)
"""5 g of thrust (a micro motor gives 15-30 g) to 50 kgf (the largest heavy-lift motors)."""
ROTOR_TIME_CONSTANT_S = within(0.0, 0.5)
"""0: ideal rotors; heavy-lift rotors answer in 0.1-0.2 s, and past 0.5 s no attitude loop
can be closed through them."""
LINEAR_DRAG_N_S_PER_M = within(0.0, 100.0)
"""Force per speed: PX4 SIH's 1 kg frame has 1 N s/m; 100 kg with the same 1 s of velocity
decay is 100."""
PARASITIC_DRAG_N_S2_PER_M2 = within(0.0, 10.0)
"""rho C_d A / 2: a 4 m^2 heavy-lift frame at C_d 2 is 5 N s^2/m^2."""
FORCE_N = within(1e-3, 2000.0)
"""A milli-newton to four of the largest rotors (4 x 500 N)."""
TORQUE_N_M = within(0.0, 1000.0)
"""Up to the largest rotor on the longest arm (500 N x 2 m)."""
BODY_RATE_RAD_S = within(0.01, 35.0)
"""A gyro's noise floor to 2000 deg/s (35 rad/s), a common gyro's range, past which the rates
reported are meaningless."""
RATE_NOISE_RAD_S = within(1e-5, 1.0)
"""SD of a body-rate sample's change: a navigation-grade gyro to no measurement left."""

# -- the controller -------------------------------------------------------------------------

LQR_WEIGHT = within(1e-6, 1e6)
"""A diagonal LQR weight: positive (every coordinate weighed, so the Riccati equation has a
stabilizing solution) and finite within twelve decades, so that the ratio of any two
weights (at most 1e12) leaves the Riccati solvers digits to work with (the bundled files
use 0.1 to 10 000)."""
LQR_WEIGHT_OR_ZERO = within(0.0, 1e6)
"""A weight that may be 0 (a coordinate left out where another weight covers it)."""

# -- the envelope, the gate, the recovery and the observers ---------------------------------

DURATION_S = within(1e-3, 600.0)
"""Windows, timeouts, settling times: a 1 kHz control period to ten minutes, past any
maneuver's length (a longer window keeps samples without end in a long hold)."""
WANDER_TIME_S = within(0.01, 1e7)
"""A random walk's time to wander by its SD: from a few control periods to 4 months, a
constant in effect (the observers' 10 000 s default)."""
DISTANCE_M = within(1e-3, MAX_GEOFENCE_M)
"""A millimetre (an estimator's noise) to the widest geofence."""
SPEED_M_S = within(0.01, MAX_SPEED_M_S)
"""1 cm/s (hovering) to 180 km/h (above any quadrotor's top speed)."""
ACCEL_M_S2 = within(0.01, 1000.0)
"""0.001 g to 100 g (a crash's spike; an accelerometer's range is 16-32 g)."""
GAIN_1_S = within(0.01, 300.0)
"""Gains and bandwidths, 1/s: a 100 s response to one of 3 ms, which a 500 Hz loop still
resolves."""
ANGLE_DEG = within(0.1, 180.0, deg=True)
"""An attitude error or angle bound, degrees in the YAML: 0.1 deg (an estimator's noise) to
180 deg (any rotation)."""
SHARE = within(0.0, 1.0)
"""A share, 0 to 1."""
