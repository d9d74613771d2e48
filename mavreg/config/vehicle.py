"""Vehicle parameters: what the controller is designed on, and what only the emulator knows."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from .loader import ConfigError, load_file
from .ranges import (ARM_M, BODY_RATE_RAD_S, DRAG_TORQUE_RATIO_M, INERTIA_KG_M2, INERTIA_PRODUCT_KG_M2,
                     LINEAR_DRAG_N_S_PER_M, MASS_KG, PARASITIC_DRAG_N_S2_PER_M2, ROTOR_THRUST_N,
                     ROTOR_TIME_CONSTANT_S, within)

__all__ = ["EmulatorParams", "RateInterfaceParams", "VehicleParams", "load_vehicle", "G", "OUTPUTS", "with_output",
           "DIALECTS", "with_dialect"]

G = 9.81
"""Gravity (m/s^2), along +z (down) of NED."""

OUTPUTS = ("rotors", "rates")
"""What the daemon commands: rotor forces (SET_ACTUATOR_CONTROL_TARGET), or body rates and
a collective thrust (SET_ATTITUDE_TARGET), which stock autopilots take (docs/autopilots.md)."""

DIALECTS = ("px4", "ardupilot")
"""Mode layouts a vehicle that announces MAV_AUTOPILOT_GENERIC (custom firmware) can be flown
with: PX4's (OFFBOARD, custom main mode 6) or ArduCopter's (GUIDED, 4). Stock PX4 and
ArduPilot are known from their HEARTBEAT (docs/autopilots.md, *Which dialect*)."""


@dataclass(frozen=True)
class EmulatorParams:
    """Physics that only firmware_sim models; the controller is never designed on it."""

    true_rotor_time_constant_s: float | None = field(
        default=None, metadata={"was": "rotor_time_constant_s", **ROTOR_TIME_CONSTANT_S})
    """The emulated rotors' true first-order thrust lag where it differs from the file's
    ``rotor_time_constant_s`` (a mismatch the controller is not told; None: the file's value,
    :attr:`VehicleParams.true_rotor_time_constant_s`)."""
    rotor_noise_sd_n: float = field(default=0.0, metadata=within(0.0, 50.0))
    """Standard deviation of the Gaussian noise on each rotor's thrust (at most a tenth of the
    largest rotor's 500 N)."""
    linear_drag_xyz_n_s_per_m: tuple[float, ...] = field(
        default=(0.0, 0.0, 0.0), metadata={"length": 3, "was": "linear_drag_n_s_per_m", **LINEAR_DRAG_N_S_PER_M}
    )
    """Linear drag per body axis x, y, z (force = -c * v_air_body, per axis); the controller's
    model has the rotor plane's and the thrust axis' (``rotor_drag_n_s_per_m``)."""
    parasitic_drag_xyz_n_s2_per_m2: tuple[float, ...] = field(
        default=(0.0, 0.0, 0.0), metadata={"length": 3, "was": "parasitic_drag_n_s2_per_m2",
                                           **PARASITIC_DRAG_N_S2_PER_M2}
    )
    """Quadratic (parasitic) drag per body axis: force = -c * |v_air| * v_air_body, per axis;
    the controller's model has one coefficient (``parasitic_drag_n_s2_per_m2``)."""
    thrust_scale: float = field(default=1.0, metadata={"min": 0.5, "max": 1.5})
    """Thrust each rotor gives per unit commanded (0.9: a battery sagged to 90 %); the
    saturation scales with it."""
    inertia_offdiag_kg_m2: tuple[float, ...] = field(default=(0.0, 0.0, 0.0),
                                                 metadata={"length": 3, **INERTIA_PRODUCT_KG_M2})
    """Products of inertia (Jxy, Jxz, Jyz) the design model neglects."""
    crash_speed_m_s: float = field(default=3.0, metadata=within(0.1, 100.0))
    """Touching the ground faster than this is a crash (0.1 m/s is a landing; 100 m/s: no crash
    detection, for a test of the daemon's own impact detector)."""


@dataclass(frozen=True)
class RateInterfaceParams:
    r"""How the vehicle's own autopilot takes body rates and a collective thrust
    (``output: rates``), as ``mavreg identify`` measures it (docs/autopilots.md).

    The autopilot's rate loop is modelled as a pure delay then a first-order response,
    :math:`\dot\omega(t) = (\omega_c(t - d) - \omega(t))/\tau_\omega`; its normalized
    thrust t in [0, 1] gives the collective
    :math:`F = F_{max}\,((1 - e)\,t + e\,t^2)`, with :math:`F_{max}` fixed by the hover
    thrust: :math:`m g = F_{max}((1 - e) t_h + e t_h^2)`.
    """

    hover_thrust: float = field(metadata=within(0.02, 0.95))
    """Normalized thrust t_h that holds the file's ``mass_kg`` in a level hover (0.02: a
    thrust-to-weight of 50 on a linear map; 0.95: 5 % of the thrust left to climb and steer)."""
    thrust_expo: float = field(default=0.0, metadata={"min": 0.0, "max": 1.0})
    """e of the thrust map: the curvature the autopilot leaves in its thrust command (0: the
    autopilot linearizes its motors' thrust, as ArduPilot with ``MOT_THST_EXPO`` does)."""
    rate_time_constant_s: float = field(default=0.02, metadata={"min": 0.001, "max": 0.5})
    """tau_omega: time constant of the body rates' response to their command (roll and pitch;
    yaw too unless :attr:`yaw_rate_time_constant_s` says otherwise)."""
    yaw_rate_time_constant_s: float | None = field(default=None, metadata={"min": 0.001, "max": 2.0})
    """tau_omega of yaw where it differs (None: ``rate_time_constant_s``). A stock autopilot's
    yaw loop can be an order of magnitude slower than roll and pitch: PX4's SIH quadrotor
    (``MC_YAWRATE_P`` 0.2 on 0.2 N m of yaw authority) answers in 0.25-0.5 s against 0.05-0.08 s."""
    rate_delay_s: float = field(default=0.0, metadata={"min": 0.0, "max": 0.2})
    """d: from the command's arrival to the start of the rates' response (added to the
    link delay the state is predicted across)."""
    max_body_rate_rad_s: tuple[float, ...] = field(
        default=(12.0, 12.0, 6.0), metadata={"length": 3, **BODY_RATE_RAD_S})
    """Largest roll, pitch and yaw rate commanded (the autopilot's own limits or lower)."""
    attitude_gain_rad_s: tuple[float, ...] = field(
        default=(0.0, 0.0, 0.0), metadata={"length": 3, "min": 0.0, "max": 50.0})
    """Roll, pitch, yaw gain of an attitude loop the autopilot closes on the integral of the
    commanded rates (ArduCopter: its rate target is the command plus ``ATC_ANG_*_P`` times the
    error from the attitude that integral leads to; PX4's body-rate set-points have none: 0).
    mavreg keeps the same integral and subtracts that term, so the rate the autopilot aims
    for is the one mavreg wants (:class:`mavreg.model.rate_interface.AttitudeLoopCompensation`)."""


@dataclass(frozen=True)
class VehicleParams:
    """The design model's parameters (paper eqs 6-17 and 34), SI units."""

    name: str
    mass_kg: float = field(metadata=MASS_KG)
    inertia_kg_m2: tuple[float, ...] = field(metadata={"length": 3, **INERTIA_KG_M2})
    """Diagonal of J: (jx, jy, jz)."""
    arm_length_m: float = field(metadata=ARM_M)
    drag_torque_ratio_m: float = field(metadata=DRAG_TORQUE_RATIO_M)
    """k of eq 34: rotor drag torque per unit thrust."""
    max_rotor_thrust_n: float = field(metadata=ROTOR_THRUST_N)
    rotor_time_constant_s: float = field(default=0.0, metadata=ROTOR_TIME_CONSTANT_S)
    """The rotors' first-order thrust lag, as the controller knows it before flight. The design
    model (eq 34) has ideal rotors; the regulator leads its feedforward by this much (or by its
    in-flight estimate: :mod:`mavreg.control.estimation.lag_in_effect`). The emulator's rotors
    lag by it too, unless ``emulator.true_rotor_time_constant_s`` says otherwise."""
    rotor_drag_n_s_per_m: tuple[float, ...] = field(default=(0.0, 0.0),
                                                metadata={"length": 2, **LINEAR_DRAG_N_S_PER_M})
    """Linear drag of the body, (c_xy, c_z): c_xy in the rotor plane, c_z along the thrust
    axis (force = -C v_body). Known drag is fed forward by the nominal (0: the paper's model)."""
    parasitic_drag_n_s2_per_m2: float = field(default=0.0, metadata=PARASITIC_DRAG_N_S2_PER_M2)
    """Quadratic parasitic drag: force = -c |v| v."""
    rotor_drag_thrust_exponent: float = field(default=0.0, metadata={"min": 0.0, "max": 2.0})
    """e in c_xy(T) = c_xy (T / (m g))^e: the rotor-plane drag grows with the collective thrust
    (0.5: momentum drag, which grows as the rotors' induced velocity; mavreg.model.drag). c_xy
    is then the coefficient in hover. 0 (default): a constant c_xy."""
    thrust_scale: float = field(default=1.0, metadata={"min": 0.5, "max": 1.5})
    """Thrust the rotors actually give per unit commanded (a calibration: ``mavreg identify``);
    the daemon divides its rotor commands by it."""
    estimate_latency_s: float = field(default=0.0, metadata={"min": 0.0, "max": 0.2})
    """How old the vehicle's state estimate already is when it is stamped and sent (its
    estimator's output lag); the link's delay is measured, this cannot be."""
    output: str = field(default="rotors", metadata={"choices": OUTPUTS})
    """What the daemon commands (``--output`` overrides it)."""
    rate_interface: RateInterfaceParams | None = None
    """The autopilot's rate loop and thrust map; required by ``output: rates``."""
    dialect: str | None = field(default=None, metadata={"choices": DIALECTS})
    """The mode layout of custom firmware that announces MAV_AUTOPILOT_GENERIC: ``px4`` or
    ``ardupilot`` (``--dialect`` overrides it). None: PX4's in the rotors output; the rates
    output refuses such a vehicle without it. A stock PX4 or ArduPilot must not contradict it."""
    emulator: EmulatorParams = field(default_factory=EmulatorParams)

    @property
    def true_rotor_time_constant_s(self) -> float:
        """The emulated rotors' lag: ``emulator.true_rotor_time_constant_s`` where the file sets
        it (a mismatch), else ``rotor_time_constant_s``."""
        true_s = self.emulator.true_rotor_time_constant_s
        return self.rotor_time_constant_s if true_s is None else true_s

    def __post_init__(self):
        if self.output == "rates" and self.rate_interface is None:
            raise ValueError("output: rates needs a rate_interface: section (hover_thrust, "
                             "rate_time_constant_s, ...; docs/autopilots.md, or mavreg identify)")
        jx, jy, jz = self.inertia_kg_m2
        # A rigid body's principal moments obey the triangle inequality.
        if jx + jy < jz or jx + jz < jy or jy + jz < jx:
            raise ValueError(
                f"inertia_kg_m2 {self.inertia_kg_m2} violates the triangle inequality "
                "(each moment must be at most the sum of the other two)"
            )
        if self.max_rotor_thrust_n * 4 <= self.mass_kg * G:
            raise ValueError(
                f"max_rotor_thrust_n {self.max_rotor_thrust_n} N cannot hover "
                f"{self.mass_kg} kg (needs more than {self.mass_kg * G / 4:.3f} N per rotor)"
            )


def load_vehicle(path: str | Path) -> VehicleParams:
    """Load ``params/vehicles/*.yaml`` (``kind: vehicle``)."""
    return load_file(path, VehicleParams, kind="vehicle")


def with_output(vehicle: VehicleParams, output: str | None) -> VehicleParams:
    """``vehicle`` commanded by ``output`` (``rotors``/``rates``; None: as its file says).
    Raises ConfigError (one line) when the file cannot fly rates."""
    if output is None or output == vehicle.output:
        return vehicle
    if output not in OUTPUTS:
        raise ConfigError(vehicle.name, None, "output", f"expected one of {', '.join(OUTPUTS)}, got {output!r}")
    if output == "rates" and vehicle.rate_interface is None:
        raise ConfigError(vehicle.name, None, "rate_interface",
                          "output rates needs this section (hover_thrust, rate_time_constant_s, ...): "
                          "add it or run mavreg identify on a flight (docs/autopilots.md)")
    return replace(vehicle, output=output)


def with_dialect(vehicle: VehicleParams, dialect: str | None) -> VehicleParams:
    """``vehicle`` flown with the mode layout ``dialect`` (``px4``/``ardupilot``; None: as its
    file says). Raises ConfigError (one line) for another value."""
    if dialect is None or dialect == vehicle.dialect:
        return vehicle
    if dialect not in DIALECTS:
        raise ConfigError(vehicle.name, None, "dialect", f"expected one of {', '.join(DIALECTS)}, got {dialect!r}")
    return replace(vehicle, dialect=dialect)
