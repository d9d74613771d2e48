"""The library's API for notebooks and scripts: what ``mavreg plan`` and ``mavreg simulate`` do,
as functions.

Each function is the command's own code path, not a second one: :func:`plan` is the planner
behind the plan cache with the margins ``mavreg plan`` prints (and the daemon computes before
it flies), :func:`simulate` is ``mavreg simulate``'s run (the command calls it). The defaults
are the commands': the bundled MK-Quadro and ``params/controller/realistic.yaml``, the
controller ``mavreg fly`` flies. Nothing heavy is imported until a function is called, so
``import mavreg`` stays fast (:mod:`mavreg` imports this module on first use).

The bundled files are found by :mod:`mavreg.config.paths` (``maneuver_file("barrel_roll")``,
``maneuver_files()``, ``controller_file("paper_lqr")``, ``vehicle_file("mk_quadro")``).
"""
from __future__ import annotations

import os
from typing import TYPE_CHECKING

from .config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER

if TYPE_CHECKING:
    from .config.controller import ControllerParams
    from .config.maneuver import ManeuverSpec
    from .config.vehicle import VehicleParams
    from .maneuver.plan import Plan
    from .sim.maneuver_run import ManeuverRun

__all__ = ["load_vehicle", "load_controller", "load_maneuver", "load_maneuver_text", "plan", "simulate",
           "plot_plan", "plot_simulation"]


def load_vehicle(path: str | os.PathLike = DEFAULT_VEHICLE) -> VehicleParams:
    """Load a vehicle file (``kind: vehicle``; ``--vehicle-params`` of the commands).

    Parameters
    ----------
    path : str or os.PathLike, optional
        The YAML file. Default: the bundled MK-Quadro of the paper
        (:data:`mavreg.config.paths.DEFAULT_VEHICLE`), the commands' default.

    Returns
    -------
    mavreg.config.vehicle.VehicleParams
        Frozen; make a variant with :func:`dataclasses.replace`.

    Raises
    ------
    mavreg.config.loader.ConfigError
        An unknown, missing or out-of-range key (one line saying which).

    Examples
    --------
    >>> import mavreg
    >>> vehicle = mavreg.load_vehicle()
    >>> vehicle.name, vehicle.mass_kg, vehicle.max_rotor_thrust_n
    ('mk_quadro', 0.749, 12.0)
    """
    from .config.vehicle import load_vehicle as load
    return load(path)


def load_controller(path: str | os.PathLike = REAL_CONTROLLER) -> ControllerParams:
    """Load a controller file (``kind: controller``; ``--controller`` of the commands).

    Parameters
    ----------
    path : str or os.PathLike, optional
        The YAML file. Default: ``params/controller/realistic.yaml``
        (:data:`mavreg.config.paths.REAL_CONTROLLER`), the controller of ``mavreg fly``,
        ``serve``, ``plan`` and ``simulate``. The paper's design is
        ``mavreg.config.paths.PAPER_CONTROLLER``.

    Returns
    -------
    mavreg.config.controller.ControllerParams
        The LQR weights, the attitude error, the rotor lag in the design, the allocation,
        the speed governor, the observer and the flight envelope.

    Examples
    --------
    >>> import mavreg
    >>> controller = mavreg.load_controller()
    >>> controller.attitude_error, controller.rotor_lag_in_design
    ('so3', True)
    >>> paper = mavreg.load_controller(mavreg.config.paths.PAPER_CONTROLLER)
    >>> paper.attitude_error, paper.rotor_lag_in_design
    ('rpy', False)
    """
    from .config.controller import load_controller as load
    return load(path)


def load_maneuver(path: str | os.PathLike, laps: int | None = None) -> ManeuverSpec:
    """Load a maneuver file (``kind: maneuver``; docs/maneuvers.md).

    Parameters
    ----------
    path : str or os.PathLike
        The YAML file; the bundled library's by ``mavreg.config.paths.maneuver_file(NAME)``.
    laps : int, optional
        Fly the file's ``laps:`` segment this many times (``--laps``). Default: as in the file.

    Returns
    -------
    mavreg.config.maneuver.ManeuverSpec

    Raises
    ------
    mavreg.config.loader.ConfigError
        The file is not a valid maneuver (one line saying where).
    ValueError
        ``laps`` for a maneuver without a laps segment, or out of 1..100.

    Examples
    --------
    >>> import mavreg
    >>> roll = mavreg.load_maneuver(mavreg.config.paths.maneuver_file("barrel_roll"))
    >>> roll.name, [segment.name for segment in roll.segments]
    ('barrel_roll', ['run_up', 'loop', 'run_out'])
    >>> mavreg.load_maneuver(mavreg.config.paths.maneuver_file("barrel_roll"), laps=3).laps.count
    3
    """
    from .config.maneuver import load_maneuver as load
    spec = load(path)
    return spec if laps is None else spec.with_laps(laps)


def load_maneuver_text(text: str, source: str = "<text>") -> ManeuverSpec:
    """Load a maneuver from YAML text (a notebook cell; what ``mavreg upload`` sends).

    Parameters
    ----------
    text : str
        The maneuver's YAML, as in a file (docs/maneuvers.md); flow style works too.
    source : str, optional
        The name errors give it.

    Returns
    -------
    mavreg.config.maneuver.ManeuverSpec

    Examples
    --------
    A 3 m line at 1 m/s, 1.5 m up:

    >>> import mavreg
    >>> hop = mavreg.load_maneuver_text(
    ...     "{kind: maneuver, version: 1, name: hop, start: {position_m: [0, 1, -1.5],"
    ...     " heading_deg: 90, climb_deg: 0}, segments: [{name: line, line: {length_m: 3}}],"
    ...     " speed: {initial_m_s: 1.0}}")
    >>> hop.name, hop.speed.initial_m_s
    ('hop', 1.0)
    """
    from .config.maneuver import load_maneuver_text as load
    return load(text, source)


def plan(maneuver: ManeuverSpec | str | os.PathLike, vehicle: VehicleParams | None = None,
         controller: ControllerParams | None = None, *, strict: bool = False, margins: bool = True,
         cache: bool = True) -> Plan:
    r"""Plan a maneuver: its path, nominal, feasibility, gain schedule and margins (``mavreg plan``).

    The nominal state and input follow by differential flatness; they are checked against the
    vehicle (rotor forces in :math:`[0, f_{max}]`, speed, tilt); the gains :math:`K(s)` of the
    regulator :math:`u = \bar u(s) - K(s)\, w` come from an LQR on the transverse coordinates
    :math:`w`, scheduled on the arc length :math:`s` (docs/transverse.md). A plan is served
    from the plan cache when the same files and code planned it before (``plan.from_cache``).

    Parameters
    ----------
    maneuver : ManeuverSpec or str or os.PathLike
        A loaded maneuver (:func:`load_maneuver`) or the path of a maneuver file.
    vehicle : VehicleParams, optional
        Default: :func:`load_vehicle`'s.
    controller : ControllerParams, optional
        Default: :func:`load_controller`'s (``realistic.yaml``, what ``mavreg fly`` flies).
    strict : bool, optional
        Raise :class:`~mavreg.errors.ManeuverError` for an infeasible maneuver (as ``simulate``
        and the daemon do) instead of returning a plan whose ``feasibility.feasible`` is False
        and whose ``feasibility.violations`` say where (as ``mavreg plan`` does; the default).
    margins : bool, optional
        Compute the delay and gain margins of the regulator along the plan and of the hover
        loop, through the vehicle's rotor lag (``plan.margins``; about a second). Default True.
    cache : bool, optional
        Use the on-disk plan cache (``~/.cache/mavreg/plans``, ``$MAVREG_PLAN_CACHE``).

    Returns
    -------
    mavreg.maneuver.plan.Plan
        ``summary()`` is ``mavreg plan --json``'s dict, less the envelope check.

    Raises
    ------
    mavreg.errors.ManeuverError
        A maneuver that cannot be planned (a geometry, a divergent sweep; with ``strict``,
        infeasible).

    Examples
    --------
    >>> import mavreg
    >>> roll = mavreg.plan(mavreg.config.paths.maneuver_file("barrel_roll"))
    >>> roll.feasibility.feasible, round(roll.length_m, 2), round(roll.duration_s, 1)
    (True, 40.47, 21.5)
    >>> roll.margins.maneuver.delay_margin_s > 0.020      # through the rotors' 20 ms lag
    True
    """
    from .planning.cache import default_cache
    from .planning.plan_io import plan_cached
    spec = maneuver if not isinstance(maneuver, (str, os.PathLike)) else load_maneuver(maneuver)
    vehicle = load_vehicle() if vehicle is None else vehicle
    controller = load_controller() if controller is None else controller
    result = plan_cached(spec, vehicle, controller, strict, default_cache() if cache else None)
    if not margins:
        return result
    from .control.controllers.hover import HoverParams
    from .maneuver.plan_margins import with_margins
    return with_margins(result, HoverParams.from_controller(controller))


def _renamed(func: str, old: str, old_value, new: str, new_value):
    """``new_value``, or ``old_value`` with a DeprecationWarning where the caller used the old
    keyword ``old`` (an old name is kept for one release, as the command line's are)."""
    if old_value is None:
        return new_value
    import warnings
    warnings.warn(f"{func}({old}=) is deprecated and goes in the next release; use {new}",
                  DeprecationWarning, stacklevel=3)
    return old_value


def simulate(plan: Plan, controller: ControllerParams | None = None, *,
             entry_offset=(0.0, 0.0, 0.0), rotor_noise_sd_n: float = 0.0,
             rotor_saturation_n: float | None = None, seed: int | None = None,
             control_rate_hz: float = 1000.0, inertia_kg_m2=None, gust_n=None,
             gust_window_s=(0.0, 1.0), gust_window=None) -> ManeuverRun:
    r"""Fly a plan with the regulator on the design model (``mavreg simulate``; the command calls this).

    The paper's quadrotor model (eqs 6-17, ideal rotors) is integrated by RK4 in 1 ms steps
    from the plan's entry, in closed loop with :math:`u = \bar u(s) - K(s)\, w` at
    ``control_rate_hz`` (zero-order hold), to the end of the path or the nominal duration
    plus 5 s. The controller's ``allocation:`` and ``speed_governor:`` act, told
    ``rotor_saturation_n``. Names and units: ``mavreg simulate``'s options (docs/cli.md).

    Parameters
    ----------
    plan : Plan
        A feasible plan (:func:`plan`).
    controller : ControllerParams, optional
        The controller the plan was made with. Default: :func:`load_controller`'s, which is
        :func:`plan`'s default.
    entry_offset : (3,) array_like, optional
        Start this far (NED, m) from the maneuver's entry, with the entry's velocity,
        attitude and rates (``--entry-offset``; the paper's Section 4: 0.6, 0.6, 0.6).
    rotor_noise_sd_n : float, optional
        Gaussian noise on each rotor's force, N (standard deviation).
    rotor_saturation_n : float, optional
        The rotors give at most this many N each; the allocation and the speed governor are
        told. Default: no limit.
    seed : int, optional
        The noise's seed.
    control_rate_hz : float, optional
        The regulator's rate: 1000 Hz divided by a whole number.
    inertia_kg_m2 : (3,) array_like, optional
        The plant's principal moments, when they differ from the design's.
    gust_n, gust_window_s : (3,) and (2,) array_like, optional
        An external force on the vehicle (NED, N) from t0 to t1 (s from the start).

    Returns
    -------
    mavreg.sim.maneuver_run.ManeuverRun
        ``metrics``: ``mavreg simulate --json``'s dict (``stable``, ``completed``,
        ``transverse_error_m``, ``attitude_error_deg``, ``segments``); ``result``: time, state
        and rotor forces every 1 ms; ``s``, ``w``: arc length, transverse state per control step.

    Raises
    ------
    mavreg.errors.ManeuverError
        An infeasible plan (no gains).
    ValueError
        A plan made with another controller (another attitude error or rotor-lag design),
        a rate that is not 1000 Hz divided by a whole number, ``gust_window_s`` t0 > t1.

    Examples
    --------
    A 3 m hop, started 20 cm off its entry:

    >>> import mavreg
    >>> hop = mavreg.load_maneuver_text(
    ...     "{kind: maneuver, version: 1, name: hop, start: {position_m: [0, 1, -1.5],"
    ...     " heading_deg: 90, climb_deg: 0}, segments: [{name: line, line: {length_m: 3}}],"
    ...     " speed: {initial_m_s: 1.0}}")
    >>> run = mavreg.simulate(mavreg.plan(hop, margins=False), entry_offset=(0.0, 0.0, 0.2))
    >>> run.metrics["stable"], run.metrics["completed"]
    (True, True)
    >>> 0.19 < run.metrics["transverse_error_m"]["max"] < 0.21    # the offset, then closer
    True
    """
    from .config.regulation import told_rotor_limit
    from .sim.maneuver_run import fly_on_design_model
    controller = load_controller() if controller is None else controller
    _check_plan_of(plan, controller)
    gust_window_s = _renamed("simulate", "gust_window", gust_window, "gust_window_s", gust_window_s)
    if not gust_window_s[0] <= gust_window_s[1]:
        raise ValueError(f"gust_window_s must be t0 <= t1, got {tuple(gust_window_s)}")
    return fly_on_design_model(plan, offset_m=entry_offset, inertia_kg_m2=inertia_kg_m2,
                               rotor_noise_sd_n=rotor_noise_sd_n, saturation_n=rotor_saturation_n,
                               seed=seed, control_rate_hz=control_rate_hz, gust_force_n=gust_n,
                               gust_window_s=tuple(gust_window_s),
                               allocation=told_rotor_limit(controller.allocation, rotor_saturation_n),
                               speed_governor=controller.speed_governor)


def _check_plan_of(plan: Plan, controller: ControllerParams) -> None:
    """Refuse an infeasible plan, and a plan whose gains another controller designed."""
    from .errors import ManeuverError
    if not plan.feasibility.feasible:
        raise ManeuverError(f"maneuver {plan.name!r} is infeasible: " + "; ".join(plan.feasibility.violations))
    lagged = plan.rotor_time_constant_s > 0
    if plan.attitude_error != controller.attitude_error or lagged != controller.rotor_lag_in_design:
        raise ValueError(f"the plan of {plan.name!r} was made with another controller (attitude error "
                         f"{plan.attitude_error}, rotor lag in the design: {lagged}) than the one given "
                         f"({controller.attitude_error}, {controller.rotor_lag_in_design}): pass the "
                         "controller the plan was made with")


def plot_plan(path: str | os.PathLike, plan: Plan) -> None:
    """Save the figure of a plan's nominal (``mavreg plan --plot``).

    The path in 3-D, from the top (north up, east right) and the side at equal scale, with
    the start, the direction of travel and the numbered segments; the speed, the collective
    thrust, the rotor forces (against their limit) and the body rates against the arc length.
    An infeasible plan's violations are in the title. matplotlib (Agg backend) is imported
    here, not before.

    Parameters
    ----------
    path : str or os.PathLike
        The figure's file: ``.png``, ``.pdf``, ``.svg``, ``.jpg``.
    plan : Plan

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import mavreg
    >>> roll = mavreg.plan(mavreg.config.paths.maneuver_file("barrel_roll"), margins=False)
    >>> png = pathlib.Path(tempfile.mkdtemp()) / "barrel_roll_plan.png"
    >>> mavreg.plot_plan(png, roll)
    >>> png.read_bytes()[:4] == b"\\x89PNG"
    True
    """
    from .plots import plot_plan as plot
    plot(path, plan)


def plot_simulation(path: str | os.PathLike, plan: Plan, run: ManeuverRun,
                    control_rate_hz: float = 1000.0) -> None:
    """Save the figure of a simulated flight (``mavreg simulate --plot``).

    The path flown (3-D, top and side views), the transverse and attitude errors against the
    arc length (log scale), the speed, the thrust, the rotor forces and the schedule.

    Parameters
    ----------
    path : str or os.PathLike
        The figure's file: ``.png``, ``.pdf``, ``.svg``, ``.jpg``.
    plan : Plan
        The plan the run flew.
    run : ManeuverRun
        :func:`simulate`'s result.
    control_rate_hz : float, optional
        The rate the run was flown at (:func:`simulate`'s ``control_rate_hz``).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import mavreg
    >>> hop = mavreg.plan(mavreg.load_maneuver_text(
    ...     "{kind: maneuver, version: 1, name: hop, start: {position_m: [0, 1, -1.5],"
    ...     " heading_deg: 90, climb_deg: 0}, segments: [{name: line, line: {length_m: 3}}],"
    ...     " speed: {initial_m_s: 1.0}}"), margins=False)
    >>> png = pathlib.Path(tempfile.mkdtemp()) / "hop.png"
    >>> mavreg.plot_simulation(png, hop, mavreg.simulate(hop))
    >>> png.stat().st_size > 10_000
    True
    """
    from .plots import plot_simulation as plot
    plot(path, plan, run, control_rate_hz)
