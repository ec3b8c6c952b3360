"""Trajectory figure like the paper's Fig. 14: planned (blue) vs actual (red) on the plants.

Uses matplotlib with the non-interactive Agg backend (Debian's
python3-matplotlib); imported lazily so the rest of the package works
without it.
"""
from __future__ import annotations

import os
from typing import Optional

import numpy as np


def plot_trajectory(path_png, planned_xy, actual_xy, plant_xy=None, title: str = "",
                    plant_radius_m: float = 0.35, units: str = "m") -> str:
    """Write a PNG: planned waypoints (blue, numbered), actual path (red), plants (green)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.patches import Circle
    except ImportError as exc:
        raise ImportError("plot_trajectory needs matplotlib (apt-get install python3-matplotlib)") from exc
    planned = np.asarray(planned_xy, dtype=float).reshape(-1, 2)
    actual = np.asarray(actual_xy, dtype=float).reshape(-1, 2)
    fig, ax = plt.subplots(figsize=(8, 8), dpi=100)
    try:
        if plant_xy is not None:
            for x, y in np.asarray(plant_xy, dtype=float).reshape(-1, 2):
                ax.add_patch(Circle((x, y), plant_radius_m, color="tab:green", alpha=0.35, lw=0))
        if len(actual):
            ax.plot(actual[:, 0], actual[:, 1], "-", color="red", lw=1.5, label="actual")
        if len(planned):
            ax.plot(planned[:, 0], planned[:, 1], "o--", color="blue", ms=5, lw=0.8, label="planned")
            for i, (x, y) in enumerate(planned):
                ax.annotate(str(i + 1), (x, y), textcoords="offset points", xytext=(3, 3), fontsize=7,
                            color="blue")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"x [{units}]")
        ax.set_ylabel(f"y [{units}]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best")
        if title:
            ax.set_title(title)
        d = os.path.dirname(os.fspath(path_png))
        if d:
            os.makedirs(d, exist_ok=True)
        fig.savefig(path_png)
    finally:
        plt.close(fig)
    return os.fspath(path_png)
