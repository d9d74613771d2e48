"""Waiting for a condition, never for a fixed time (tests/README.md, "Writing a test")."""
from __future__ import annotations

import asyncio
import time

__all__ = ["wait_until", "wait_until_async"]


def wait_until(cond, what: str, timeout_s: float = 600.0, poll_s: float = 0.05):
    """``cond()``'s first truthy value, polled every ``poll_s``; an ``AssertionError`` naming
    ``what`` after ``timeout_s`` (the bound is for a broken run, not relied on)."""
    deadline = time.monotonic() + timeout_s
    while (v := _poll(cond, what, timeout_s, deadline)) is None:
        time.sleep(poll_s)
    return v


async def wait_until_async(cond, what: str, timeout_s: float = 60.0, poll_s: float = 0.01):
    """:func:`wait_until` inside an event loop: the loop runs while it waits."""
    deadline = time.monotonic() + timeout_s
    while (v := _poll(cond, what, timeout_s, deadline)) is None:
        await asyncio.sleep(poll_s)
    return v


def _poll(cond, what: str, timeout_s: float, deadline: float):
    """One look: ``cond()``'s value when truthy, None to look again, an ``AssertionError``
    naming ``what`` once ``deadline`` (monotonic s) has passed."""
    if (v := cond()):
        return v
    if time.monotonic() >= deadline:
        raise AssertionError(f"{what}: not within {timeout_s} s")
    return None
