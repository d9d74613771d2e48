"""The figures of ``mavreg plan --plot``, ``mavreg simulate --plot`` and ``mavreg fly``
(``flight.png``): matplotlib with the Agg backend, imported only when a figure is asked for.

- :func:`plot_plan`: the nominal's path (3-D, top and side views), speed, thrust, rotor
  forces and body rates against arc length;
- :func:`plot_simulation`: a design-model flight, its errors (log scale), speed, thrust,
  rotor forces and schedule;
- :func:`plot_fly`: a flight of the daemon, its TRUE errors from the emulator's ground truth
  (with the controller's own for comparison), the whole flight by phase, and a failure's
  cause and place.

Views are map-correct: east right, north up, altitude up, at equal scale (:mod:`.views`).
"""
from __future__ import annotations

__all__ = ["plot_plan", "plot_simulation", "plot_fly"]


def plot_plan(png_path, plan, note: str = "", violations=None) -> None:
    """Save the figure of a plan's nominal (``mavreg plan --plot``); ``violations`` (default:
    the plan's feasibility's) go in its title, in red."""
    from .figures import plan_figure
    plan_figure(png_path, plan, note, violations)


def plot_simulation(png_path, plan, run, control_rate_hz: float, heading: str = "") -> None:
    """Save the figure of a design-model flight (``mavreg simulate --plot``).

    Parameters
    ----------
    run : :class:`~mavreg.sim.maneuver_run.ManeuverRun`
    control_rate_hz : the regulator's rate the run was flown at.
    """
    from .figures import flight_figure
    from .sources import from_simulation
    flight_figure(png_path, plan, from_simulation(plan, run, control_rate_hz,
                                                  heading or f"{plan.name} on the design model"))


def plot_fly(png_path, plan, ctrl: dict, record: dict | None, summary: dict | None,
             heading: str = "") -> None:
    """Save ``mavreg fly``'s ``flight.png``.

    Parameters
    ----------
    ctrl : the control log (:func:`mavreg.daemon.jobs.ctrllog.load_control_log`).
    record : the emulator's recording (``t_s``, ``position_ned_m`` and, optionally,
        ``quaternion_wxyz``, ``velocity_ned_m_s``), or None for a vehicle without one.
    summary : ``summary.json``'s dict (``result``, ``reason``, ``failure``), or None.
    """
    from .figures import flight_figure
    from .sources import from_fly
    flight_figure(png_path, plan, from_fly(plan, ctrl, record, summary,
                                           heading or f"{plan.name} flown by mavreg fly"))
