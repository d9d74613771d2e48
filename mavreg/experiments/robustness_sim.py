"""``mavreg experiment robustness --via sim``: the cells the design model can represent.

Via sitl the experiment judges the product (the daemon, its safety layer, the emulator's
realistic world, take-off to landing); via sim it judges the controller alone: the default
controller file (``params/controller/realistic.yaml``: its lag-aware gains, allocation, speed
governor, prediction across the delay and disturbance observer) flies the maneuver on the
design model (:func:`mavreg.sim.maneuver_run.fly_on_design_model`) from its entry to its
end, with no take-off, landing or safety layer, in a design-model version of firmware_sim's
``realistic`` world:

- the rotors lag by the vehicle file's ``rotor_time_constant_s``;
- the controller runs at 500 Hz (the daemon's rate) on physics steps of 1 ms;
- the state it sees is :data:`REAL_TELEMETRY_DELAY_S` + :data:`REAL_ESTIMATE_LATENCY_S` old
  and carries the realistic estimator's errors (:data:`REAL_ESTIMATE`); its command reaches
  the rotors :data:`REAL_COMMAND_DELAY_S` later; the link's jitter and loss are not modelled
  (fixed delays, rounded to whole milliseconds);
- with ``predict_delay`` the state is predicted across the true round trip (the daemon
  measures it with TIMESYNC);
- the noise is seeded from the flight's seed.

A cell's emulator arguments say what it changes; those the design model represents are
read from them (the delays, ``--estimator-scale``, ``--thrust-scale``), so a cell is defined
once (:mod:`.robustness`). The mismatch cell draws only the principal moments of inertia
(as firmware_sim does: each ``(1 + e)``, ``e ~ U(-0.3, 0.3)``, from the mismatch seed, not
the emulator's own numbers); mass, per-rotor thrust, yaw coefficient, arm, rotor lag and
centre of mass keep the vehicle file's. Wind (no drag in the design model), message loss and
TIMESYNC (no link protocol) are not represented: :data:`SIM_UNREPRESENTABLE`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import UsageError
from ..config.controller import load_controller
from ..config.defaults import CONTROL_RATE_HZ
from ..config.regulation import told_rotor_limit
from ..sim.estimate_noise import EstimateNoise
from ..sim.maneuver_run import fly_on_design_model
from .record import Flight
from .robustness import RobustnessExperiment, robustness, select_cells
from .via_sim import EXTRA_TIME_S, flight_from_result

__all__ = ["SIM_CONTROL_RATE_HZ", "REAL_TELEMETRY_DELAY_S", "REAL_COMMAND_DELAY_S", "REAL_ESTIMATE_LATENCY_S",
           "REAL_ESTIMATE", "MISMATCH_INERTIA_REL", "SIM_UNREPRESENTABLE", "SimWorld", "sim_skip_reason",
           "robustness_via_sim", "sim_world", "fly_robust_sim", "judge_sim", "sim_description"]

SIM_CONTROL_RATE_HZ = CONTROL_RATE_HZ
"""The daemon's control rate (its telemetry rate, ``mavreg fly``'s default)."""
# firmware_sim's realistic preset (firmware_sim/world.py, _REAL_LINK and _REAL_ESTIMATOR),
# written here so that mavreg does not depend on the emulator:
REAL_TELEMETRY_DELAY_S = 0.010
"""_REAL_LINK.telemetry_delay_s (its +-3 ms jitter is not modelled)."""
REAL_COMMAND_DELAY_S = 0.005
"""_REAL_LINK.command_delay_s (its +-3 ms jitter is not modelled)."""
REAL_ESTIMATE_LATENCY_S = 0.004
"""_REAL_ESTIMATOR.latency_s: the estimate is this old when it is sent."""
REAL_ESTIMATE = EstimateNoise()
"""_REAL_ESTIMATOR's standard deviations and correlation times (EstimateNoise's defaults are
those numbers: position 5 mm / 0.5 s, velocity 0.02 m/s / 0.2 s, attitude 0.3 deg / 0.5 s,
gyro 0.005 rad/s white, bias 0.003 rad/s / 30 s)."""
MISMATCH_INERTIA_REL = 0.3
"""Each principal moment of a drawn airframe is nominal (1 + e), e ~ U(-0.3, 0.3) (firmware_sim/mismatch.py)."""
SIM_UNREPRESENTABLE = {
    "wind3": "wind: the design model has no drag",
    "wind6": "wind: the design model has no drag",
    "loss": "message loss: the design model has no link protocol",
    "timesync": "TIMESYNC: the design model has no link protocol",
}
"""Cell groups that do not fly via sim, and why."""
_READ = {"--telemetry-delay-s", "--command-delay-s", "--estimator-scale", "--thrust-scale", "--mismatch-seed"}
_NOT_MODELLED = {"--telemetry-jitter-s": "link jitter", "--command-jitter-s": "link jitter"}


@dataclass(frozen=True)
class SimWorld:
    """What one via-sim flight's world differs in (SI units)."""

    measurement_delay_s: float = REAL_TELEMETRY_DELAY_S + REAL_ESTIMATE_LATENCY_S
    command_delay_s: float = REAL_COMMAND_DELAY_S
    estimator_scale: float = 1.0
    """Every estimator standard deviation times this."""
    thrust_scale: float = 1.0
    """The rotors give this much of their command (the controller is not told)."""
    inertia_kg_m2: tuple[float, float, float] | None = None
    """The plant's principal moments; None: the vehicle file's."""
    not_modelled: tuple[str, ...] = ()
    """The cell's emulator arguments the design model leaves out (e.g. jitter)."""


def sim_skip_reason(cell) -> str | None:
    """Why ``cell`` does not fly via sim (None: it does)."""
    return SIM_UNREPRESENTABLE.get(cell.group)


def robustness_via_sim(seed: int, flights: int, only: str | None) -> RobustnessExperiment:
    """The robustness experiment as ``--via sim`` flies it: the cells ``only`` chooses that the
    design model represents (the seeds as via sitl); the others listed in ``skipped``.

    Raises
    ------
    ValueError
        One line: ``only`` names a cell the design model cannot fly (or chooses none it can).
    """
    chosen = select_cells(only)
    skipped = tuple((c.name, why) for c in chosen if (why := sim_skip_reason(c)) is not None)
    names = {n.strip() for n in (only or "").split(",")}
    named = [f"{c} ({why})" for c, why in skipped if c in names]
    if named or len(skipped) == len(chosen):
        bad = named or [f"{c} ({why})" for c, why in skipped]
        raise UsageError("cannot fly via sim: " + "; ".join(bad) + "; use --via sitl, or leave them out of --cells")
    flown = ",".join(c.name for c in chosen if sim_skip_reason(c) is None)
    exp = robustness(seed, flights, flown)
    return dataclasses.replace(exp, via="sim", skipped=skipped,
                               title="Robustness of the default controller on the design model")


def _draw_inertia(nominal, mismatch_seed: int) -> tuple[float, float, float]:
    e = np.random.default_rng(mismatch_seed).uniform(-MISMATCH_INERTIA_REL, MISMATCH_INERTIA_REL, 3)
    return tuple(float(j) for j in np.asarray(nominal, dtype=float) * (1.0 + e))


def sim_world(spec, vehicle) -> SimWorld:
    """The design-model world of robustness flight ``spec``, read from its emulator arguments.

    Raises
    ------
    ValueError
        An emulator argument the design model neither reads nor knows to leave out.
    """
    args = dict((a.split("=", 1) + [""])[:2] for a in spec.emulator_args)
    unknown = [a for a in args if a not in _READ and a not in _NOT_MODELLED]
    if unknown:
        raise ValueError(f"{spec.cell}: the design model cannot represent {unknown[0]}")
    down = float(args.get("--telemetry-delay-s", REAL_TELEMETRY_DELAY_S))
    return SimWorld(measurement_delay_s=down + REAL_ESTIMATE_LATENCY_S,
                    command_delay_s=float(args.get("--command-delay-s", REAL_COMMAND_DELAY_S)),
                    estimator_scale=float(args.get("--estimator-scale", 1.0)),
                    thrust_scale=float(args.get("--thrust-scale", 1.0)),
                    inertia_kg_m2=(None if spec.mismatch_seed is None
                                   else _draw_inertia(vehicle.inertia_kg_m2, spec.mismatch_seed)),
                    not_modelled=tuple(sorted({_NOT_MODELLED[a] for a in args if a in _NOT_MODELLED})))


def judge_sim(status: str, reason: str) -> dict:
    """The outcome of a via-sim flight in :func:`.robustness_metrics.judge_flight`'s keys: ``ok``
    when the maneuver reached its end; what only a whole flight has (safety bounds, altitude,
    touchdowns, motor stops) None."""
    none = ("first_bound", "bound_phase", "action", "flight_time_s", "emulator_exit_code", "emulator_stop",
            "lowest_altitude_m", "judged_from_to_s", "touchdowns", "max_touchdown_speed_m_s", "ground_impact",
            "motors_stopped_in_air", "motors_stopped_in_air_at", "motors_stopped_event_t_s", "airframe")
    return {"via": "sim", "result": "ok" if status == "completed" else "failed",
            "reason": "" if status == "completed" else f"{status}: {reason}", **dict.fromkeys(none)}


def fly_robust_sim(plan, spec, controller_path: Path) -> Flight:
    """Fly robustness flight ``spec`` on the design model (see the module docstring)."""
    ctrl = load_controller(controller_path)
    world = sim_world(spec, plan.vehicle)
    run = fly_on_design_model(
        plan, control_rate_hz=SIM_CONTROL_RATE_HZ, dt_s=0.001, seed=spec.seed, extra_time_s=EXTRA_TIME_S,
        rotor_time_constant_s=plan.vehicle.rotor_time_constant_s, inertia_kg_m2=world.inertia_kg_m2,
        saturation_n=spec.saturation_n, thrust_scale=world.thrust_scale,
        measurement_delay_s=world.measurement_delay_s, command_delay_s=world.command_delay_s,
        estimate_noise=REAL_ESTIMATE.scaled(world.estimator_scale), predict=ctrl.predict_delay,
        max_prediction_s=ctrl.max_prediction_s, disturbance=ctrl.disturbance if ctrl.predict_delay else None,
        gust_force_n=spec.gust_force_n, gust_window_s=spec.gust_window_s or (0.0, 0.0),
        allocation=told_rotor_limit(ctrl.allocation, spec.saturation_n), speed_governor=ctrl.speed_governor,
        true_metrics=False)                        # the runner's truth_trace judges the flight
    res = run.result
    judged = judge_sim(res.status.value, res.reason)
    if world.inertia_kg_m2 is not None:           # the drawn part of the airframe, as the emulator records it
        rel = np.asarray(world.inertia_kg_m2) / np.asarray(plan.vehicle.inertia_kg_m2, dtype=float) - 1.0
        judged["airframe"] = {"mismatch": {"inertia_rel": [float(r) for r in rel]}}
    extra = {"flight": judged, "world": dataclasses.asdict(world)}
    return flight_from_result(res, spec.saturation_n, extra)


def sim_description() -> dict:
    """The via-sim world for ``results.json`` (``sim``): one sentence and its numbers."""
    down_ms = 1e3 * (REAL_TELEMETRY_DELAY_S + REAL_ESTIMATE_LATENCY_S)
    return {"world": (f"the vehicle file's rotor lag, control at {SIM_CONTROL_RATE_HZ:g} Hz, the state seen "
                      f"{down_ms:g} ms late ({1e3 * REAL_TELEMETRY_DELAY_S:g} ms telemetry + "
                      f"{1e3 * REAL_ESTIMATE_LATENCY_S:g} ms estimate latency) with the realistic estimator's "
                      f"errors, commands acting {1e3 * REAL_COMMAND_DELAY_S:g} ms later, no jitter, no loss, "
                      "no drag, each cell's factor on top."),
            "control_rate_hz": SIM_CONTROL_RATE_HZ, "physics_step_s": 0.001,
            "telemetry_delay_s": REAL_TELEMETRY_DELAY_S, "estimate_latency_s": REAL_ESTIMATE_LATENCY_S,
            "command_delay_s": REAL_COMMAND_DELAY_S, "estimate_noise": dataclasses.asdict(REAL_ESTIMATE),
            "jitter": "not modelled", "start": "the maneuver's entry state (no take-off, landing or safety layer)",
            "mismatch": "inertia drawn (each moment x U(0.7, 1.3)); mass, rotor thrust, yaw coefficient, arm, "
                        "rotor lag and centre of mass keep the vehicle file's"}
