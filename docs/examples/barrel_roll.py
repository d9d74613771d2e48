"""The paper's barrel roll planned, simulated and plotted through the library, notebook style.

    python docs/examples/barrel_roll.py [OUT_DIR]

Each ``# %%`` cell can be pasted into a notebook (Jupyter, VS Code). The figures go to OUT_DIR
(default: a new temporary directory): ``barrel_roll.png`` (``mavreg simulate --plot``'s) and
``distance_from_path.png`` (drawn here from the run's arrays). docs/api.md explains each call;
``tests/unit/test_api_example.py`` runs this file in the suite.
"""
# %% The vehicle, the controller and the maneuver: the defaults are mavreg fly's
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import mavreg

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="mavreg-barrel-roll-"))
out.mkdir(parents=True, exist_ok=True)
roll = mavreg.load_maneuver(mavreg.config.paths.maneuver_file("barrel_roll"))

# %% Plan (MK-Quadro, realistic.yaml), simulate from the paper's start error, plot
plan = mavreg.plan(roll)
print(f"{plan.name}: {plan.length_m:.1f} m in {plan.duration_s:.1f} s, delay margin "
      f"{plan.margins.maneuver.delay_margin_s * 1e3:.1f} ms")
run = mavreg.simulate(plan, entry_offset=(0.6, 0.6, 0.6))
print(f"{run.metrics['status']}: transverse error max {run.metrics['transverse_error_m']['max']:.3f} m")
mavreg.plot_simulation(out / "barrel_roll.png", plan, run)

# %% The results are arrays: the distance from the path (w1, w2) against the arc length s
fig, ax = plt.subplots(figsize=(7, 3), layout="constrained")
ax.semilogy(run.s, np.hypot(run.w[:, 0], run.w[:, 1]))
ax.set(xlabel="arc length s (m)", ylabel="distance from the path (m)", title=plan.name)
fig.savefig(out / "distance_from_path.png", dpi=100)
print(f"figures in {out}")
