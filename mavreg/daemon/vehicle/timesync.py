r"""The link's sample-to-actuation delay, measured with TIMESYNC (sans-I/O).

What the predictor needs is not the round trip of the link but the time from the instant a
state sample describes (its ``time_boot_ms``) to the instant a command answering it reaches
the vehicle. Both ends of that interval are on the *vehicle's* clock, so no clock offset has
to be estimated: right after answering a sample of time :math:`t_s`, the daemon sends a
TIMESYNC request (``tc1 = 0``, ``ts1`` = its own clock in ns, as the MAVLink spec and PX4
have it) and remembers :math:`t_s` under that ``ts1``. The vehicle answers with ``tc1`` = its
clock when it handled the request, which travelled the same way as the command. So

.. math:: d = tc_1 - t_s

is the downlink delay of the sample, the daemon's own processing, and the uplink delay of
the command, in vehicle time. It holds in real time and in lockstep alike (in lockstep the
wall clock means nothing to the vehicle), and asymmetric links need no assumption.

Each reply gives one sample of d. The estimate is the median of the last ``window`` samples
(robust to a late or reordered reply); the jitter is 1.4826 times their median absolute
deviation (the standard deviation, for Gaussian jitter). The wall-clock round trip
``now - ts1`` is reported too, for the operator.
"""
from __future__ import annotations

from collections import OrderedDict, deque
from dataclasses import dataclass

import numpy as np

__all__ = ["LinkDelay", "TimesyncEstimator"]


@dataclass(frozen=True)
class LinkDelay:
    """The measured sample-to-actuation delay of the link."""

    delay_s: float
    """Median of the recent delay samples (vehicle time)."""
    jitter_s: float
    """Robust standard deviation of the samples (1.4826 MAD)."""
    round_trip_s: float
    """Median wall-clock round trip of the TIMESYNC exchange."""
    samples: int


class TimesyncEstimator:
    """Keeps TIMESYNC requests in flight and turns replies into a delay estimate.

    Parameters
    ----------
    request_period_s : float
        Vehicle time between two requests.
    window : int
        Delay samples kept for the median.
    max_in_flight : int
        Unanswered requests remembered (older ones are forgotten: their reply is dropped).
    max_delay_s : float
        A reply implying a longer delay is dropped as implausible.
    """

    def __init__(self, request_period_s: float = 0.1, window: int = 31, max_in_flight: int = 16,
                 max_delay_s: float = 1.0):
        if not (request_period_s > 0 and window >= 1 and max_in_flight >= 1 and max_delay_s > 0):
            raise ValueError("TimesyncEstimator: periods, sizes and limits must be positive")
        self.request_period_s = float(request_period_s)
        self.max_delay_s = float(max_delay_s)
        self.max_in_flight = int(max_in_flight)
        self._in_flight: OrderedDict[int, float] = OrderedDict()
        self._delays: deque = deque(maxlen=int(window))
        self._rtts: deque = deque(maxlen=int(window))
        self._last_request_t = -np.inf
        self.dropped = 0
        self._estimate: LinkDelay | None = None     # recomputed only when a reply changes it

    def restart(self) -> None:
        """Forget the requests in flight and the delay samples (the vehicle rebooted: its clock
        starts again, and the delay is measured again); ``dropped`` is kept."""
        self._in_flight.clear()
        self._delays.clear()
        self._rtts.clear()
        self._last_request_t = -np.inf
        self._estimate = None

    def due(self, sample_time_s: float) -> bool:
        """Whether a request should go out after answering the sample of this vehicle time."""
        return sample_time_s - self._last_request_t >= self.request_period_s - 1e-9 or \
            sample_time_s < self._last_request_t

    def request(self, now_ns: int, sample_time_s: float) -> int:
        """Record a request sent at daemon clock ``now_ns`` right after answering the sample
        of vehicle time ``sample_time_s``; returns the ``ts1`` to send."""
        ts1 = int(now_ns)
        while ts1 in self._in_flight:
            ts1 += 1
        self._in_flight[ts1] = float(sample_time_s)
        while len(self._in_flight) > self.max_in_flight:
            self._in_flight.popitem(last=False)
        self._last_request_t = float(sample_time_s)
        return ts1

    def reply(self, tc1_ns: int, ts1_ns: int, now_ns: int) -> bool:
        """Take a TIMESYNC reply; False (and counted in ``dropped``) if it answers no request
        of ours or implies an implausible delay."""
        t_sample = self._in_flight.pop(int(ts1_ns), None)
        if t_sample is None:
            self.dropped += 1
            return False
        d = tc1_ns * 1e-9 - t_sample
        if not (0.0 <= d <= self.max_delay_s):
            self.dropped += 1
            return False
        self._delays.append(d)
        self._rtts.append((now_ns - ts1_ns) * 1e-9)
        self._estimate = None
        return True

    def estimate(self) -> LinkDelay | None:
        """The current estimate, or None before the first valid reply.

        The supervisor asks for it on every sample (the prediction's horizon); it changes
        only with a reply (every 0.1 s), so it is computed once per reply and kept."""
        if self._estimate is None and self._delays:
            d = np.fromiter(self._delays, float)
            med = float(np.median(d))
            self._estimate = LinkDelay(med, float(1.4826 * np.median(np.abs(d - med))),
                                       float(np.median(np.fromiter(self._rtts, float))), len(d))
        return self._estimate
