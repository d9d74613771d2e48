"""``mavreg fly``'s summary of a maneuver cut short after its first control step (a link lost
as it began: tests/sitl/test_serial_sitl.py pulls the cable there) is a summary, not exit 70."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from mavreg.daemon.jobs.ctrllog import PHASE_CODES
from mavreg.daemon.jobs.report import controller_metrics
from mavreg.daemon.flight.supervisor import Phase


def _ctrl(n_maneuver: int) -> dict:
    n = 3 + n_maneuver
    phase = np.full(n, PHASE_CODES[Phase.HOLD])
    phase[3:] = PHASE_CODES[Phase.MANEUVER]
    return {"t_s": 0.002 * np.arange(n), "phase": phase, "s_m": np.linspace(0.0, 0.01, n),
            "w": np.zeros((n, 11)), "rotor_cmd_n": np.full((n, 4), 2.0)}


def test_one_maneuver_step_gives_metrics_without_a_saturation_time():
    plan = SimpleNamespace(segments=[("line", 0.0, 3.0)])
    one = controller_metrics(_ctrl(1), plan, 12.0)
    assert one["rotor_jitter_n"] is None and one["samples"] == 1 and "saturated_s" not in one
    many = controller_metrics(_ctrl(50), plan, 12.0)
    assert many["saturated_s"] == 0.0 and many["rotor_jitter_n"] is not None
