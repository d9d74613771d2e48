"""Small campaigns of each kind on the design model, end to end; results independent of --jobs."""
from __future__ import annotations

import io
import json

import pytest

from mavreg.experiments.campaign import run_campaign
from mavreg.experiments.definitions import paper_group1, paper_group2
from mavreg.experiments.runner import run_experiment


@pytest.fixture(scope="module")
def group1(tmp_path_factory):
    """Two runs of group 1 (nominal inertia and the first drawn one) over two processes."""
    out = tmp_path_factory.mktemp("g1")
    progress = io.StringIO()
    camp = run_campaign(paper_group1(0, samples=1), "sim", 2, out, "test command", progress=progress)
    return camp, out, progress.getvalue()


def test_group1_campaign_converges_and_writes_its_tables_and_figures(group1):
    camp, out, progress = group1
    res = json.loads((out / "results.json").read_text())
    assert res == camp.results and res["experiment"] == "paper-group1" and res["via"] == "sim"
    assert [r["index"] for r in res["runs"]] == [0, 1]
    for r in res["runs"]:
        # the paper's claim on the design model: converged on the run-up, the loop within millimetres
        assert r["converged"] and r["completed"] and r["ok"]
        assert -0.6 < r["converged_at_s_m"] < 16.5
        assert r["start_distance_m"] == pytest.approx(0.6 * 2 ** 0.5, abs=0.01)   # across the path
        assert r["loop"]["transverse_error_m"]["max"] < 0.005
        assert r["loop_peak_thrust_n"] == pytest.approx(39.1, abs=0.5)            # m (g + v^2 / r)
        assert r["converged_peak_torque_n_m"][1] < 0.5 < r["peak_torque_n_m"][1]  # pitch: the start's
    assert res["runs"][0]["inertia_kg_m2"] is None and res["runs"][1]["inertia_kg_m2"] is not None
    assert res["summary"]["converged"] == 2 and camp.all_ok
    md = (out / "results.md").read_text()
    assert "Converged before the loop in 2 of 2 runs" in md and md.count("| yes |") == 2
    for name in ("fig2_inertia_paths.png", "fig3_attitude_velocity.png", "fig3_start.png", "fig4_inputs.png",
                 "errors.png"):
        assert (out / name).stat().st_size > 10_000 and f"]({name})" in md
    assert progress.count("\n") == 2 and "2/2 runs" in progress     # not a terminal: a line per run
    prov = res["provenance"]                 # the same block as fly's summary.json (mavreg.provenance)
    assert prov["argv"] == ["test", "command"] and prov["world"].startswith("the design model")
    assert {"maneuver", "vehicle", "controller"} <= set(prov["files"])
    assert all(len(f["sha256"]) == 64 for f in prov["files"].values())


@pytest.mark.slow     # 20 s: the runs flown one at a time, in this process; run before releases (README)
def test_results_do_not_depend_on_jobs_nor_on_the_batch(group1, monkeypatch):
    """The campaign above flew its runs in one batch; flown one at a time on the sequential
    simulator (what a run the batch cannot fly takes), the numbers are the same."""
    from mavreg.experiments import via_batch
    camp, _, _ = group1
    monkeypatch.setattr(via_batch, "batchable", lambda *a: False)
    inline = run_experiment(paper_group1(0, samples=1), "sim", 1, progress=None)
    assert [o.metrics.keys() for o in inline] == [o.metrics.keys() for o in camp.outcomes]
    for a, b in zip(inline, camp.outcomes):
        assert a.metrics["loop"]["transverse_error_m"] == pytest.approx(b.metrics["loop"]["transverse_error_m"],
                                                                        rel=1e-9, abs=1e-12)
        assert a.metrics["converged_at_s_m"] == pytest.approx(b.metrics["converged_at_s_m"], rel=1e-9)


def test_group2_campaign_is_stable_and_saturates_only_with_a_limit(tmp_path):
    exp = paper_group2(0, laps=1, saturations_n=(None, 7.0))
    camp = run_campaign(exp, "sim", 1, tmp_path, "test command", progress=None)
    free, sat = camp.results["runs"]
    assert free["stable"] and sat["stable"] and camp.all_ok
    assert free["laps_flown"] == 1.0 and sat["laps_flown"] == 1.0
    assert free["saturated_share"] == 0.0 and 0.0 < sat["saturated_share"] < 0.5
    # torque asked for and not given: the noise alone (0.04 N m SD); at 7 N the controller knows
    # the limit and allocates the torques first (per-rotor clipping lost more than 1 N m)
    assert max(free["loop_torque_shortfall_n_m"]) < 0.3 and max(sat["loop_torque_shortfall_n_m"]) < 0.5
    # 0.1 N of noise alone keeps the loop within millimetres; at 7 N the governor slows the loop
    # down to what the rotors give: centimetres (per-rotor clipping at full speed: decimetres)
    assert free["loop"]["transverse_error_m"]["max"] < 0.005
    assert 0.005 < sat["loop"]["transverse_error_m"]["max"] < 0.4
    assert max(max(o.trace.rotor_applied_n.max(axis=0)) for o in camp.outcomes[1:]) <= 7.0
    md = (tmp_path / "results.md").read_text()
    assert "Stable in 2 of 2 cases" in md and "saturation 7 N" in md
    for name in ("fig5_rotor_forces.png", "fig6_paths.png", "fig7_attitude_velocity.png", "errors.png"):
        assert (tmp_path / name).stat().st_size > 10_000


def test_a_run_that_raises_is_recorded_and_the_campaign_goes_on(tmp_path):
    from dataclasses import replace
    exp = paper_group1(0, samples=0)
    bad = replace(exp, runs=(replace(exp.runs[0], inertia_kg_m2=(-1.0, 0.02, 0.03)),))
    outs = run_experiment(bad, "sim", 1, progress=None)
    assert outs[0].metrics is None and not outs[0].ok
    assert outs[0].error.startswith("ValueError: inertia_kg_m2 must be 3 positive numbers")
    assert "Traceback" in outs[0].traceback


def test_progress_on_a_terminal_rewrites_one_line():
    from mavreg.experiments.runner import RunOutcome, _Progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    exp = paper_group1(0, samples=2)
    tty = Tty()
    bar = _Progress(exp, "sim", tty)
    for spec, ok in zip(exp.runs, (True, False, True)):
        bar.update(RunOutcome(spec, {"ok": ok}, None))
    text = tty.getvalue()
    assert text.count("\r") == 3 and text.endswith("\n") and text.count("\n") == 1
    assert "3/3 runs, 1 not ok" in text.split("\r")[-1] and "left" not in text.split("\r")[-1]
