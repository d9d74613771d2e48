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
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..cli.common import DEFAULT_VEHICLE, PAPER_CONTROLLER, PARAMS_DIR

__all__ = ["RunSpec", "Experiment", "EXPERIMENTS", "build_experiment", "draw_inertia", "run_seed",
           "paper_group1", "paper_group2", "PAPER_INERTIA_SD_KG_M2", "PAPER_OFFSET_M",
           "PAPER_ROTOR_NOISE_SD_N", "PAPER_SATURATIONS_N", "PAPER_LAPS", "MIN_INERTIA_KG_M2",
           "CONVERGENCE", "SATURATION"]

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
                      SATURATION, int(seed), runs, vehicle_path=vehicle_path)


EXPERIMENTS: dict[str, Callable[..., Experiment]] = {
    "paper-group1": paper_group1,
    "paper-group2": paper_group2,
}
"""Every experiment ``mavreg experiment`` knows, by name."""


def build_experiment(name: str, seed: int = 0) -> Experiment:
    """The experiment ``name`` with its default settings, drawn from ``seed``.

    Raises
    ------
    ValueError
        On an unknown name (the message lists the known ones).
    """
    if name not in EXPERIMENTS:
        raise ValueError(f"unknown experiment {name!r}; known: {', '.join(EXPERIMENTS)}")
    return EXPERIMENTS[name](seed)
