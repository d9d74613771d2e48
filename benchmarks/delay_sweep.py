"""Loop error of the barrel roll against the link's round-trip delay, with and without prediction.

    python benchmarks/delay_sweep.py [--via sim|sitl|both] [--delays-ms 0,10,20,30,40,50,60]

``sim``: the design model with a 20 ms rotor lag and the realistic estimator errors
(:class:`mavreg.sim.estimate_noise.EstimateNoise`), the delay split 2/3 downlink (the
controller sees a late state) and 1/3 uplink (its command acts late), controller
``params/controller/realistic.yaml`` with the delay known. ``sitl``: ``mavreg fly --lockstep``
on the bundled emulator's realistic preset with its telemetry and command delays set the
same way, each with the preset's +-3 ms jitter (less on a shorter leg); the daemon measures
the delay with TIMESYNC. A failed flight is marked (its result: a bound fired, the daemon
recovered or stopped the motors). Each row gives the loop's true
maximum transverse error (cm), or the way the run ended. Prints a table; figures go to
docs/robustness.md.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from mavreg.config.paths import PARAMS_DIR  # noqa: E402

MANEUVER = PARAMS_DIR / "maneuvers" / "barrel_roll.yaml"
VEHICLE = PARAMS_DIR / "vehicles" / "mk_quadro.yaml"
CONTROLLER = PARAMS_DIR / "controller" / "realistic.yaml"


def _split(delay_ms: float) -> tuple[float, float]:
    down = round(delay_ms * 2 / 3)
    return down, delay_ms - down


def sim_row(delay_ms: float, predict: bool, seed: int = 1) -> str:
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.planning.plan_io import plan_file
    from mavreg.sim.estimate_noise import EstimateNoise
    from mavreg.sim.maneuver_run import fly_on_design_model
    vehicle = load_vehicle(VEHICLE)
    controller = dataclasses.replace(load_controller(CONTROLLER), predict_delay=predict)
    plan = _plan_cache.setdefault("plan", plan_file(MANEUVER, vehicle, controller))
    down, up = _split(delay_ms)
    run = fly_on_design_model(plan, control_rate_hz=500, dt_s=0.001,
                              rotor_time_constant_s=vehicle.rotor_time_constant_s,
                              measurement_delay_s=down / 1e3, command_delay_s=up / 1e3,
                              estimate_noise=EstimateNoise(), predict=predict, seed=seed)
    m = run.metrics
    loop = (m["true"]["segments"].get("loop") or {}).get("max_m")
    if m["status"] != "completed" or loop is None:
        return m["status"]
    return f"{100 * loop:.2f}"


_plan_cache: dict = {}


def sitl_row(delay_ms: float, predict: bool) -> str:
    down, up = _split(delay_ms)
    with tempfile.TemporaryDirectory() as tmp:
        ctl = Path(tmp) / "controller.yaml"
        text = CONTROLLER.read_text().replace("predict_delay: true", f"predict_delay: {str(predict).lower()}")
        ctl.write_text(text)
        out = Path(tmp) / "flight"
        cmd = [sys.executable, "-m", "mavreg.cli.main", "fly", str(MANEUVER), "--lockstep",
               "--controller", str(ctl), "--out", str(out), "--timeout-s", "600",
               f"--emulator-arg=--telemetry-delay-s={down / 1e3:g}", f"--emulator-arg=--command-delay-s={up / 1e3:g}",
               # the preset's +-3 ms jitter, or less where a leg is shorter than that
               f"--emulator-arg=--telemetry-jitter-s={min(3.0, down) / 1e3:g}",
               f"--emulator-arg=--command-jitter-s={min(3.0, up) / 1e3:g}"]
        subprocess.run(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=900)
        try:
            summary = json.loads((out / "summary.json").read_text())
        except (OSError, ValueError):
            return "no summary"
        gt = ((summary.get("ground_truth") or {}).get("segments") or {}).get("loop") or {}
        if gt.get("max_m") is None:
            return summary.get("result", "?")
        mark = "" if summary.get("result") == "ok" else f" ({summary.get('result')})"
        return f"{100 * gt['max_m']:.2f}{mark}"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--via", choices=("sim", "sitl", "both"), default="both")
    p.add_argument("--delays-ms", default="0,10,20,30,40,50,60")
    a = p.parse_args(argv)
    delays = [float(d) for d in a.delays_ms.split(",")]
    vias = ("sim", "sitl") if a.via == "both" else (a.via,)
    print("loop max transverse error (cm, ground truth) against round-trip delay")
    print(f"{'delay ms':>9} " + " ".join(f"{v + (' pred' if p_ else ' no pred'):>16}"
                                          for v in vias for p_ in (False, True)))
    for d in delays:
        cells = []
        for v in vias:
            for pr in (False, True):
                cells.append(sim_row(d, pr) if v == "sim" else sitl_row(d, pr))
        print(f"{d:9.0f} " + " ".join(f"{c:>16}" for c in cells), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
