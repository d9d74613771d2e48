"""``mavreg.control.controllers.sample_warmup``: after the warm-up, a closed-loop flight compiles nothing.

In a fresh process (numba's dispatchers start empty there), the kernels' compiled
signatures are read before the warm-up, after it, and after a closed-loop realistic.yaml
hover and the barrel roll's first second flown through the daemon's objects
(``harness/controller_flight.py``): the warm-ups the daemon runs before it opens the link
(the regulator's step, :func:`mavreg.control.controllers.fastpath.warm_up`, then the sample kernels)
must have compiled every kernel the flights call, for every argument type they call it with.
(The regulator's step compiles the compensation kernels into itself; on a cold numba cache
their dispatchers then show the signatures too.)
"""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from mavreg.accel import ACCELERATED
from tests.helpers.repo import ROOT as REPO

_CHILD = """
import json
from mavreg.control.controllers import compensation_kernel, hover_kernel
from mavreg.control.estimation import command_history_kernel, observer_kernel, predictor_kernel
from mavreg.control.controllers.hover import HoverParams
from mavreg.control.controllers import fastpath
from mavreg.control.controllers.sample_warmup import warm_up_sample_kernels
from harness import controller_flight as flight

MODULES = (predictor_kernel, command_history_kernel, observer_kernel, hover_kernel, compensation_kernel)

def compiled():
    return {f"{m.__name__}.{k}": [str(s) for s in v.signatures] for m in MODULES
            for k, v in vars(m).items() if hasattr(v, "signatures") and v.__module__ == m.__name__}

setup = flight.Setup()
before = compiled()
c = setup.controller
fastpath.warm_up()      # as the daemon: its regulator factory compiles the step before the link
ran = warm_up_sample_kernels(setup.vehicle, 1.0 / flight.RATE_HZ, c.max_prediction_s, c.disturbance, HoverParams())
warm = compiled()
flight.fly(setup, "hover", 1.0)
flight.fly(setup, "maneuver", 1.0)
print(json.dumps({"before": before, "warm": warm, "flown": compiled(), "ran": ran}))
"""


@pytest.mark.skipif(not ACCELERATED, reason="the pure path compiles nothing")
def test_the_warm_up_compiles_every_kernel_the_flights_call():
    out = subprocess.run([sys.executable, "-c", _CHILD], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["ran"] is True
    assert not any(r["before"].values())
    for name in ("predictor_kernel.predict_into", "command_history_kernel.prepare", "command_history_kernel.advance",
                 "observer_kernel.update", "hover_kernel.reference", "hover_kernel.feedback"):
        assert any(k.endswith(name) and v for k, v in r["warm"].items()), name
    assert r["flown"] == r["warm"]
