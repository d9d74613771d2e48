"""The robustness experiment's matrix: which flights ``mavreg experiment robustness`` flies.

It judges the product as shipped: the default controller of ``mavreg fly``
(``params/controller/realistic.yaml``, its envelope untouched) on firmware_sim's default
``realistic`` world, one factor changed at a time from the baseline (the barrel roll on the
nominal vehicle). Each :class:`Cell` is one such change, given to the emulator as its own
arguments (``mavreg fly --emulator-arg=...``); a rotor limit is also told to the controller
(a copy of the default file with ``allocation.max_rotor_thrust_n``, as the paper-group2 runs
do). Groups of cells (``--cells`` takes a group or a cell name):

- ``baseline``: the barrel roll, realistic world, nominal vehicle.
- ``wind3``: a steady 3 m/s wind from each of 8 compass directions; ``wind6``: 6 m/s from 4.
- ``thrust90``: the rotors give 90 % of their command.
- ``gust``: 8 N against the path for 1 s, on the run-up at speed, at low speed and at the
  loop's start (the ``gust`` experiment's places and windows, :func:`.definitions.gust`).
- ``rotors``: the rotors clip at 8.5 N or 7 N (12 N nominal), the controller told.
- ``mismatch``: an airframe drawn by the emulator (``--mismatch-seed``): mass, inertia,
  per-rotor thrust, yaw coefficient, arms, rotor lag, centre of mass.
- ``delay``: round trip 0, 20, 40, 60 ms, half each way, +-5 ms each way (none at 0 ms).
- ``loss``: 5 % of telemetry messages and command datagrams lost.
- ``timesync``: a vehicle that does not answer TIMESYNC (``--no-timesync``).
- ``estimator``: every estimator error twice as large (``--estimator-scale 2``).
- ``maneuvers``: every other file of ``params/maneuvers/`` on the default world (the barrel
  roll is the baseline).

``--via sim`` flies the cells the design model represents, the maneuver alone, on a
design-model version of the realistic world (:mod:`.robustness_sim`).

Seeds: flight ``k`` of every cell uses the emulator noise seed ``run_seed(seed, k)``
(common random numbers: cells differ by their factor, not by their noise); the mismatch
cell's flight ``k`` also draws its airframe from ``run_seed(seed, MISMATCH_STREAM + k)``.
Every seed is fixed when the experiment is built, before any flight.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import UsageError
from ..config.paths import DEFAULT_VEHICLE, PARAMS_DIR, REAL_CONTROLLER
from .definitions import BARREL_ROLL, REGULATOR, Experiment, RunSpec, gust, run_seed

__all__ = ["ROBUSTNESS", "Cell", "RobustSpec", "RobustnessExperiment", "all_cells", "select_cells",
           "robustness", "DEFAULT_FLIGHTS", "MISMATCH_STREAM", "GUST_FORCE_N", "WIND3_FROM_DEG",
           "WIND6_FROM_DEG", "ROUND_TRIPS_MS", "JITTER_MS", "ROTOR_LIMITS_N", "check_emulator"]

ROBUSTNESS = "robustness"
"""Kind of the robustness experiment: each flight judged by the daemon's outcome and its safety."""
DEFAULT_FLIGHTS = 2
"""Flights (seeds) per cell unless ``--flights`` says otherwise; every cell, the mismatch one
included, gets the same number (its 100 draws: ``--cells mismatch --flights 100``)."""
MISMATCH_STREAM = 1 << 20
"""The mismatch draws are seeded ``run_seed(seed, MISMATCH_STREAM + k)``: apart from the noise seeds."""
GUST_FORCE_N = 8.0
WIND3_FROM_DEG = (0, 45, 90, 135, 180, 225, 270, 315)
WIND6_FROM_DEG = (0, 90, 180, 270)
ROUND_TRIPS_MS = (0, 20, 40, 60)
JITTER_MS = 5.0
"""Half-width of each direction's uniform delay spread (clipped to the delay: none at 0 ms)."""
ROTOR_LIMITS_N = (8.5, 7.0)
MANEUVERS_DIR = PARAMS_DIR / "maneuvers"


@dataclass(frozen=True)
class Cell:
    """One case of the matrix: what differs from the baseline flight."""

    name: str
    group: str
    title: str
    """What differs, in a few words."""
    emulator_args: tuple[str, ...] = ()
    """firmware_sim arguments, each ``--flag`` or ``--flag=value``."""
    maneuver_path: Path = BARREL_ROLL
    saturation_n: float | None = None
    """The rotors clip at this force (emulator) and the controller is told it; None: the vehicle file's."""
    gust_place: str | None = None
    """A :data:`~.definitions.GUST_PLACES` key: an 8 N force against the path there for 1 s."""
    mismatch: bool = False
    """Each flight flies an airframe the emulator draws from its own seed."""


@dataclass(frozen=True)
class RobustSpec(RunSpec):
    """One flight of the robustness experiment: a :class:`~.definitions.RunSpec` with its
    cell's emulator arguments and maneuver file."""

    rotor_noise_sd_n: float | None = None
    """None: the vehicle file's rotor noise (not overridden)."""
    laps: int | None = None
    """None: the maneuver file's own laps count."""
    cell: str = ""
    emulator_args: tuple[str, ...] = ()
    """firmware_sim arguments of this flight (the cell's, and ``--mismatch-seed``)."""
    maneuver_path: Path | None = None
    mismatch_seed: int | None = None


@dataclass(frozen=True)
class RobustnessExperiment(Experiment):
    """The robustness campaign: :class:`RobustSpec` runs of the chosen cells."""

    world: str = "realistic"
    """firmware_sim's world preset (``mavreg fly --world``)."""
    widen_envelope: bool = False
    """False: the controller file flies as is (the other experiments widen its envelope)."""
    flights: int = DEFAULT_FLIGHTS
    cells: tuple[Cell, ...] = ()
    via: str = "sitl"
    """``sitl``: the whole flight against firmware_sim; ``sim``: the maneuver on the design
    model (:mod:`.robustness_sim`)."""
    skipped: tuple[tuple[str, str], ...] = ()
    """(cell, why) of the chosen cells that do not fly this way."""


def _delay_args(rtt_ms: int) -> tuple[str, ...]:
    """The emulator's link options of a round trip: half of it each way, in seconds (the
    text is the decimal meant, so that the emulator reads the double it read from ms)."""
    one_way_s = rtt_ms / 2.0 / 1000.0
    jitter_s = min(JITTER_MS / 1000.0, one_way_s)
    return (f"--telemetry-delay-s={one_way_s:g}", f"--telemetry-jitter-s={jitter_s:g}",
            f"--command-delay-s={one_way_s:g}", f"--command-jitter-s={jitter_s:g}")


def all_cells(maneuvers_dir: Path = MANEUVERS_DIR) -> tuple[Cell, ...]:
    """Every cell of the matrix, in the order of the tables (see the module docstring)."""
    cells = [Cell("baseline", "baseline", "barrel roll, realistic world, nominal vehicle")]
    cells += [Cell(f"wind3-from-{d:03d}", "wind3", f"3 m/s wind from {d} deg",
                   ("--wind-speed-m-s=3", f"--wind-from-deg={d}")) for d in WIND3_FROM_DEG]
    cells += [Cell(f"wind6-from-{d:03d}", "wind6", f"6 m/s wind from {d} deg",
                   ("--wind-speed-m-s=6", f"--wind-from-deg={d}")) for d in WIND6_FROM_DEG]
    cells.append(Cell("thrust90", "thrust90", "rotors give 90 % of their command", ("--thrust-scale=0.9",)))
    cells += [Cell(f"gust-{p}", "gust", f"{GUST_FORCE_N:g} N against the path for 1 s, {what}", gust_place=p)
              for p, what in (("run-up", "run-up at 8 m/s"), ("slow", "run-up at 0.75 m/s"),
                              ("loop", "loop's start"))]
    cells += [Cell(f"rotors-{f:g}n", "rotors", f"rotors clip at {f:g} N (controller told)", saturation_n=f)
              for f in ROTOR_LIMITS_N]
    cells.append(Cell("mismatch", "mismatch", "airframe drawn by the emulator (--mismatch-seed)", mismatch=True))
    cells += [Cell(f"rtt-{r:03d}ms", "delay", f"round trip {r} ms" + (f", +-{JITTER_MS:g} ms each way" if r else ""),
                   _delay_args(r)) for r in ROUND_TRIPS_MS]
    cells.append(Cell("loss-5pct", "loss", "5 % of messages lost", ("--loss=0.05",)))
    cells.append(Cell("no-timesync", "timesync", "vehicle does not answer TIMESYNC", ("--no-timesync",)))
    cells.append(Cell("estimator-x2", "estimator", "estimator errors x2", ("--estimator-scale=2",)))
    for path in sorted(Path(maneuvers_dir).glob("*.yaml")):
        if path.resolve() != BARREL_ROLL.resolve():
            cells.append(Cell(f"maneuver-{path.stem}", "maneuvers", f"{path.stem}, default world",
                              maneuver_path=path.resolve()))
    return tuple(cells)


def select_cells(only: str | None, cells: tuple[Cell, ...] | None = None) -> tuple[Cell, ...]:
    """The cells ``only`` names (comma-separated cell or group names; None or ``all``: every
    cell), in matrix order.

    Raises
    ------
    ValueError
        A name that is neither a cell nor a group (the message lists the groups), or nothing chosen.
    """
    cells = all_cells() if cells is None else cells
    if only is None or only.strip() == "all":
        return cells
    names = [n.strip() for n in only.split(",") if n.strip()]
    if not names:
        raise UsageError("--cells names no cell; give cell or group names separated by commas")
    groups = list(dict.fromkeys(c.group for c in cells))
    known = {c.name for c in cells} | set(groups)
    bad = [n for n in names if n not in known]
    if bad:
        raise UsageError(f"--cells: unknown cell or group {bad[0]!r}; groups: {', '.join(groups)} "
                         "(or a cell name, e.g. wind3-from-090; see docs/experiments.md)")
    return tuple(c for c in cells if c.name in names or c.group in names)


def _gust_fields(place: str) -> dict:
    """The gust experiment's force and window at ``place`` (its 8 N case)."""
    (run,) = gust(0, forces_n=(GUST_FORCE_N,), places=(place,), controllers=(REGULATOR,),
                  saturations_n=(None,)).runs
    return {"gust_force_n": run.gust_force_n, "gust_window_s": run.gust_window_s}


def robustness(seed: int = 0, flights: int = DEFAULT_FLIGHTS, only: str | None = None) -> RobustnessExperiment:
    """The robustness experiment: ``flights`` flights of each cell ``only`` chooses
    (:func:`select_cells`), every seed drawn from ``seed`` now (see the module docstring)."""
    if isinstance(flights, bool) or not isinstance(flights, int) or flights < 1:
        raise UsageError(f"--flights must be a whole number of at least 1, got {flights!r}")
    cells = select_cells(only)
    noise = [run_seed(seed, k) for k in range(flights)]
    gusts = {c.gust_place: _gust_fields(c.gust_place) for c in cells if c.gust_place}
    runs = []
    for cell in cells:
        for k in range(flights):
            mseed = run_seed(seed, MISMATCH_STREAM + k) if cell.mismatch else None
            args = cell.emulator_args + ((f"--mismatch-seed={mseed}",) if mseed is not None else ())
            runs.append(RobustSpec(len(runs), f"{cell.name} #{k}", saturation_n=cell.saturation_n, seed=noise[k],
                                   group=cell.group, case=cell.name, cell=cell.name, emulator_args=args,
                                   maneuver_path=Path(cell.maneuver_path).resolve(), mismatch_seed=mseed,
                                   **gusts.get(cell.gust_place, {})))
    return RobustnessExperiment(ROBUSTNESS, "Robustness of the default controller and its safety layer",
                                ROBUSTNESS, int(seed), tuple(runs), vehicle_path=DEFAULT_VEHICLE,
                                controller_path=REAL_CONTROLLER, flights=flights, cells=cells)


def check_emulator(exp: RobustnessExperiment) -> None:
    """Raise ValueError (one line) when a chosen cell needs a firmware_sim option this one lacks."""
    from firmware_sim.cli import build_parser
    known = set(build_parser()._option_string_actions)
    for cell in exp.cells:
        need = [a.split("=")[0] for a in cell.emulator_args] + (["--mismatch-seed"] if cell.mismatch else [])
        missing = [a for a in need if a not in known]
        if missing:
            raise UsageError(f"cell {cell.name} needs firmware-sim {missing[0]}, which this firmware_sim does not "
                             "have; leave the cell out with --cells")
