"""Localisation error of a pose estimate (AMCL's /amcl_pose) against ground truth along a run.

Why: the map-based experiment's accuracy depends on how well AMCL knows where
the robot is; the issue's target is a mean error <= 5 cm and a maximum <= 15 cm
over the whole route. The estimates are in the map frame (= Home, the spawn
pose), the truth in the world frame; each estimate is compared with the true
position linearly interpolated at its stamp (estimates outside the truth's time
span are left out).
"""
from __future__ import annotations

import math
from typing import Dict, Optional

import numpy as np


def localization_errors(estimates, trajectory, home) -> np.ndarray:
    """Position errors [m] of map-frame estimates (N, 3: t_s, x_m, y_m) against a world trajectory (M, >=3:
    t_s, x_m, y_m, ...) sorted by time; ``home``: the map frame in the world (.x_m, .y_m, .yaw_rad)."""
    est = np.asarray(estimates, dtype=float).reshape(-1, 3)
    traj = np.asarray(trajectory, dtype=float)
    if traj.ndim != 2 or traj.shape[1] < 3:
        raise ValueError(f"trajectory must be (M, >=3) rows of t_s, x_m, y_m, got shape {traj.shape}")
    est = est[np.all(np.isfinite(est), axis=1)]
    if len(traj) < 2 or len(est) == 0:
        return np.zeros(0)
    if np.any(np.diff(traj[:, 0]) < 0):
        raise ValueError("trajectory stamps must not decrease")
    inside = (est[:, 0] >= traj[0, 0]) & (est[:, 0] <= traj[-1, 0])
    est = est[inside]
    tx = np.interp(est[:, 0], traj[:, 0], traj[:, 1])
    ty = np.interp(est[:, 0], traj[:, 0], traj[:, 2])
    c, s = math.cos(home.yaw_rad), math.sin(home.yaw_rad)
    wx = home.x_m + c * est[:, 1] - s * est[:, 2]
    wy = home.y_m + s * est[:, 1] + c * est[:, 2]
    return np.hypot(wx - tx, wy - ty)


def localization_summary(errors) -> Dict[str, Optional[float]]:
    """mean / max / RMSE [m] and the count of the errors (None when there are none)."""
    e = np.asarray(errors, dtype=float).reshape(-1)
    if e.size == 0:
        return {"localization_samples": 0, "localization_error_mean_m": None, "localization_error_max_m": None,
                "localization_error_rmse_m": None}
    return {"localization_samples": int(e.size), "localization_error_mean_m": float(e.mean()),
            "localization_error_max_m": float(e.max()), "localization_error_rmse_m": float(np.sqrt(np.mean(e * e)))}
