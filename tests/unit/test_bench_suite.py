"""``python -m benchmarks --quick`` runs, prints one table and writes the issue's JSON keys.

A smoke test of the suite's plumbing (the sections that need no emulator; the lockstep and
real-time ones have their own plumbing tests in test_bench_io.py). It asserts no timing:
only that every figure is there with its baseline and ratio, and that the batch Monte
Carlo agreed with the sequential simulator.
"""
from __future__ import annotations

import json
import subprocess
import sys
import pytest

from benchmarks.report import fmt, format_table
from tests.helpers.repo import ROOT as REPO


@pytest.mark.slow     # 11 s: every benchmark section once; run before releases (README)
def test_quick_suite_prints_one_table_and_writes_the_figures(tmp_path):
    out = tmp_path / "bench.json"
    p = subprocess.run([sys.executable, "-m", "benchmarks", "--quick", "--only", "plan", "step", "monte_carlo",
                        "--json", str(out)], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    figs = json.loads(out.read_text())
    for key in ("plan_s.total", "plan_s.path", "plan_s.nominal", "plan_s.linearization", "plan_s.riccati",
                "step_us.p50", "step_us.p99", "step_us.p999", "monte_carlo_s.group1"):
        assert figs[key]["value"] > 0, key
        assert key in p.stdout
    for key in ("step_us.p50", "step_us.p99", "monte_carlo_s.group1"):
        f = figs[key]
        assert f["baseline"] > 0 and f["ratio"] > 0 and f["target"] > 0 and f["met"] in (True, False)
    assert figs["monte_carlo_agreement_m.group1"]["value"] < 1e-9
    assert figs["machine"]["cpus"] >= 1 and figs["machine"]["quick"] is True
    assert p.stdout.count("figure ") == 1              # one table header


def test_table_rows_line_up_and_numbers_keep_three_digits():
    figs = {"a.b": {"value": 13119.4, "baseline": 8904.0, "ratio": 1.47, "target": 8000.0, "met": True,
                    "unit": "periods/s", "note": ""},
            "c": {"value": 0.0912, "baseline": None, "ratio": None, "target": None, "met": None, "unit": "us",
                  "note": ""}}
    lines = format_table(figs).splitlines()
    assert len(lines) == 4
    assert lines[0].index("unit") == lines[2].index("periods/s") == lines[3].index("us")
    assert lines[0].index("value") + len("value") == lines[2].index("13,119") + len("13,119")
    assert "13,119" in lines[2] and "yes" in lines[2] and "1.47x" in lines[2]
    assert (fmt(0.0912), fmt(12.34), fmt(123.4), fmt(None)) == ("0.0912", "12.3", "123", "-")
