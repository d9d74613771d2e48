"""``mavreg serve`` on a stock ArduCopter SITL with a ground station beside it, for the tests
that reboot the autopilot (tests/sitl/test_ardupilot_reboot*.py).

The SITL (freestyle, GPS, the pilot's parameters) gives its first link to the daemon and a
second one, on SERIAL1, to the test's ground station (:class:`~.ardupilot_sitl.GroundLink`),
which streams SIM_STATE, the truth, and can command the autopilot over MAVLink.
"""
from __future__ import annotations

import contextlib
import time
from pathlib import Path

from harness.ardupilot_flight import PILOT_PARAMS, vehicle_args
from harness.ardupilot_sitl import M, ArduPilotSitl
from .sitl import mavreg

__all__ = ["SIM_STATE_HZ", "serve_on_arducopter", "set_pilot_params"]

SIM_STATE_HZ = 50.0


@contextlib.contextmanager
def serve_on_arducopter(tmp_path: Path):
    """The SITL and ``mavreg serve`` on it (control socket ``tmp_path/d.sock``, its logs in
    ``tmp_path``); yields (ground link, serve's :class:`~.sitl.Proc`, socket path). On exit
    serve is stopped (its lines kept in ``tmp_path/serve.log``), then the SITL."""
    sock = tmp_path / "d.sock"
    with ArduPilotSitl(frame="freestyle", params=PILOT_PARAMS, ground_link=True) as sitl:
        gcs = sitl.ground
        gcs.set_rate(M.MAVLINK_MSG_ID_SIM_STATE, SIM_STATE_HZ)
        port = sitl.release_link()        # the daemon takes SERIAL0; the SITL keeps sending there
        gcs.pump()
        serve = mavreg("serve", *vehicle_args(port), "--control-rate-hz", "200", "--socket", str(sock),
                       "--out", str(tmp_path))
        try:
            serve.wait_line("control endpoint", 120)
            yield gcs, serve, sock
        finally:
            serve.stop()
            (tmp_path / "serve.log").write_text("\n".join(serve.lines))


def set_pilot_params(gcs, timeout_s: float = 30.0) -> None:
    """Set the pilot's parameters again once the rebooted autopilot answers (start.sh's
    ``--wipe`` makes a rebooted SITL forget them), and ask for SIM_STATE again (message rates
    do not survive a reboot either)."""
    deadline = time.monotonic() + timeout_s
    for name, value in PILOT_PARAMS.items():
        while True:
            try:
                gcs.set_param(name, value, 1.0)
                break
            except Exception:            # still booting: its first requests go unanswered
                if time.monotonic() > deadline:
                    raise
    gcs.set_rate(M.MAVLINK_MSG_ID_SIM_STATE, SIM_STATE_HZ)
