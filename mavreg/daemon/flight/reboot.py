"""A vehicle that rebooted: seen, and what the flight does about it (sans-I/O).

An autopilot that restarts forgets everything the daemon set up with it: its clock starts
again (``time_boot_ms`` from 0), the telemetry intervals the daemon asked for are gone
(ArduCopter then sends no state at all), a TIMESYNC request in flight can no longer be
answered against the old clock, and it comes back disarmed. The daemon sees it by
:class:`RebootDetector`:

- **``time_boot_ms`` going back**: a state part (ATTITUDE, ATTITUDE_QUATERNION,
  LOCAL_POSITION_NED) more than ``back_s`` (1 s) older than the newest one seen. No link
  reorders telemetry by that much (TIMESYNC already refuses a delay over 1 s as
  implausible), and the sample assembler would drop every part of the new boot as late
  until its clock caught up with the old one;
- **the heartbeat gap**: the longest wall-clock gap between two vehicle HEARTBEATs since the
  newest part of the old boot, or the silence so far (a reboot is 1-5 s without any), which
  the event reports. A gap alone is a link outage, which the link checks judge; it does make
  the daemon ask for the telemetry again when no complete sample has come for
  ``stale_timeout_s`` (:meth:`mavreg.daemon.flight.supervisor.Supervisor.handle`).

What follows (:func:`on_reboot`), by phase:

- **in the air** (an airborne phase, or the takeover): the vehicle fell or is falling; it is
  the loss it is: the command stream stops for good, as on a lost link (bound
  ``vehicle_rebooted``; never a motor stop from the daemon);
- **the flight is over** (disarmed, aborted: a link lost in the air is usually judged before
  the vehicle is back): the event, and the outcome's actions name the reboot as the cause;
- **the forced disarm** (after an impact): the vehicle is disarmed, confirmed;
- **on the ground before take-off** (preflight): whatever was keyed to the old boot is built
  again: the sample assembler's clock, the TIMESYNC estimate (the link delay is measured
  again before arming), the command history, the vehicle's status (the next HEARTBEAT), the
  parameter checks and the telemetry requests (re-sent with each HEARTBEAT until samples
  stream); a queued maneuver then flies as from a fresh start.

``counters.reboots`` counts them (the daemon's ``status``).

The vehicle's clock is the vehicle's, not the flight's: a daemon of many flights hands each
new flight's detector what the last one saw (:meth:`RebootDetector.carry_on`), so that a
reboot that ended a flight (in the air, the link lost first) and had the next one begin on
its disarmed HEARTBEAT is still seen, and named, by the first state part of the new boot.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..vehicle import messages as mm
from .phases import AIRBORNE, Phase

__all__ = ["STATE_PARTS", "Reboot", "RebootDetector", "on_reboot"]

STATE_PARTS = frozenset(("ATTITUDE", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED"))
"""The messages whose ``time_boot_ms`` the detector watches."""
_IN_THE_AIR = AIRBORNE | {Phase.TAKEOVER}


@dataclass(frozen=True)
class Reboot:
    """A reboot seen: the vehicle's clock before and after (s), the heartbeat gap (wall s)."""

    from_s: float
    to_s: float
    heartbeat_gap_s: float
    previous_flight: bool = False
    """The old boot is the one the previous flight saw last (this flight saw none of it)."""

    def describe(self) -> str:
        gap = (f"after a {self.heartbeat_gap_s:.1f} s heartbeat gap" if math.isfinite(self.heartbeat_gap_s)
               else "with no HEARTBEAT heard before")
        old = " s (the boot the previous flight flew)" if self.previous_flight else ""
        return f"time_boot_ms went back from {self.from_s:.3f}{old} to {self.to_s:.3f} s {gap}"


class RebootDetector:
    """Sees the vehicle's clock go back (see the module docstring).

    Parameters
    ----------
    back_s : float
        A state part this much older than the newest one seen is a new boot's.
    """

    def __init__(self, back_s: float = 1.0):
        self.back_ms = int(round(1000.0 * back_s))
        self.newest_ms = -1
        self._last_heartbeat_wall_s: float | None = None
        self._heartbeat_gap_s = 0.0
        self._carried_ms = -1

    def carry_on(self, previous: RebootDetector) -> None:
        """Go on from what ``previous`` (the last flight's detector, the same vehicle) saw of
        the vehicle's clock and HEARTBEATs: see the module docstring."""
        self.newest_ms = self._carried_ms = previous.newest_ms
        self._last_heartbeat_wall_s = previous._last_heartbeat_wall_s
        self._heartbeat_gap_s = previous._heartbeat_gap_s

    def heartbeat(self, now_wall_s: float) -> None:
        """A vehicle HEARTBEAT at the injected clock ``now_wall_s``."""
        last = self._last_heartbeat_wall_s
        if last is not None:
            self._heartbeat_gap_s = max(self._heartbeat_gap_s, now_wall_s - last)
        self._last_heartbeat_wall_s = now_wall_s

    def part(self, msg, now_wall_s: float) -> Reboot | None:
        """A state part (:data:`STATE_PARTS`): the reboot it reveals, or None."""
        t_ms = int(msg.time_boot_ms)
        newest = self.newest_ms
        if t_ms > newest:
            self.newest_ms = t_ms
            self._heartbeat_gap_s = 0.0
            return None
        if t_ms >= newest - self.back_ms:
            return None                              # late or reordered: the assembler's business
        last = self._last_heartbeat_wall_s
        gap = math.inf if last is None else max(self._heartbeat_gap_s, now_wall_s - last)
        self.newest_ms = t_ms
        self._heartbeat_gap_s = 0.0
        return Reboot(newest / 1000.0, t_ms / 1000.0, gap, previous_flight=newest == self._carried_ms >= 0)


def on_reboot(flight, safety, seen: Reboot, out) -> None:
    """What the flight does about the reboot ``seen`` (see the module docstring)."""
    ctx, parts = flight.ctx, flight.parts
    parts.counters.reboots += 1
    line = f"the vehicle rebooted: {seen.describe()}"
    if ctx.phase in _IN_THE_AIR:
        safety.hand_over(out, "vehicle_rebooted", seen.from_s - seen.to_s, parts.params.reboot_back_s, "s",
                         f"{line}, in the air ({ctx.phase}): the vehicle is lost")
    elif ctx.phase in (Phase.DISARMED, Phase.ABORTED):
        flight.event(out, "vehicle_rebooted", f"{line}; the flight was over ({ctx.phase})")
        if ctx.failure is not None:
            flight.note_action(f"the vehicle rebooted ({seen.describe()})")
    elif ctx.phase == Phase.TERMINATE:
        safety.disarm_confirmed(out, "the vehicle rebooted (disarmed)")
    else:                                # stamped with the old clock's last time, then rebuilt
        flight.announce(out, "vehicle_rebooted", mm.SEVERITY_WARNING,
                        f"{line}; on the ground: its clock, the link delay, its status, the parameter "
                        "checks and the telemetry requests are taken again")
        _rebuild(flight)


def _rebuild(flight) -> None:
    """Forget what was keyed to the old boot, before take-off."""
    ctx, parts = flight.ctx, flight.parts
    parts.assembler.restart()
    parts.timesync.restart()
    parts.forecaster.reset()
    parts.autopilot.restart()
    flight.ctx = ctx.after_reboot()      # its next HEARTBEAT gives its status: a reboot disarms
