r"""Which rotor lag is in effect: one answer that every user asks, and nobody copies.

The rotors' first-order time constant :math:`\tau` has three sources:

- the vehicle file's ``rotor_time_constant_s``, the controller's belief before flight;
- the plan's ``rotor_time_constant_s``, the lag its gains were designed on (0: gains on the
  paper's ideal rotors, ``rotor_lag_in_design: false``);
- the in-flight estimate of the disturbance observer's rotor-lag part
  (:mod:`mavreg.control.estimation.lag_observer`), and its follower at a bounded rate.

:class:`RotorLagInEffect` answers the flight's questions from the file and the estimate, read
live at each call: the predictor lags the commands by :attr:`~RotorLagInEffect.estimate_s`,
the regulator's feedforward leads by :attr:`~RotorLagInEffect.applied_s`, and the rates
output lags the commanded torque by the same. :func:`plant_lag_s` answers the plan's
question: the lag a plan's loops are analysed on (its margins).

Pure: numbers in, numbers out.

Examples
--------
>>> from types import SimpleNamespace
>>> lag = RotorLagInEffect(0.02)
>>> lag.estimate_s, lag.applied_s
(0.02, 0.02)
>>> observer = SimpleNamespace(estimate_s=0.035, applied_s=0.03)
>>> lag = RotorLagInEffect(0.02, observer)
>>> lag.estimate_s, lag.applied_s, lag.file_s
(0.035, 0.03, 0.02)
"""
from __future__ import annotations

from typing import Protocol

__all__ = ["LagEstimate", "RotorLagInEffect", "plant_lag_s"]


class LagEstimate(Protocol):
    """What :class:`RotorLagInEffect` reads of an in-flight estimate
    (:class:`~mavreg.control.estimation.lag_observer.RotorLagObserver`)."""

    @property
    def estimate_s(self) -> float: ...

    @property
    def applied_s(self) -> float: ...


class RotorLagInEffect:
    """The rotor lag in effect now: the in-flight estimate where there is one, else the file's.

    Parameters
    ----------
    file_s : float
        The vehicle file's ``rotor_time_constant_s`` (s; 0: ideal rotors).
    estimate : LagEstimate, optional
        The rotor-lag part of the disturbance observer, read live at each question (None: no
        estimate in flight, the file's value holds).
    """

    def __init__(self, file_s: float, estimate: LagEstimate | None = None):
        self.file_s = float(file_s)
        self.estimate = estimate

    @classmethod
    def of_vehicle(cls, vehicle, estimate: LagEstimate | None = None) -> RotorLagInEffect:
        """The lag of ``vehicle``'s file (``rotor_time_constant_s``), with ``estimate`` if any."""
        return cls(vehicle.rotor_time_constant_s, estimate)

    @property
    def estimate_s(self) -> float:
        """What the prediction lags the commands by (s): the filter's estimate, else the file's."""
        return self.file_s if self.estimate is None else self.estimate.estimate_s

    @property
    def applied_s(self) -> float:
        """What the feedforward leads by and the rates output lags the torque by (s): the
        estimate's follower at a bounded rate, else the file's."""
        return self.file_s if self.estimate is None else self.estimate.applied_s


def plant_lag_s(plan) -> float:
    """The rotors' lag (s) a plan's loops are analysed on: the lag its gains were designed on,
    or, for gains on ideal rotors (``plan.rotor_time_constant_s`` 0), its vehicle file's.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> plant_lag_s(SimpleNamespace(rotor_time_constant_s=0.0,
    ...                             vehicle=SimpleNamespace(rotor_time_constant_s=0.02)))
    0.02
    """
    designed = float(plan.rotor_time_constant_s)
    return designed if designed > 0 else float(plan.vehicle.rotor_time_constant_s)
