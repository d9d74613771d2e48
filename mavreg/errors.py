"""Errors a user can cause: the CLI prints their message on one line and exits 2."""
from __future__ import annotations

from .config.loader import ConfigError

__all__ = ["ConfigError", "ManeuverError"]


class ManeuverError(ValueError):
    """A maneuver that loads but cannot be flown: infeasible, or ill-formed geometry.

    The message is one line and says where (segment, arc length) and by how much.
    """
