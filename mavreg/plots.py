"""The flight plot of ``mavreg simulate`` and ``mavreg fly``: the path in the maneuver's
plane and the tracking errors against arc length (matplotlib, Agg backend)."""
from __future__ import annotations

import numpy as np

__all__ = ["plot_flight", "maneuver_plane"]

_UP = np.array([0.0, 0.0, -1.0])


def maneuver_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Origin and in-plane axes (horizontal, up) of the plane that best fits ``points``.

    The plane's normal is the least principal direction of the points; the first axis is
    horizontal in the plane and the second points as much up as the plane allows, so a
    loop in the east-down plane is drawn with east across and altitude up.
    """
    origin = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - origin, full_matrices=False)
    normal = vt[2]
    horizontal = np.cross(normal, _UP)
    if np.linalg.norm(horizontal) < 1e-6:  # a horizontal plane: north across, east up
        return origin, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    horizontal /= np.linalg.norm(horizontal)
    up = np.cross(horizontal, normal)
    if up @ _UP < 0:
        up = -up
    if horizontal @ np.array([1.0, 1.0, 0.0]) < 0:   # point it north or east
        horizontal = -horizontal
    return origin, horizontal, up


def _axis_label(a: np.ndarray) -> str:
    """'east', 'altitude', or a mix such as '+0.71 north +0.71 east'."""
    names = ("north", "east", "altitude")
    a = np.array([a[0], a[1], -a[2]])
    parts = [(c, n) for c, n in zip(a, names) if abs(c) > 0.02]
    if len(parts) == 1:
        c, n = parts[0]
        return n if c > 0 else f"-{n}"
    return " ".join(f"{c:+.2f} {n}" for c, n in parts)


def plot_flight(png_path, plan, s, w, flown_ned=None, truth_ned=None, title: str = "") -> None:
    """Save the flight plot.

    Parameters
    ----------
    plan : Plan; s : (N,) arc lengths; w : (N, 11) transverse coordinates;
    flown_ned : (M, 3) positions as the controller saw them; truth_ned : (K, 3) true positions.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = plan.path.evaluate(np.linspace(0.0, plan.length_m, 3000))[0]
    origin, across, up = maneuver_plane(ref)

    def proj(p):
        q = np.asarray(p, dtype=float) - origin
        return q @ across, q @ up

    fig, (a0, a1, a2) = plt.subplots(3, 1, figsize=(8, 11))
    a0.plot(*proj(ref), "k--", lw=1, label="path")
    if flown_ned is not None:
        a0.plot(*proj(flown_ned), lw=0.8, label="flown (controller's state)")
    if truth_ned is not None:
        a0.plot(*proj(truth_ned), lw=0.6, alpha=0.6, label="ground truth")
    a0.set_aspect("equal")
    a0.set_xlabel(f"{_axis_label(across)} (m, from the path's centre)")
    a0.set_ylabel(f"{_axis_label(up)} (m, from the path's centre)")
    a0.legend(fontsize=8)
    a0.set_title(title or f"{plan.name}: path in the plane of the maneuver")
    s = np.asarray(s, dtype=float)
    w = np.asarray(w, dtype=float)
    a1.plot(s, 100 * np.hypot(w[:, 0], w[:, 1]), lw=0.8)
    a1.set_ylabel("transverse error (cm)")
    angle = np.arctan2(np.sin(w[:, 2:5]), np.cos(w[:, 2:5]))
    a2.plot(s, np.degrees(np.linalg.norm(angle, axis=1)), lw=0.8)
    a2.set_ylabel("attitude error (deg)")
    a2.set_xlabel("arc length s (m)")
    for ax in (a1, a2):
        for _, s0, _ in plan.segments:
            ax.axvline(s0, color="0.8", lw=0.5)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png_path, dpi=110)
    plt.close(fig)
