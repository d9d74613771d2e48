"""mavreg: maneuver regulation of a quadrotor, after Spedicato, Notarstefano, Bülthoff and Franchi.

A maneuver is a path with a speed and a yaw profile on it (a YAML file, docs/maneuvers.md).
Planning gives its nominal state and input by differential flatness, checks them against the
vehicle, and designs an LQR on the transverse coordinates scheduled by the arc length ``s``
of the nearest point on the path, not by time; the regulator flies
``u = u_nominal(s) - K(s) w``. The same objects back the ``mavreg`` commands.

Load, plan, simulate, look (docs/api.md; ``mavreg plan`` and ``mavreg simulate`` do the same)::

    import mavreg
    roll = mavreg.load_maneuver(mavreg.config.paths.maneuver_file("barrel_roll"))
    plan = mavreg.plan(roll)                  # the MK-Quadro and realistic.yaml, as `mavreg fly`
    plan.summary()["margins"]                 # what `mavreg plan` prints
    run = mavreg.simulate(plan, entry_offset=(0.6, 0.6, 0.6))
    run.metrics["transverse_error_m"]         # {"max": ..., "rms": ...}, m
    mavreg.plot_simulation("roll.png", plan, run)

Functions (imported on first use, so ``import mavreg`` costs nothing):

- :func:`load_vehicle`, :func:`load_controller`, :func:`load_maneuver`,
  :func:`load_maneuver_text`: the parameter files, through the one validating loader;
- :func:`plan`: nominal, feasibility, gain schedule and margins, through the plan cache;
- :func:`simulate`: the closed loop on the design model, with tracking metrics against ``s``;
- :func:`plot_plan`, :func:`plot_simulation`: the commands' figures.

Classes of the results: :class:`Plan`, :class:`ManeuverRun`; of the parameters:
:class:`VehicleParams`, :class:`ControllerParams`, :class:`ManeuverSpec`. The bundled files:
:mod:`mavreg.config.paths` (``maneuver_file(NAME)``, ``maneuver_files()``,
``controller_file(NAME)``, ``vehicle_file(NAME)``, ``PAPER_CONTROLLER``).
"""
import importlib as _importlib

__all__ = ["load_vehicle", "load_controller", "load_maneuver", "load_maneuver_text", "plan", "simulate",
           "plot_plan", "plot_simulation", "Plan", "ManeuverRun", "VehicleParams", "ControllerParams",
           "ManeuverSpec"]

_LAZY = {
    **{name: "mavreg.api" for name in ("load_vehicle", "load_controller", "load_maneuver", "load_maneuver_text",
                                       "plan", "simulate", "plot_plan", "plot_simulation")},
    "Plan": "mavreg.maneuver.plan",
    "ManeuverRun": "mavreg.sim.maneuver_run",
    "VehicleParams": "mavreg.config.vehicle",
    "ControllerParams": "mavreg.config.controller",
    "ManeuverSpec": "mavreg.config.maneuver",
}
"""Where each name of the API lives; imported at its first use (PEP 562)."""


def __getattr__(name: str):
    """The API's names, each imported from its module at its first use (PEP 562)."""
    if name in _LAZY:
        value = getattr(_importlib.import_module(_LAZY[name]), name)
        globals()[name] = value          # once: later lookups do not come here
        return value
    if name == "config":                 # mavreg.config.paths reachable after `import mavreg`
        _importlib.import_module("mavreg.config.paths")
        return _importlib.import_module("mavreg.config")
    raise AttributeError(f"module 'mavreg' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The module's names and the API's, imported or not."""
    return sorted(set(globals()) | set(__all__))
