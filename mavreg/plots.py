"""Plots of a flight: the path in the maneuver's plane and the errors against s."""
from __future__ import annotations

import numpy as np

__all__ = ["plot_run"]


def plot_run(plan, t, positions, s, w, png_path: str) -> None:
    """Path (east-up and north-up views) and transverse/attitude errors against s."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ref = plan.path.evaluate(np.linspace(0, plan.length_m, 2000))[0]
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    ax[0].plot(ref[:, 1], -ref[:, 2], "k-", lw=2, label="path")
    ax[0].plot(positions[:, 1], -positions[:, 2], "r-", lw=1, label="flown")
    ax[0].set(xlabel="east (m)", ylabel="altitude (m)", title=plan.name, aspect="equal")
    ax[0].legend()
    err = np.hypot(w[:, 0], w[:, 1])
    ax[1].semilogy(s, np.maximum(err, 1e-7) * 1e3)
    ax[1].set(xlabel="arc length s (m)", ylabel="transverse error (mm)")
    ax[2].plot(s, np.degrees(w[:, 2:5]))
    ax[2].set(xlabel="arc length s (m)", ylabel="attitude error (deg)")
    ax[2].legend(["roll", "pitch", "yaw"])
    for a in ax[1:]:
        for name, s0, _ in plan.segments:
            a.axvline(s0, color="0.8", lw=0.8)
    fig.tight_layout()
    fig.savefig(png_path, dpi=100)
    plt.close(fig)
