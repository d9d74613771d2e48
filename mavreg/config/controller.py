"""LQR weights of the maneuver regulator (paper Section 4) and of the hover controller."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .defaults import MAX_PREDICTION_S
from .disturbance import DisturbanceParams
from .envelope import EnvelopeParams
from .loader import load_file
from .ranges import LQR_WEIGHT, LQR_WEIGHT_OR_ZERO
from .regulation import AllocationParams, SpeedGovernorParams

__all__ = ["ControllerParams", "load_controller", "MIN_RICCATI_STEP_S"]

MIN_RICCATI_STEP_S = 1e-4
"""0.1 ms: RK4's error at the 2 ms default is already far below the gains' meaning (O(h^4));
a finer step only multiplies the nodes (20 times the default's memory and time at 0.1 ms)."""


@dataclass(frozen=True)
class ControllerParams:
    r"""Diagonal LQR weights on the 11 transverse coordinates and the 4 inputs.

    The paper prints Q = diag(100, 100, 9, 9, 9, 9, 10, 10, 10, 3, 3, 3): twelve entries
    for eleven coordinates. Grouped by meaning, the groups are 2 (normal and binormal
    position), 3 (angles), 3 (body velocity) and 3 (body rates); the print has four 9s,
    one too many. We read it as position (100, 100), angles (9, 9, 9), velocity
    (10, 10, 10), rates (3, 3, 3); docs/transverse.md gives the reasoning and the check.
    """

    q_position: tuple[float, ...] = field(metadata={"length": 2, **LQR_WEIGHT})
    q_attitude: tuple[float, ...] = field(metadata={"length": 3, **LQR_WEIGHT})
    q_velocity: tuple[float, ...] = field(metadata={"length": 3, **LQR_WEIGHT})
    q_rate: tuple[float, ...] = field(metadata={"length": 3, **LQR_WEIGHT})
    r_input: tuple[float, ...] = field(metadata={"length": 4, **LQR_WEIGHT})
    """Weights on (f, gamma1, gamma2, gamma3)."""
    riccati_step_s: float = field(default=0.002, metadata={"min": MIN_RICCATI_STEP_S, "max": 0.01})
    """Step of the RK4 Riccati sweep, in nominal time (the s-step is speed times this); the
    plan's tables hold its nodes and the midpoints between them, half a step apart. At least
    :data:`MIN_RICCATI_STEP_S`; what a finer step costs is bounded by the planning budget
    (:mod:`mavreg.maneuver.budget`)."""
    attitude_error: str = field(default="rpy", metadata={"choices": ("rpy", "so3")})
    """The regulator's attitude error: ``rpy``, the paper's roll-pitch-yaw differences
    (singular at pitch +-90 deg), or ``so3``, the rotation vector Log(Rbar^T R) of the body
    relative to the nominal, defined at every attitude (docs/transverse.md)."""
    envelope: EnvelopeParams = field(default_factory=EnvelopeParams)
    """The flight envelope the daemon holds flights to (:mod:`mavreg.config.envelope`)."""
    rotor_lag_in_design: bool = False
    """Design the LQR on the transverse state augmented with the wrench the rotors achieve
    through their first-order lag (``rotor_time_constant_s`` of the vehicle file; see
    :mod:`mavreg.control.design.actuator`). False: the paper's design, which assumes the commanded
    wrench acts at once."""
    q_wrench: tuple[float, ...] = field(default=(0.0, 0.0, 0.0, 0.0),
                                        metadata={"length": 4, **LQR_WEIGHT_OR_ZERO})
    """With ``rotor_lag_in_design``: weights on the achieved wrench's deviation from the
    nominal, (f, gamma1, gamma2, gamma3)."""
    predict_delay: bool = False
    """Predict the state across the measured (or ``fixed_delay_s``) sample-to-actuation delay
    before regulating (:mod:`mavreg.control.estimation.predictor`). False: regulate the sample as it is."""
    fixed_delay_s: float | None = field(default=None, metadata={"min": 0.0, "max": 0.5})
    """A configured link delay (downlink + uplink, s) that overrides the measured one."""
    max_prediction_s: float = field(default=MAX_PREDICTION_S, metadata={"min": 0.0, "max": 0.5})
    """Cap on the prediction horizon; past it a gap is not flown on the prediction."""
    disturbance: DisturbanceParams = field(default_factory=DisturbanceParams)
    """The disturbance observer (:mod:`mavreg.config.disturbance`); off by default."""
    allocation: AllocationParams = field(default_factory=AllocationParams)
    """How the regulator maps its wrench to rotor forces, and the rotor limit it counts on
    (:mod:`mavreg.config.regulation`); the torques first by default."""
    speed_governor: SpeedGovernorParams = field(default_factory=SpeedGovernorParams)
    """The speed the regulator regulates to (:mod:`mavreg.config.regulation`); off by default."""
    hover_q: tuple[float, ...] = field(default=(20.0, 20.0, 30.0, 4.0, 4.0, 4.0, 6.0, 6.0, 8.0, 0.5, 0.5, 0.5),
                                       metadata={"length": 12, **LQR_WEIGHT})
    """The hover LQR's state weights over x = (p, roll pitch yaw, v_body, w_body): take-off,
    holds, landing (:class:`mavreg.control.controllers.hover.HoverParams`)."""
    hover_r_input: tuple[float, ...] = field(default=(0.1, 4.0, 4.0, 1.0),
                                             metadata={"length": 4, **LQR_WEIGHT})
    """The hover LQR's input weights over (f, gamma1, gamma2, gamma3). Roll and pitch at 4:
    through the 20 ms rotor lag the hold keeps 29 ms of delay margin on the paper's airframe
    (17 ms at 1; docs/robustness.md, *Margins*); a lighter airframe needs larger torque weights
    for the same margin (params/controller/freestyle.yaml)."""

    @property
    def q(self) -> np.ndarray:
        """Q as an (11,) diagonal, in the order of w."""
        return np.array(self.q_position + self.q_attitude + self.q_velocity + self.q_rate)

    @property
    def r(self) -> np.ndarray:
        return np.array(self.r_input)


def load_controller(path: str | Path) -> ControllerParams:
    """Load ``params/controller/*.yaml`` (``kind: controller``)."""
    return load_file(path, ControllerParams, kind="controller")
