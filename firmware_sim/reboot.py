"""The autopilot's reboots: by command, or injected in the air (sans-I/O, sim time).

``MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN`` (246) with ``param1`` = 1, as PX4's commander answers
it: refused while armed (``MAV_RESULT_DENIED``, PX4's ``shutdown_if_allowed``; ArduPilot
answers FAILED), else ACCEPTED and the autopilot goes down :data:`SHUTDOWN_DELAY_S` later
(PX4's ``px4_reboot_request(false, 400_ms)``). ``param1`` = 0 is accepted and does nothing
(as PX4); any other ``param1`` (shutdown, bootloader) is UNSUPPORTED.

``--reboot-at-s T`` (repeatable) takes the autopilot down at sim time T whatever it is doing:
a brown-out or a watchdog reset. Armed in the air, the motors stop and the vehicle falls.

While down (``--reboot-time-s``, 1.5 s of sim time by default, so deterministic in lockstep)
the autopilot sends nothing and every message that reaches it is lost (counted
``dropped_rebooting``); the rotors get no command. Then it is a new autopilot
(:func:`fresh_autopilot`): ``time_boot_ms`` counts from 0 again, disarmed, in HOLD, the
default stream rates (a requested message interval is forgotten), no offboard peer, no
known link peers (it sends again only to a peer whose HEARTBEAT it hears, or to
``--remote``), the estimator started again; the parameters it had are kept (PX4 stores them),
and so is the battery's charge. The vehicle is where it lay or fell: the physics never stops.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink2

from .px4 import Px4Services

__all__ = ["SHUTDOWN_DELAY_S", "DEFAULT_REBOOT_TIME_S", "Reboots", "RebootRecord", "fresh_autopilot",
           "handle_reboot_command", "add_reboot_args"]

SHUTDOWN_DELAY_S = 0.4
"""From the accepted command to the autopilot going down (PX4: ``px4_reboot_request(false, 400_ms)``)."""
DEFAULT_REBOOT_TIME_S = 1.5
"""How long the autopilot is down (sim time; a real flight controller takes 1-5 s)."""


@dataclass
class RebootRecord:
    """One reboot: when it went down and came back (sim time), why, and what it was doing."""

    down_t_s: float
    why: str
    armed: bool
    on_ground: bool
    up_t_s: float | None = None

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass
class Reboots:
    """When the autopilot goes down and comes back.

    Parameters
    ----------
    reboot_time_s : float
        Time down (sim time).
    at_s : tuple of float
        Injected reboots (``--reboot-at-s``), sim time.
    """

    reboot_time_s: float = DEFAULT_REBOOT_TIME_S
    at_s: tuple = ()
    records: list = field(default_factory=list)
    requested_t_s: float | None = None
    """A commanded reboot goes down at this time (None: none requested)."""

    def __post_init__(self):
        self._injected = sorted(float(t) for t in self.at_s)

    @property
    def down(self) -> bool:
        """The autopilot is down now."""
        return bool(self.records) and self.records[-1].up_t_s is None

    def request(self, t_s: float) -> None:
        """A reboot command was accepted at ``t_s``."""
        if self.requested_t_s is None:
            self.requested_t_s = t_s + SHUTDOWN_DELAY_S

    def due(self, t_s: float) -> str | None:
        """``"down"`` (with its reason in the new record), ``"up"`` or None at ``t_s``."""
        eps = 1e-9
        if self.down:
            if t_s >= self.records[-1].down_t_s + self.reboot_time_s - eps:
                self.records[-1].up_t_s = t_s
                return "up"
            return None
        why = None
        if self._injected and t_s >= self._injected[0] - eps:
            self._injected.pop(0)
            why = "injected (--reboot-at-s): brown-out or watchdog reset"
        elif self.requested_t_s is not None and t_s >= self.requested_t_s - eps:
            why = "by command (MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN)"
        if why is None:
            return None
        self.requested_t_s = None
        self.records.append(RebootRecord(t_s, why, False, True))
        return "down"


def handle_reboot_command(ap, msg) -> None:
    """``MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN`` (acked through ``ap``; see the module docstring)."""
    action = int(msg.param1)
    if action == 0:
        ap._ack(msg, mavlink2.MAV_RESULT_ACCEPTED)
    elif action != 1:
        ap.drops["unsupported"] += 1
        ap._ack(msg, mavlink2.MAV_RESULT_UNSUPPORTED)
    elif ap.armed:
        ap.deny(msg, "reboot denied: armed")
    else:
        ap._ack(msg, mavlink2.MAV_RESULT_ACCEPTED)
        ap._out.append(ap._statustext(mavlink2.MAV_SEVERITY_WARNING, "rebooting"))
        ap.reboot_requested = True


def fresh_autopilot(ap):
    """The autopilot ``ap`` is after a reboot: its configuration and parameters, the battery's
    charge; nothing else (disarmed, HOLD, default streams, no offboard peer, clocks at 0)."""
    px4 = Px4Services(ap.px4.cfg, ap.px4.rate_hz)
    px4.takeoff_height_m = ap.px4.takeoff_height_m
    px4.used_mah = ap.px4.used_mah
    new = type(ap)(ap.cfg, ap.stab, ap.hover_thrust_n, px4, ap.rates.cfg)
    new.drops = ap.drops            # the run's counters, not the autopilot's state
    return new


def add_reboot_args(p) -> None:
    """``--reboot-time-s``, ``--reboot-at-s`` (see the module docstring)."""
    from .argtypes import nonneg_float, positive_float
    p.add_argument("--reboot-time-s", type=positive_float, default=DEFAULT_REBOOT_TIME_S, metavar="S",
                   help="sim seconds the autopilot is down after a reboot: MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN "
                   "(param1 1; DENIED while armed, as PX4; it goes down 0.4 s after its ACK) or --reboot-at-s; "
                   "then it is a new autopilot: time_boot_ms from 0, disarmed, default streams, no known peer "
                   "(default %(default)s)")
    p.add_argument("--reboot-at-s", type=nonneg_float, action="append", default=[], metavar="T",
                   help="fault injection (repeatable): the autopilot reboots at sim time T whatever it does, "
                   "a brown-out or watchdog reset; armed in the air its motors stop and the vehicle falls. "
                   "A hard touchdown of that fall is recorded (meta 'reboot_impacts'), not a crash exit")
