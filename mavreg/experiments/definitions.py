"""What each experiment of ``mavreg experiment`` flies, with its seeds (no flying, no I/O).

An :class:`Experiment` is a tuple of :class:`RunSpec`, each complete in itself: start offset,
plant inertia, rotor noise, saturation, laps and the noise seed of that run. The runs are
fixed when the experiment is built from its seed, before any is flown, so a campaign gives
the same results however many processes fly it and in whatever order they finish.

The paper's Section 4 (Spedicato et al.):

- ``paper-group1``: start 0.6 m off in each of p1, p2, p3 (1.04 m from the entry point); one
  run on the nominal inertia and 25 whose jx, jy, jz are drawn independently from normal
  distributions about the nominal with SD 0.0102/3 kg m^2. The controller is always designed
  on the nominal vehicle; only the plant differs.
- ``paper-group2``: nominal start, 0.1 N of Gaussian noise on each rotor force, rotor
  saturation none / 8.5 N / 7 N, the loop flown 3 times. The three runs share one noise
  seed, so they differ only by the saturation.

The scenario of the paper's Fig. 1, measured: maneuver regulation against two time-indexed
trackers of the same nominal (:mod:`mavreg.trackers`), each with ideal rotors and with the
vehicle's 12 N rotors (the plant clips at 12 N):

- ``gust``: a force of 5, 8 or 10 N against the path's tangent at the gust's onset, held
  for 1 s in that direction (a gust has a direction; it does not turn with the path), at
  three places of the nominal: on the run-up at speed (s = 11 m, 8 m/s), early in the run-up
  at low speed (s = 2 m, 0.75 m/s, 1.45 m/s a second later) and at the start of the loop
  (s = 19.5 m, where the circle begins). The window is in time from the start at the
  entry: the nominal's time at that s, which every controller reaches on time (they all
  fly the unperturbed nominal to within millimetres until then).
- ``lag``: the vehicle starts on the nominal state at s = 11 m (the run-up at speed, where
  the gust would have struck) and the trackers' timed reference 1, 2 or 4 m further along
  the path (as after a gust that held the vehicle back). Maneuver regulation has no timed
  reference: for it every lead is the same start.

No noise: the seed only names the runs.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import UsageError
from ..config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, PAPER_GOVERNED_CONTROLLER, PARAMS_DIR

__all__ = ["RunSpec", "Experiment", "EXPERIMENTS", "build_experiment", "draw_inertia", "run_seed",
           "paper_group1", "paper_group2", "gust", "lag", "PAPER_INERTIA_SD_KG_M2", "PAPER_OFFSET_M",
           "PAPER_ROTOR_NOISE_SD_N", "PAPER_SATURATIONS_N", "PAPER_LAPS", "MIN_INERTIA_KG_M2",
           "CONVERGENCE", "SATURATION", "DISTURBANCE", "REGULATOR", "TVLQR", "SE3", "CONTROLLERS",
           "GUST_FORCES_N", "GUST_DURATION_S", "GUST_PLACES", "LAG_LEADS_M", "LAG_START_S_M",
           "ROTOR_LIMITS_N", "rotors_label", "nominal_clock"]

PAPER_INERTIA_SD_KG_M2 = 0.0102 / 3
"""SD of each drawn moment of inertia: 95 % of the draws within +-jz (the largest moment)."""
PAPER_OFFSET_M = (0.6, 0.6, 0.6)
"""Start offset of group 1, NED (m)."""
PAPER_ROTOR_NOISE_SD_N = 0.1
PAPER_SATURATIONS_N = (None, 8.5, 7.0)
PAPER_LAPS = 3
MIN_INERTIA_KG_M2 = 1e-3
"""A drawn moment below this is drawn again (nominal jx is 4.9 SD above it: about one draw in
two million)."""
BARREL_ROLL = PARAMS_DIR / "maneuvers" / "barrel_roll.yaml"

CONVERGENCE = "convergence"
"""Kind of experiment judged by convergence to the path before the loop (group 1)."""
SATURATION = "saturation"
"""Kind of experiment judged by stability under noise and saturation (group 2)."""
DISTURBANCE = "disturbance"
"""Kind of experiment that compares the controllers after a disturbance (gust, lag), judged
by whether each run reaches the path's end."""

REGULATOR = "regulator"
"""Maneuver regulation (:class:`mavreg.control.controllers.regulator.ManeuverRegulator`), the plan's gains."""
TVLQR = "tvlqr"
"""The time-varying LQR of :mod:`mavreg.trackers.tvlqr`, on the regulator's weights."""
SE3 = "se3"
"""The SE(3) geometric tracker of :mod:`mavreg.trackers.se3`."""
CONTROLLERS = (REGULATOR, TVLQR, SE3)

GUST_FORCES_N = (5.0, 8.0, 10.0)
GUST_DURATION_S = 1.0
GUST_PLACES = {"run-up": 11.0, "slow": 2.0, "loop": 19.5}
"""Where the gust strikes: the arc length of the nominal at its onset (m)."""
LAG_LEADS_M = (1.0, 2.0, 4.0)
LAG_START_S_M = 11.0
ROTOR_LIMITS_N = (None, 12.0)
"""Ideal rotors, and the plant clipping at the vehicle's 12 N."""


@dataclass(frozen=True)
class RunSpec:
    """One run of an experiment (SI units)."""

    index: int
    label: str
    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Start position minus the nominal entry position, NED."""
    inertia_kg_m2: tuple[float, float, float] | None = None
    """The plant's jx, jy, jz; None: the vehicle file's (the design's)."""
    rotor_noise_sd_n: float = 0.0
    saturation_n: float | None = None
    """Rotor force limit of the plant only (the design keeps the vehicle file's); None: none."""
    laps: int = 1
    seed: int = 0
    """Seed of this run's rotor noise."""
    controller: str = REGULATOR
    """:data:`REGULATOR`, :data:`TVLQR` or :data:`SE3`."""
    group: str = ""
    """The runs of a group share a figure (gust: where it strikes; lag: ``lag``)."""
    case: str = ""
    """Within a group, the runs that differ only by controller and rotors (``8 N``)."""
    gust_force_n: tuple[float, float, float] | None = None
    """External force (NED) during ``gust_window_s``."""
    gust_window_s: tuple[float, float] | None = None
    """(start, end) in time from the run's start."""
    start_s_m: float = 0.0
    """The run starts on the nominal state at this arc length (plus ``offset_m``); 0: the entry."""
    reference_lead_m: float = 0.0
    """A time-indexed tracker's reference starts this far ahead along the path."""
    max_time_s: float | None = None
    """Stop this long after the start at the latest; None: the nominal time left plus a margin."""


@dataclass(frozen=True)
class Experiment:
    """A named set of runs of one maneuver on one vehicle and controller design."""

    name: str
    title: str
    kind: str
    """:data:`CONVERGENCE` or :data:`SATURATION`: how the runs are judged and drawn."""
    seed: int
    runs: tuple[RunSpec, ...]
    maneuver_path: Path = BARREL_ROLL
    vehicle_path: Path = DEFAULT_VEHICLE
    controller_path: Path = PAPER_CONTROLLER


def run_seed(seed: int, index: int) -> int:
    """The noise seed of run ``index`` of an experiment seeded ``seed`` (31 bits, for any
    program that takes a seed)."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0] >> 1)


def draw_inertia(nominal_kg_m2, n: int, seed: int, sd_kg_m2: float = PAPER_INERTIA_SD_KG_M2) -> np.ndarray:
    """``n`` independent normal draws of (jx, jy, jz) about ``nominal_kg_m2``, shape (n, 3).

    A row with a moment below :data:`MIN_INERTIA_KG_M2` is drawn again (from the same
    stream, so the result depends on the seed alone).
    """
    if n < 0:
        raise ValueError(f"the number of inertia draws must be >= 0, got {n}")
    J0 = np.asarray(nominal_kg_m2, dtype=float).reshape(3)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x1e27]))
    out = np.empty((n, 3))
    for i in range(n):
        row = J0 + rng.normal(0.0, sd_kg_m2, 3)
        while row.min() < MIN_INERTIA_KG_M2:
            row = J0 + rng.normal(0.0, sd_kg_m2, 3)
        out[i] = row
    return out


def paper_group1(seed: int = 0, samples: int = 25, vehicle_path: Path = DEFAULT_VEHICLE) -> Experiment:
    """Group 1: 0.6 m off in each axis; nominal inertia plus ``samples`` drawn inertias."""
    from ..config.vehicle import load_vehicle
    J0 = tuple(float(j) for j in load_vehicle(vehicle_path).inertia_kg_m2)
    runs = [RunSpec(0, "nominal inertia", PAPER_OFFSET_M, None, seed=run_seed(seed, 0))]
    for i, J in enumerate(draw_inertia(J0, samples, seed), start=1):
        runs.append(RunSpec(i, f"inertia sample {i}", PAPER_OFFSET_M,
                            tuple(float(j) for j in J), seed=run_seed(seed, i)))
    return Experiment("paper-group1", "Paper group 1: start 0.6 m off in each axis, inertia Monte Carlo",
                      CONVERGENCE, int(seed), tuple(runs), vehicle_path=vehicle_path)


def paper_group2(seed: int = 0, laps: int = PAPER_LAPS, saturations_n=PAPER_SATURATIONS_N,
                 vehicle_path: Path = DEFAULT_VEHICLE) -> Experiment:
    """Group 2: nominal start, 0.1 N rotor noise, one run per saturation, ``laps`` laps."""
    if laps < 1:
        raise ValueError(f"laps must be at least 1, got {laps}")
    noise_seed = run_seed(seed, 0)
    runs = tuple(RunSpec(i, "no saturation" if sat is None else f"saturation {sat:g} N",
                         rotor_noise_sd_n=PAPER_ROTOR_NOISE_SD_N,
                         saturation_n=None if sat is None else float(sat), laps=laps, seed=noise_seed)
                 for i, sat in enumerate(saturations_n))
    return Experiment("paper-group2", f"Paper group 2: 0.1 N rotor noise, saturation, {laps} laps",
                      SATURATION, int(seed), runs, vehicle_path=vehicle_path,
                      controller_path=PAPER_GOVERNED_CONTROLLER)


def rotors_label(saturation_n: float | None) -> str:
    return "ideal rotors" if saturation_n is None else f"{saturation_n:g} N rotors"


def nominal_clock(maneuver_path: Path):
    """``(t_of_s, tangent)`` of a maneuver's nominal: the time it reaches arc length s,
    ``int_0^s ds / v(s)`` (trapezoid on 0.2 mm steps), and the path's unit tangent at s.
    Path and speed profile only: no nominal, no gains."""
    from ..config.maneuver import load_maneuver
    from ..geometry.build import build_path
    from ..maneuver.plan import build_profiles
    spec = load_maneuver(maneuver_path)
    path = build_path(spec)
    speed, _ = build_profiles(spec, path)
    s = np.linspace(0.0, path.length_m, int(np.ceil(path.length_m / 2e-4)) + 1)
    inv_v = 1.0 / speed.evaluate(s)[0]
    t = np.concatenate([[0.0], np.cumsum(np.diff(s) * (inv_v[1:] + inv_v[:-1]) / 2)])

    def t_of_s(sq: float) -> float:
        return float(np.interp(sq, s, t))

    def tangent(sq: float) -> np.ndarray:
        return path.evaluate(np.array([float(sq)]))[1][0][:, 0]

    return t_of_s, tangent


def _runs_by_case(seed, cases, saturations_n, controllers):
    """(group, case, spec fields) x rotors x controllers, in that order, indexed."""
    runs = []
    for group, case, fields in cases:
        for sat in saturations_n:
            for ctrl in controllers:
                i = len(runs)
                runs.append(RunSpec(i, f"{group} {case}, {rotors_label(sat)}, {ctrl}",
                                    saturation_n=None if sat is None else float(sat), seed=run_seed(seed, i),
                                    controller=ctrl, group=group, case=case, **fields))
    return tuple(runs)


def _check_controllers(controllers) -> None:
    bad = [c for c in controllers if c not in CONTROLLERS]
    if bad or not controllers:
        raise ValueError(f"controllers must be some of {', '.join(CONTROLLERS)}, got {list(controllers)}")


def gust(seed: int = 0, forces_n=GUST_FORCES_N, places=tuple(GUST_PLACES), controllers=CONTROLLERS,
         saturations_n=ROTOR_LIMITS_N, max_time_s: float | None = None, start_s_m: float = 0.0) -> Experiment:
    """A gust against the path's tangent for :data:`GUST_DURATION_S` at each place of
    :data:`GUST_PLACES` and force, for each controller and rotor limit; start at the entry
    (or on the nominal at ``start_s_m``, before every place: a shorter run)."""
    _check_controllers(controllers)
    t_of_s, tangent = nominal_clock(BARREL_ROLL)
    cases = []
    for place in places:
        if place not in GUST_PLACES:
            raise ValueError(f"unknown gust place {place!r}; known: {', '.join(GUST_PLACES)}")
        s_on = GUST_PLACES[place]
        if not 0.0 <= start_s_m < s_on:
            raise ValueError(f"the runs must start before the gust at s = {s_on:g} m, not at {start_s_m:g} m")
        t_on = round(t_of_s(s_on) - t_of_s(start_s_m), 3)     # on the 1 ms grid of the simulations
        direction = -tangent(s_on)
        for F in forces_n:
            cases.append((place, f"{F:g} N", {
                "gust_force_n": tuple(float(v) for v in np.round(F * direction, 12) + 0.0),
                "gust_window_s": (t_on, round(t_on + GUST_DURATION_S, 3)), "max_time_s": max_time_s,
                "start_s_m": float(start_s_m)}))
    return Experiment("gust", "Gust against the path's tangent: maneuver regulation and two time-indexed trackers",
                      DISTURBANCE, int(seed), _runs_by_case(seed, cases, saturations_n, controllers),
                      controller_path=PAPER_GOVERNED_CONTROLLER)


def lag(seed: int = 0, leads_m=LAG_LEADS_M, controllers=CONTROLLERS, saturations_n=ROTOR_LIMITS_N,
        max_time_s: float | None = None) -> Experiment:
    """The trackers' reference ``leads_m`` ahead of a vehicle on the nominal at
    :data:`LAG_START_S_M`, for each controller and rotor limit."""
    _check_controllers(controllers)
    cases = [("lag", f"{d:g} m ahead", {"start_s_m": LAG_START_S_M, "reference_lead_m": float(d),
                                        "max_time_s": max_time_s}) for d in leads_m]
    return Experiment("lag", "Timed reference ahead of the vehicle: maneuver regulation and two time-indexed "
                      "trackers", DISTURBANCE, int(seed), _runs_by_case(seed, cases, saturations_n, controllers),
                      controller_path=PAPER_GOVERNED_CONTROLLER)


EXPERIMENTS: dict[str, Callable[..., Experiment]] = {
    "paper-group1": paper_group1,
    "paper-group2": paper_group2,
    "gust": gust,
    "lag": lag,
}
"""Every experiment ``mavreg experiment`` knows, by name."""


SITL_ROTOR_LIMIT_N = 12.0
"""The emulator's rotors always clip at the vehicle file's limit: no ideal rotors via sitl."""


def build_experiment(name: str, seed: int = 0, via: str = "sim") -> Experiment:
    """The experiment ``name`` with its default settings, drawn from ``seed``, as flown ``via``.

    Via ``sitl`` only maneuver regulation flies (the daemon flies the regulator): ``gust`` is
    its runs on the emulator's 12 N rotors; ``lag`` has nothing to fly there (for the
    regulator a reference ahead is no disturbance).

    Raises
    ------
    ValueError
        On an unknown name (the message lists the known ones), or ``lag`` via ``sitl``.
    """
    if name not in EXPERIMENTS:
        raise UsageError(f"unknown experiment {name!r}; known: {', '.join(EXPERIMENTS)}")
    if via == "sitl" and name == "lag":
        raise UsageError("lag flies only on the design model (--via sim): the daemon flies maneuver "
                         "regulation alone, which has no timed reference to lag behind")
    if via == "sitl" and name == "gust":
        return gust(seed, controllers=(REGULATOR,), saturations_n=(SITL_ROTOR_LIMIT_N,))
    return EXPERIMENTS[name](seed)
