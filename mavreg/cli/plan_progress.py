"""Planning said on stderr by the commands that plan in their own process (plan, simulate),
when stderr is a terminal: these are short commands whose output is read by scripts and
tests too, where an anticipated error is one line and nothing else (``mavreg fly`` and
``serve`` are logs: they always say their stages)."""
from __future__ import annotations

__all__ = ["plan_saying"]


def plan_saying(command: str, spec, vehicle, controller, strict: bool = True):
    """Plan ``spec`` through the plan cache, saying so on stderr (``mavreg COMMAND  0.4 s
    planning NAME ...``) at once on a cache miss (seconds, and numba's compile on a cold
    cache), else only if it takes more than a second (:mod:`mavreg.progress`)."""
    import sys

    from ..planning.cache import default_cache
    from ..planning.plan_io import plan_cached
    from ..progress import Progress
    cache = default_cache()
    miss = cache is not None and not cache.has((spec, vehicle, controller, strict))
    doing = f"planning {spec.name}" + (" (not in the plan cache yet)" if miss else "")
    progress = Progress(tag=f"mavreg {command}", quiet=not sys.stderr.isatty())
    with progress.stage(doing, f"planned {spec.name}", announce=miss):
        return plan_cached(spec, vehicle, controller, strict, cache)
