"""``entry_offset_m``: the run-in ends off the path with the entry's velocity (experiments)."""
from __future__ import annotations

import numpy as np

from mavreg.control.controllers.hover import HoverParams
from mavreg.daemon.flight import flightpath as fp
from mavreg.daemon.flight.supervisor import Phase
from tests.helpers.supervisor_harness import FakePlan, SimVehicle, make_supervisor, run


def test_entry_moves_by_the_offset_and_keeps_its_velocity():
    plan = FakePlan()
    offset = np.array([0.3, -0.2, 0.1])
    a = fp.entry_of(plan, HoverParams(), 0.6)
    b = fp.entry_of(plan, HoverParams(), 0.6, offset)
    np.testing.assert_allclose(b.position_m - a.position_m, offset)
    np.testing.assert_allclose(b.hold_m - a.hold_m, offset)       # the run-in is the same ramp, moved
    np.testing.assert_allclose(b.velocity_m_s, a.velocity_m_s)
    np.testing.assert_allclose(b.accel_m_s2, a.accel_m_s2)
    assert b.yaw_rad == a.yaw_rad


def test_the_regulator_takes_over_off_the_path_at_the_entry_speed():
    offset = (0.0, 0.3, -0.2)                  # 0.36 m across the fake line (north), 0.2 m higher
    sup = make_supervisor(FakePlan(), entry_offset_m=offset)
    veh = SimVehicle()
    events, logs, _ = run(sup, veh, 60.0)
    assert sup.succeeded
    (x_reset, s_guess), = sup.regulators[0].resets
    start = np.array(FakePlan().start) + offset
    assert np.linalg.norm(x_reset[:3] - start) < 0.03
    assert abs(x_reset[6] - FakePlan().speed) < 0.05                # flying at the entry's speed
    man = [r for r in logs if r.phase == Phase.MANEUVER]
    first = np.hypot(man[0].w[0], man[0].w[1])
    assert abs(first - np.hypot(0.3, 0.2)) < 0.03                   # the regulator sees the offset
