"""The sample-to-actuation delay the supervisor predicts across (sans-I/O; a part of the
:class:`~mavreg.daemon.flight.supervisor.Supervisor`).

Two parts: the link's, configured (the controller file's ``fixed_delay_s``) or measured by
TIMESYNC (:mod:`mavreg.daemon.vehicle.timesync`, its median), and the vehicle's, which TIMESYNC
cannot see and the vehicle file states: the age of its state estimate when it is stamped
(``estimate_latency_s``) and, when the daemon commands body rates, the autopilot rate loop's
own delay (``rate_interface.rate_delay_s``).
"""
from __future__ import annotations

from ...config.vehicle import VehicleParams
from ..vehicle.timesync import TimesyncEstimator

__all__ = ["ActuationDelay"]


class ActuationDelay:
    """The delay of one vehicle's commands, as the prediction and the gate use it.

    Parameters
    ----------
    timesync : TimesyncEstimator
    vehicle : VehicleParams
    output : str
        ``rotors`` or ``rates``: what the daemon commands.
    fixed_delay_s : float, optional
        A configured link delay that overrides the measured one.
    """

    def __init__(self, timesync: TimesyncEstimator, vehicle: VehicleParams, output: str,
                 fixed_delay_s: float | None = None):
        self.timesync = timesync
        self.fixed_delay_s = fixed_delay_s
        rates = vehicle.rate_interface if output == "rates" else None
        self.vehicle_s = vehicle.estimate_latency_s + (0.0 if rates is None else rates.rate_delay_s)
        """The delays the vehicle file states (TIMESYNC cannot see them)."""

    @property
    def known(self) -> bool:
        """The link's delay is configured or measured."""
        return self.fixed_delay_s is not None or self.timesync.estimate() is not None

    def measured_link(self) -> tuple[float, float] | None:
        """(delay, jitter) of the link by TIMESYNC, or None before the first reply."""
        est = self.timesync.estimate()
        return None if est is None else (est.delay_s, est.jitter_s)

    def total_s(self) -> float:
        """What the prediction spans: the configured link delay, else the TIMESYNC median (0
        before the first reply), plus :attr:`vehicle_s`."""
        if self.fixed_delay_s is not None:
            d = self.fixed_delay_s
        else:
            est = self.timesync.estimate()
            d = 0.0 if est is None else est.delay_s
        return d + self.vehicle_s

    def status(self, predicting: bool) -> dict | None:
        """The link delay in the daemon's ``status`` (ms; None before the first TIMESYNC reply);
        ``predicting``: the prediction spans :meth:`total_s`."""
        est = self.timesync.estimate()
        return None if est is None else {
            "sample_to_actuation": est.delay_s * 1e3, "jitter": est.jitter_s * 1e3,
            "round_trip_wall": est.round_trip_s * 1e3, "replies": est.samples,
            "used_for_prediction": self.total_s() * 1e3 if predicting else None}
