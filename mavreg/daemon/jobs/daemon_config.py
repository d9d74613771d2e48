"""What a daemon is started with: its settings (:class:`DaemonConfig`) and the factory of the
maneuver regulator it flies each plan with (:func:`regulator_factory`).

Both are importable from :mod:`mavreg.daemon.jobs.app` too, where the daemon that uses them lives.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ...config.controller import ControllerParams
from ...config.defaults import CONTROL_RATE_HZ
from ...config.disturbance import DisturbanceParams
from ...config.envelope import EnvelopeParams
from ...config.regulation import AllocationParams, SpeedGovernorParams
from ...config.vehicle import VehicleParams
from ...control.controllers import fastpath
from ...control.controllers.regulator import ManeuverRegulator
from ..gcs.bridge import GcsParams
from .planner_pool import PlannerBounds
from ..flight.supervisor import SupervisorParams

__all__ = ["DaemonConfig", "regulator_factory"]


def regulator_factory(vehicle: VehicleParams, control_rate_hz: float,
                      disturbance: DisturbanceParams | None = None,
                      allocation: AllocationParams | None = None,
                      speed_governor: SpeedGovernorParams | None = None, warm: bool = True) -> Callable:
    """(plan, rotor_lag) -> ManeuverRegulator at the vehicle's control rate (for its feedforward
    lead), leading by the flight's rotor lag in effect ``rotor_lag``
    (:class:`~mavreg.control.estimation.lag_in_effect.RotorLagInEffect`; None: the file's), its
    disturbance compensation bounded by ``disturbance``, its allocation and speed governor
    ``allocation`` and ``speed_governor`` (the controller file's sections; None: the paper's).
    The regulator's compiled step is compiled (or loaded from numba's cache) here, so that a
    maneuver uploaded in flight does not stall the loop for it; ``warm=False`` leaves that to
    the caller (:class:`~mavreg.daemon.jobs.app.Daemon` compiles every kernel as a stage of its start,
    said on the terminal: :mod:`mavreg.daemon.jobs.startup`)."""
    if not control_rate_hz > 0:
        raise ValueError(f"control rate must be positive, got {control_rate_hz} Hz")
    d = disturbance if disturbance is not None else DisturbanceParams()
    if warm:
        fastpath.warm_up()      # the compiled step now, before the link: a later upload builds at once

    def make(plan, rotor_lag=None) -> ManeuverRegulator:
        return ManeuverRegulator(plan, vehicle, control_period_s=1.0 / control_rate_hz, rotor_lag=rotor_lag,
                                 max_compensation_turn_rad=d.max_compensation_turn_rad,
                                 allocation=allocation, speed_governor=speed_governor)
    return make


@dataclass(frozen=True)
class DaemonConfig:
    """A daemon's settings: the vehicle's URL, the loaded controller, the control endpoint's
    socket, the ``.tlog`` and its clock, the supervisor's and the envelope's parameters, the
    ground stations and the planner worker's bounds. The controller is the loaded object,
    never its file's path (:meth:`__post_init__` refuses one): nothing reloads it."""

    vehicle_url: str
    controller: ControllerParams
    """The controller file, loaded: its prediction settings (``predict_delay``,
    ``fixed_delay_s``, ``max_prediction_s``), its disturbance observer, and the planner
    worker's parameters (a restarted worker plans with them, even if the file changed since)."""
    socket_path: Path | None
    tlog_path: Path | None
    supervisor: SupervisorParams
    envelope: EnvelopeParams = field(default_factory=EnvelopeParams)
    """The controller file's ``envelope:`` section (``fly`` and ``serve`` load it)."""
    control_rate_hz: float = CONTROL_RATE_HZ
    """The vehicle's telemetry (control) rate: the regulator's period (its feedforward lead),
    the prediction's integration step."""
    gcs_urls: tuple[str, ...] = ()
    """Ground stations to forward the flight to (``--gcs``; :mod:`mavreg.daemon.gcs.bridge`)."""
    gcs: GcsParams = field(default_factory=GcsParams)
    tlog_clock: str = "wall"
    """The ``.tlog``'s timestamps: ``wall`` (a vehicle in real time) or ``vehicle`` (a
    lockstep simulator: the start's wall time plus the vehicle time elapsed,
    :class:`mavreg.daemon.logs.tlog.VehicleClock`)."""
    planner: PlannerBounds = field(default_factory=PlannerBounds)
    """What one upload may cost the planner worker (memory, CPU, wall clock)."""
    flights: int | None = 1
    """Flights to fly before the daemon stops: 1 (``fly``, ``serve --once``); None: until it is
    stopped (``serve``: after each flight ends on the ground, the next upload starts a new one;
    :mod:`mavreg.daemon.jobs.flight_book`)."""
    control_log_path: Path | None = None
    """Save each flight's controller log here when it ends (numbered per flight when
    ``flights`` is not 1). None: the caller saves :attr:`Daemon.ctrl_log` itself (``fly``)."""
    keep_control_log: bool = True
    """Keep the controller log in memory; off for a ``serve`` that writes none (about 65 kB
    a second at 500 Hz, forever)."""
    keep_logs: int = 20
    """Numbered logs (``.tlog``, controller log) of a many-flight daemon: the newest this many stay."""

    def __post_init__(self):
        if not isinstance(self.controller, ControllerParams):
            raise TypeError(f"DaemonConfig.controller: a loaded ControllerParams, got "
                            f"{type(self.controller).__name__} (load the file once: load_controller)")
        if self.tlog_clock not in ("wall", "vehicle"):
            raise ValueError(f"tlog clock {self.tlog_clock!r}: expected 'wall' or 'vehicle'")
        if self.flights is not None and self.flights < 1:
            raise ValueError(f"flights must be at least 1 (or None: until stopped), got {self.flights}")
        if self.keep_logs < 1:
            raise ValueError(f"keep_logs must be at least 1, got {self.keep_logs}")
