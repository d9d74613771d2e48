"""The emulator configured as PX4's SIH quadrotor with PX4's rate-loop parameters: the
``firmware-sim`` flags under which its rate step is compared with a stock PX4's
(docs/firmware_sim.md, "PX4's SIH quadrotor"; :mod:`harness.px4_rate_step` measures PX4's).

- the airframe: ``mavreg/params/vehicles/px4_sih.yaml`` (``SIH_*``; its ``emulator:`` section
  has SIH's rotor lag and linear drag) and SIH's angular drag ``SIH_KDW``;
- the ideal world: SIH's gyro is the state of its step (noisy, not delayed), so no estimate
  latency; the mean response is compared, so no estimator errors;
- the loop at SIH's lockstep rate, ``min(IMU_GYRO_RATEMAX, IMU_INTEG_RATE)`` (250 Hz), a
  set-point used at the first tick after its receipt (``--rate-latency-s 0``);
- PX4's gains (P, I and D times ``MC_*RATE_K``), integrator limits, filters and ``THR_MDL_FAC``.
"""
from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

from firmware_sim.cli import main

__all__ = ["PX4_RATE_DEFAULTS", "SIH_KDW", "VEHICLE", "emulator_sih_args", "printed_figures"]

VEHICLE = Path(__file__).resolve().parents[2] / "mavreg" / "params" / "vehicles" / "px4_sih.yaml"
PX4_RATE_DEFAULTS = {
    "MC_ROLLRATE_P": 0.15, "MC_ROLLRATE_I": 0.2, "MC_ROLLRATE_D": 0.003, "MC_ROLLRATE_K": 1.0, "MC_ROLLRATE_FF": 0.0,
    "MC_PITCHRATE_P": 0.15, "MC_PITCHRATE_I": 0.2, "MC_PITCHRATE_D": 0.003, "MC_PITCHRATE_K": 1.0,
    "MC_PITCHRATE_FF": 0.0, "MC_YAWRATE_P": 0.2, "MC_YAWRATE_I": 0.1, "MC_YAWRATE_D": 0.0, "MC_YAWRATE_K": 1.0,
    "MC_YAWRATE_FF": 0.0, "MC_RR_INT_LIM": 0.3, "MC_PR_INT_LIM": 0.3, "MC_YR_INT_LIM": 0.3,
    "IMU_GYRO_CUTOFF": 40.0, "IMU_DGYRO_CUTOFF": 30.0, "IMU_GYRO_RATEMAX": 800.0, "IMU_INTEG_RATE": 250.0,
    "THR_MDL_FAC": 0.0, "SIH_KDW": 0.025}
"""PX4 v1.16's values on SIH (airframe 10040), as read over MAVLink (``python -m
scripts.px4.rate_step`` prints them)."""
SIH_KDW = PX4_RATE_DEFAULTS["SIH_KDW"]


def emulator_sih_args(px4_params: dict | None = None) -> list[str]:
    """``firmware-sim`` flags for the SIH airframe and the rate-loop parameters ``px4_params``
    (PX4's names; missing or None: :data:`PX4_RATE_DEFAULTS`)."""
    p = dict(PX4_RATE_DEFAULTS)
    p.update({k: v for k, v in (px4_params or {}).items() if k in p and v is not None})
    rate_hz = int(min(p["IMU_GYRO_RATEMAX"], p["IMU_INTEG_RATE"]))
    args = ["--vehicle-params", str(VEHICLE), "--world", "ideal", "--control-rate-hz", str(rate_hz),
            "--rate-latency-s", "0", "--angular-drag-n-m-s-per-rad", f"{p['SIH_KDW']:g}"]
    for axis in ("ROLL", "PITCH", "YAW"):
        k = p[f"MC_{axis}RATE_K"]
        for g in ("P", "I", "D"):
            args += ["--rate-param", f"MC_{axis}RATE_{g}={k * p[f'MC_{axis}RATE_{g}']:g}"]
        args += ["--rate-param", f"MC_{axis}RATE_FF={p[f'MC_{axis}RATE_FF']:g}"]
    for name in ("MC_RR_INT_LIM", "MC_PR_INT_LIM", "MC_YR_INT_LIM", "IMU_GYRO_CUTOFF", "IMU_DGYRO_CUTOFF",
                 "THR_MDL_FAC"):
        args += ["--rate-param", f"{name}={p[name]:g}"]
    return args


def printed_figures(argv) -> dict:
    """``firmware-sim ARGV --print-rate-response``'s roll and pitch figures: ``{axis: {"t10",
    "t50", "t90" (ms), "overshoot" (%), "final", "tau", "delay" (ms)}}``."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main([*argv, "--print-rate-response"]) == 0
    figures = {}
    for axis in ("roll", "pitch"):
        line = next(x for x in out.getvalue().splitlines() if f"rate response {axis} " in x)
        values = (float(v) for v in re.search(
            r"at ([\d.]+)/([\d.]+)/([\d.]+) ms, overshoot ([\d.]+) %, final ([\d.]+); first order \+ delay: "
            r"tau ([\d.]+) ms, delay ([\d.]+) ms", line).groups())
        figures[axis] = dict(zip(("t10", "t50", "t90", "overshoot", "final", "tau", "delay"), values))
    return figures
