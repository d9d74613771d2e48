"""A stock PX4's (v1.16, SIH) roll and pitch rate step, measured from the sent step to SIH's
true body rate (harness/px4_rate_step.py), against the emulator configured as SIH with
the parameters PX4 reports (tests/helpers/emulator_as_sih.py): the emulator's rate mode claims
PX4's form (docs/firmware_sim.md, "PX4's SIH quadrotor").

Slow (real time: PX4's boot, a take-off and 8 doublets, under a minute) and skipped where the
PX4 SITL is absent (harness/px4_sitl.py says where it is looked for). Times are read on
PX4's clock; on a machine too loaded for SIH's lockstep to keep near real time the test says so.
"""
from __future__ import annotations

import pytest

from harness.px4_sitl import require_px4


@pytest.mark.slow
def test_px4s_rate_step_is_the_emulators_configured_as_sih():
    require_px4()
    from tests.helpers.emulator_as_sih import PX4_RATE_DEFAULTS, emulator_sih_args, printed_figures
    from harness.px4_rate_step import measure_px4_rate_step
    res = measure_px4_rate_step(reps=4)
    assert res["sim_speed"] > 0.8, f"PX4's clock ran at {res['sim_speed']:.2f} of the wall clock: machine too loaded"
    changed = {k: v for k, v in res["params"].items() if k in PX4_RATE_DEFAULTS and v != PX4_RATE_DEFAULTS[k]}
    emu = printed_figures(emulator_sih_args(res["params"]))
    for axis, name in ((0, "roll"), (1, "pitch")):
        px4, e = res["truth"][axis], emu[name]
        why = (f"{name}: PX4 10/50/90 % at {1e3 * px4.t10_s:.1f}/{1e3 * px4.t50_s:.1f}/{1e3 * px4.t90_s:.1f} ms, "
               f"final {px4.final:.3f}; emulator {e}; PX4's parameters off the defaults: {changed}")
        assert e["t50"] == pytest.approx(1e3 * px4.t50_s, rel=0.10), why
        assert e["t90"] == pytest.approx(1e3 * px4.t90_s, rel=0.15), why
        assert e["final"] == pytest.approx(px4.final, abs=0.08), why
