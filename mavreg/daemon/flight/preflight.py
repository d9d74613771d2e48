"""Before arming: which autopilot this is, its telemetry, and the parameters mavreg relies on
(sans-I/O; a part of the :class:`~mavreg.daemon.flight.supervisor.Supervisor`).

The first vehicle HEARTBEAT chooses the :class:`~mavreg.daemon.vehicle.autopilots.Dialect` (PX4 or
ArduCopter; for custom firmware that announces GENERIC, the mode layout the operator chose,
PX4's by default in the rotors output: :func:`~mavreg.daemon.vehicle.autopilots.choose_dialect`);
every later one is decoded by it. With each HEARTBEAT until the first complete
state sample, the dialect's SET_MESSAGE_INTERVAL requests go out (the telemetry mavreg flies
on, at the control rate: ArduCopter sends none of it by default). Before the first arm
request, :meth:`AutopilotSetup.ready` reads the parameters the dialect checks
(PARAM_REQUEST_READ by name, repeated every ``retry_s`` for those not yet answered). It
passes when every parameter has been read and holds; it refuses, with the dialect's one line
naming the parameter and the value to set, when one does not hold, or when the parameters
are not answered within ``timeout_s`` of vehicle time. It never sets a parameter. A vehicle
mavreg does not speak to is refused at its first HEARTBEAT (:attr:`AutopilotSetup.refusal`).
"""
from __future__ import annotations

import math

from ..vehicle.autopilots import Dialect, HeartbeatInfo, ParamChecker, choose_dialect
from .gate import GateVerdict
from ..vehicle.peers import VehicleIds

__all__ = ["AutopilotSetup"]


class AutopilotSetup:
    """Dialect, telemetry requests and parameter checks of one vehicle.

    Parameters
    ----------
    ids : VehicleIds
        The vehicle's (read when a request is built: known by its first HEARTBEAT).
    telemetry_rate_hz : float
        Rate asked for the attitude and position telemetry (the control rate).
    timeout_s : float
        Vehicle time the parameter reads may take before the take-off is refused.
    retry_s : float
        Vehicle time between repeats of unanswered reads.
    choice : {"px4", "ardupilot"} or None
        The mode layout of a vehicle that announces GENERIC (``--dialect``, ``dialect:``).
    output : {"rotors", "rates"}
        What the daemon commands (a GENERIC vehicle in the rates output needs ``choice``).
    """

    def __init__(self, ids: VehicleIds, telemetry_rate_hz: float, timeout_s: float = 10.0,
                 retry_s: float = 1.0, choice: str | None = None, output: str = "rotors"):
        self.ids = ids
        self.choice = choice
        self.output = output
        self.telemetry_rate_hz = float(telemetry_rate_hz)
        self.timeout_s = float(timeout_s)
        self.retry_s = float(retry_s)
        self.dialect: Dialect | None = None
        self.unsupported: str | None = None
        """Why the vehicle's autopilot is not one mavreg speaks to (None: it is, or unknown)."""
        self.notice: str | None = None
        """The line the first HEARTBEAT's choice of dialect is announced with (None: nothing
        to say, or already said: the supervisor takes it)."""
        self.checker: ParamChecker | None = None
        self._t0 = math.nan
        self._sent_t = -math.inf

    def heartbeat(self, msg, messages: list, streaming: bool) -> HeartbeatInfo | None:
        """Decode a vehicle HEARTBEAT (the first one chooses the dialect); None when its
        autopilot is not supported. Until the telemetry is ``streaming`` (complete samples
        arrive), its requests are appended to ``messages``."""
        if self.dialect is None and self.unsupported is None:
            self.dialect, self.unsupported, self.notice = choose_dialect(msg, self.choice, self.output)
        if self.dialect is None:
            return None
        if not streaming:
            messages.extend(self.dialect.telemetry_requests(*self.ids.target, self.telemetry_rate_hz))
        return self.dialect.decode(msg)

    def restart(self) -> None:
        """The parameters are checked again, from the next :meth:`ready` (the vehicle rebooted);
        the dialect is kept."""
        self.checker = None
        self._t0 = math.nan
        self._sent_t = -math.inf

    def param_value(self, msg) -> None:
        """Take a PARAM_VALUE (ignored unless a check is under way)."""
        if self.checker is not None:
            self.checker.add(msg)

    def set_offboard_mode(self):
        """The command that asks for the mode mavreg flies in."""
        return self.dialect.set_offboard_mode(*self.ids.target)

    @property
    def refusal(self) -> GateVerdict | None:
        """The refusal of a vehicle mavreg does not fly (its autopilot, or a dialect choice that
        contradicts it), known at its first HEARTBEAT; None otherwise."""
        return None if self.unsupported is None else GateVerdict(False, "gate_autopilot", detail=self.unsupported)

    def ready(self, t_s: float, messages: list) -> GateVerdict | None:
        """PASS, a refusal, or None while waiting; requests to send are appended to
        ``messages``. ``t_s``: vehicle time."""
        if self.unsupported is not None:
            return self.refusal
        if self.dialect is None:
            return None
        if self.checker is None:
            self.checker = self.dialect.param_checker()
            self._t0 = t_s
        verdict = self.checker.verdict()
        if verdict.state == "ok":
            return GateVerdict(True)
        if verdict.state == "refused":
            return GateVerdict(False, "gate_parameter", detail="; ".join(verdict.lines))
        waited = t_s - self._t0
        if waited > self.timeout_s:
            return GateVerdict(False, "gate_parameter", waited, self.timeout_s, "s",
                               f"{self.dialect.name} did not answer the read of "
                               f"{', '.join(verdict.missing)} within {self.timeout_s:g} s: mavreg checks "
                               "them before arming (docs/autopilots.md)")
        if t_s - self._sent_t >= self.retry_s or t_s < self._sent_t:
            messages.extend(self.dialect.param_requests(*self.ids.target, verdict.missing))
            self._sent_t = t_s
        return None

