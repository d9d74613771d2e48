"""The MAVLink link as FIFO delay lines in simulation time, with loss (sans-I/O).

Downlink (vehicle to peers)
    Everything a control period sends (HEARTBEAT and STATUSTEXT when due, ATTITUDE,
    ATTITUDE_QUATERNION, LOCAL_POSITION_NED) is one *bundle* with one delay draw. A
    bundle made at period k is due at ``k + delay / period`` and released at the period
    boundary nearest to that (delays are quantized to the control period), never before
    an earlier bundle: ``release = max(previous release, round(k + delay/period))``.
    Replies to commands (COMMAND_ACK, STATUSTEXT, HEARTBEAT, TIMESYNC) form bundles of
    their own, made at the physics step where the command was handled, with their own
    delay draw, in the same FIFO. Loss is drawn per message. A bundle is *complete* when
    its ATTITUDE_QUATERNION and LOCAL_POSITION_NED both survived: a peer then has a
    complete state sample of that time (the lockstep loop waits for an answer only then).
Uplink (peers to vehicle)
    Each received datagram gets its own delay, quantized to the physics step, and one
    loss draw (all its messages share the fate), FIFO: ``due = max(previous due,
    round(step + delay/dt))``. HEARTBEAT-only and undecodable datagrams are not
    delayed: they change nothing the vehicle could show late.

Delays are uniform in ``[delay - jitter, delay + jitter]``. Random numbers come from
independent streams seeded with ``[seed, 2]`` (downlink state bundles: delay, then loss
of ATTITUDE, ATTITUDE_QUATERNION, LOCAL_POSITION_NED), ``[seed, 4]`` (downlink: every
other message's loss and the replies' delays), ``[seed, 3]`` (uplink datagrams holding an
offboard target: SET_ACTUATOR_CONTROL_TARGET or SET_ATTITUDE_TARGET) and ``[seed, 5]`` (other uplink datagrams), so that chatter
which does not depend on the simulation (a peer's wall-clock heartbeat) leaves the draws
of the state and of the actuator stream alone. A draw is made only for an effect that is
on (non-zero jitter, non-zero loss); the rotor-noise stream (``seed``) is never touched.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from .world import LinkParams

__all__ = ["Uniforms", "Downlink", "Uplink"]

_CHUNK = 4096
_NOTHING = ((), 0)


class Uniforms:
    """Uniform numbers in [0, 1) from a seeded generator, drawn in chunks (no per-call numpy).

    Parameters
    ----------
    seed_sequence : list of int
        Passed to :func:`numpy.random.default_rng`.
    """

    def __init__(self, seed_sequence):
        self.rng = np.random.default_rng(seed_sequence)
        self._buf: list = []
        self._i = 0

    def next(self) -> float:
        """The next number of the stream."""
        if self._i >= len(self._buf):
            self._buf = self.rng.random(_CHUNK).tolist()
            self._i = 0
        u = self._buf[self._i]
        self._i += 1
        return u


def _ticks(delay_ticks: float) -> int:
    """Round a delay (>= 0) in ticks to the nearest tick, halves up."""
    return int(delay_ticks + 0.5)


class Downlink:
    """Telemetry delay line, released at control-period boundaries (see the module docstring).

    Parameters
    ----------
    params : LinkParams
    rate_hz : int
        Control (telemetry) rate: one tick of this line is one control period.
    substeps : int
        Physics steps per control period (replies are made at physics steps).
    seed : int
    """

    def __init__(self, params: LinkParams, rate_hz: int, substeps: int, seed: int):
        self.delay_periods = params.telemetry_delay_s * rate_hz
        self.jitter_periods = params.telemetry_jitter_s * rate_hz
        self.loss = params.loss_probability
        self.substeps = int(substeps)
        self._state_rng = Uniforms([int(seed), 2])
        self._event_rng = Uniforms([int(seed), 4])
        self._queue: deque = deque()       # (release period, [messages], complete)
        self._last_release = 0
        self.sent = 0
        self.lost = 0

    def _delay(self, rng: Uniforms) -> float:
        if self.jitter_periods:
            return max(0.0, self.delay_periods + self.jitter_periods * (2.0 * rng.next() - 1.0))
        return self.delay_periods

    def _enqueue(self, release: int, msgs: list, complete: bool) -> None:
        if release < self._last_release:
            release = self._last_release
        self._last_release = release
        self._queue.append((release, msgs, complete))

    def _survivors(self, msgs, rng: Uniforms) -> list:
        if not self.loss:
            return list(msgs)
        kept = []
        for m in msgs:
            if rng.next() < self.loss:
                self.lost += 1
            else:
                kept.append(m)
        return kept

    def push_period(self, period: int, events: list, state: tuple) -> None:
        """Queue the bundle of control period ``period``.

        Parameters
        ----------
        period : int
            Index k of the period (its time is k / rate_hz).
        events : list
            HEARTBEAT / STATUSTEXT of the period (sent first).
        state : tuple
            ``(ATTITUDE, ATTITUDE_QUATERNION, LOCAL_POSITION_NED)``; ``None`` for one whose
            stream is not due in this period (MAV_CMD_SET_MESSAGE_INTERVAL).
        """
        release = period + int((self._delay(self._state_rng) if self.jitter_periods
                                else self.delay_periods) + 0.5)
        msgs = self._survivors(events, self._event_rng) if events else []
        if self.loss:
            rng, p = self._state_rng, self.loss
            att_ok, quat_ok, pos_ok = rng.next() >= p, rng.next() >= p, rng.next() >= p
            for ok, m in zip((att_ok, quat_ok, pos_ok), state):
                if m is None:
                    continue
                if ok:
                    msgs.append(m)
                else:
                    self.lost += 1
            complete = quat_ok and pos_ok and state[1] is not None and state[2] is not None
        else:
            msgs.extend(m for m in state if m is not None)
            complete = state[1] is not None and state[2] is not None
        self._enqueue(release, msgs, complete)

    def push_reply(self, step: int, msgs: list) -> None:
        """Queue replies made at physics step ``step`` as a bundle of their own."""
        release = _ticks(step / self.substeps + self._delay(self._event_rng))
        self._enqueue(release, self._survivors(msgs, self._event_rng), False)

    def release(self, period: int) -> tuple[list, int]:
        """Pop every bundle due at or before ``period``.

        Returns
        -------
        messages : list or tuple
            In FIFO order, to send now (an empty tuple when nothing is due).
        complete : int
            How many complete state bundles are among them.
        """
        q = self._queue
        if not q or q[0][0] > period:
            return _NOTHING
        out: list = []
        complete = 0
        while q and q[0][0] <= period:
            _, msgs, full = q.popleft()
            out.extend(msgs)
            complete += full
        self.sent += len(out)
        return out, complete

    @property
    def pending(self) -> int:
        """Bundles waiting in the line."""
        return len(self._queue)


class Uplink:
    """Command delay line, due at physics steps (see the module docstring).

    Parameters
    ----------
    params : LinkParams
    physics_hz : int
        One tick of this line is one physics step.
    seed : int
    """

    def __init__(self, params: LinkParams, physics_hz: int, seed: int):
        self.delay_steps = params.command_delay_s * physics_hz
        self.jitter_steps = params.command_jitter_s * physics_hz
        self.loss = params.loss_probability
        self.ideal = not (self.delay_steps or self.jitter_steps or self.loss)
        self._target_rng = Uniforms([int(seed), 3])
        self._other_rng = Uniforms([int(seed), 5])
        self._queue: deque = deque()       # (due step, [messages])
        self._last_due = 0
        self.received = 0
        self.lost = 0

    def push(self, step: int, msgs: list, carries_target: bool) -> bool:
        """Queue one datagram received at physics step ``step``; ``False`` if it is lost."""
        rng = self._target_rng if carries_target else self._other_rng
        self.received += 1
        d = self.delay_steps
        if self.jitter_steps:
            d = max(0.0, d + self.jitter_steps * (2.0 * rng.next() - 1.0))
        if self.loss and rng.next() < self.loss:
            self.lost += 1
            return False
        due = step + _ticks(d)
        if due < self._last_due:
            due = self._last_due
        self._last_due = due
        self._queue.append((due, msgs))
        return True

    def next_due(self) -> int | None:
        """Physics step at which the oldest queued datagram is due (``None``: empty)."""
        return self._queue[0][0] if self._queue else None

    def pop_due(self, step: int) -> list:
        """Datagrams (lists of messages) due at or before ``step``, in FIFO order."""
        q = self._queue
        out = []
        while q and q[0][0] <= step:
            out.append(q.popleft()[1])
        return out
