"""``--vehicle``: its converter, its help, and the checks of a serial port before anything starts."""
from __future__ import annotations

import argparse
import os

__all__ = ["vehicle_url", "vehicle_url_help", "check_vehicle_link"]


def vehicle_url(text: str) -> str:
    """udpin:HOST:PORT, udpout:HOST:PORT, serial:PATH[:BAUD] or tcp:HOST:PORT
    (mavreg.daemon.vehicle.url.parse_url)."""
    from ..daemon.vehicle.url import parse_url
    try:
        parse_url(text)
    except ValueError as exc:      # parse_url's only failure: the text is not such a URL
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def vehicle_url_help(default: str) -> str:
    """``--vehicle``'s help: the forms, where each fits, and the default."""
    from ..daemon.vehicle.url import VEHICLE_URL_FORMS
    return (f"vehicle connection: {VEHICLE_URL_FORMS}. udpout: PX4 SITL's offboard port; udpin: the "
            "vehicle sends first; serial: the flight controller's TELEM port on a UART or USB (e.g. "
            "serial:/dev/ttyAMA0:921600), checked against the telemetry rate; tcp: ArduPilot SITL "
            f"(tcp:127.0.0.1:5760). See docs/serial.md (default: {default})")


def check_vehicle_link(url: str | None, rate_hz: float, output: str, signed: bool) -> None:
    """UsageError (one line, before anything starts) when ``url`` is a serial port that is not
    there or not readable and writable by this user, or whose baud cannot carry the telemetry and
    commands at ``rate_hz`` (:mod:`mavreg.daemon.vehicle.link_budget`)."""
    if url is None or not url.startswith("serial:"):
        return
    from ..daemon.vehicle.link_budget import baud_refusal
    from ..daemon.vehicle.url import parse_url
    from ..errors import UsageError
    _, path, baud_bps = parse_url(url)
    if not os.path.exists(path):
        raise UsageError(f"--vehicle {url}: no device {path} (is the flight controller plugged in? ls /dev/tty*)")
    if not os.access(path, os.R_OK | os.W_OK):
        raise UsageError(f"--vehicle {url}: {path} is not readable and writable by this user: add it to the "
                         "device's group (e.g. sudo usermod -aG dialout $USER, then log in again)")
    why = baud_refusal(baud_bps, rate_hz, output, signed, name=f"--vehicle {url}")
    if why is not None:
        raise UsageError(why)
