"""The paper's navigation metrics (Eq. 4-7) and the run report.

For each planned waypoint i, E_i = distance to the nearest point of the
actual trajectory (Eq. 4); AE = mean E (Eq. 5); RMSE = sqrt(mean E^2)
(Eq. 6); CR = 100 * (number of E_i <= r) / N (Eq. 7). For GPS routes the
paper measures E in degrees: the Euclidean distance in (lat, lon) degrees,
with r = 5e-6 deg; :func:`waypoint_errors_deg` does that, and the metre
variant is used for map routes (r = 0.25 m in the paper). A degree of
longitude shrinks with cos(lat), so r is 0.56 m north-south everywhere but
0.36 m east-west at the default 49.9 N (0.46 m at 33.4 N, 0.10 m at 80 N):
compare farms at other latitudes by the metre figures (cr_percent_010m, AE).

Cross-track error: distance of trajectory points to the nearest lane centre
line, counted only for points alongside a row (lane y extent).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, Optional, Sequence

import numpy as np

MAP_CR_THRESHOLD_M = 0.25
GPS_CR_THRESHOLD_DEG = 5e-6


def _as_xy(points, name: str) -> np.ndarray:
    arr = np.asarray(points, dtype=float)
    if arr.ndim != 2 or arr.shape[1] < 2:
        raise ValueError(f"{name} must be an (N, 2) array, got shape {arr.shape}")
    arr = arr[:, :2]
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains non-finite values")
    return arr


def waypoint_errors(planned, actual) -> np.ndarray:
    """E_i (Eq. 4): for each planned point (N, 2), distance to the nearest actual point (M, 2).

    Units are those of the inputs (m for map routes; degrees for (lat, lon)).
    """
    p = _as_xy(planned, "planned")
    a = _as_xy(actual, "actual")
    if len(p) == 0:
        raise ValueError("planned has no waypoints")
    if len(a) == 0:
        raise ValueError("actual trajectory is empty")
    out = np.empty(len(p))
    for start in range(0, len(a), 20000):        # chunks keep memory bounded for long runs
        chunk = a[start:start + 20000]
        d = np.sqrt(((p[:, None, :] - chunk[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
        out = d if start == 0 else np.minimum(out, d)
    return out


def waypoint_errors_deg(planned_latlon, actual_latlon) -> np.ndarray:
    """E_i in degrees for (lat, lon) inputs, as the paper computes it for GPS routes."""
    return waypoint_errors(planned_latlon, actual_latlon)


@dataclass(frozen=True)
class RouteMetrics:
    errors: np.ndarray
    ae: float              # mean error (Eq. 5)
    rmse: float            # Eq. 6
    cr_percent: float      # Eq. 7
    cr_threshold: float
    reached: int           # waypoints with E <= threshold


def route_metrics(errors, threshold: float) -> RouteMetrics:
    """AE, RMSE and CR for per-waypoint errors and a completion radius ``threshold``."""
    e = np.asarray(errors, dtype=float).reshape(-1)
    if e.size == 0:
        raise ValueError("errors is empty")
    if not np.all(np.isfinite(e)) or np.any(e < 0):
        raise ValueError("errors must be finite and >= 0")
    if not (math.isfinite(threshold) and threshold >= 0):
        raise ValueError(f"threshold must be finite and >= 0, got {threshold}")
    reached = int(np.sum(e <= threshold))
    return RouteMetrics(e, float(e.mean()), float(np.sqrt(np.mean(e ** 2))),
                        100.0 * reached / e.size, float(threshold), reached)


def cross_track_errors(trajectory, lane_x_m: Sequence[float], lane_y_start_m: Sequence[float],
                       lane_y_end_m: Sequence[float]) -> np.ndarray:
    """|x - nearest lane centre x| [m] for trajectory points alongside a row (lanes along y).

    A point counts when its y lies within some lane's [y_start, y_end]; the
    nearest such lane's centre line gives the error. Returns the errors of
    the counted points (possibly empty).
    """
    t = _as_xy(trajectory, "trajectory")
    lx = np.asarray(lane_x_m, dtype=float)
    y0 = np.asarray(lane_y_start_m, dtype=float)
    y1 = np.asarray(lane_y_end_m, dtype=float)
    if not (lx.shape == y0.shape == y1.shape) or lx.ndim != 1 or lx.size == 0:
        raise ValueError("lane_x_m, lane_y_start_m, lane_y_end_m must be equal-length, non-empty 1-D")
    inside = (t[:, 1:2] >= np.minimum(y0, y1)) & (t[:, 1:2] <= np.maximum(y0, y1))     # (N, L)
    dx = np.abs(t[:, 0:1] - lx[None, :])
    dx = np.where(inside, dx, np.inf)
    best = dx.min(axis=1)
    return best[np.isfinite(best)]


def report_dict(mode: str, planned, actual, sim_duration_s: float, wall_duration_s: float,
                plant_contacts: int = 0, lanes=None, planned_xy_m=None, actual_xy_m=None,
                cr_threshold: Optional[float] = None) -> Dict[str, object]:
    """The report.json contents of a navigation run.

    mode 'map': planned/actual are map/world x, y [m]; CR threshold 0.25 m.
    mode 'gps': planned/actual are (lat, lon) [deg]; CR threshold 5e-6 deg;
    ae_m / rmse_m / cr_percent_010m then come from planned_xy_m / actual_xy_m
    (the same points in metres) when given, else they are None.
    lanes: optional list of objects with x_m, y_start_m, y_end_m for the
    cross-track error (computed on the metric trajectory).
    """
    if mode not in ("map", "gps"):
        raise ValueError(f"mode must be 'map' or 'gps', got {mode!r}")
    for name, v in (("sim_duration_s", sim_duration_s), ("wall_duration_s", wall_duration_s)):
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {v}")
    if mode == "map":
        thr = MAP_CR_THRESHOLD_M if cr_threshold is None else cr_threshold
        m = route_metrics(waypoint_errors(planned, actual), thr)
        pm, am = planned, actual
        metric = m
        cr = m.cr_percent
    else:
        thr = GPS_CR_THRESHOLD_DEG if cr_threshold is None else cr_threshold
        m = route_metrics(waypoint_errors_deg(planned, actual), thr)
        cr = m.cr_percent
        pm, am = planned_xy_m, actual_xy_m
        metric = route_metrics(waypoint_errors(pm, am), MAP_CR_THRESHOLD_M) if pm is not None and am is not None else None
    ct_mean = ct_max = None
    if lanes and am is not None:
        ct = cross_track_errors(am, [l.x_m for l in lanes], [l.y_start_m for l in lanes],
                                [l.y_end_m for l in lanes])
        if ct.size:
            ct_mean, ct_max = float(ct.mean()), float(ct.max())
    cr010 = None
    if metric is not None:
        cr010 = route_metrics(metric.errors, 0.10).cr_percent
    return {
        "mode": mode,
        "waypoints": int(m.errors.size),
        "reached": int(m.reached),
        "ae_m": None if metric is None else metric.ae,
        "rmse_m": None if metric is None else metric.rmse,
        "cr_percent": cr,
        "cr_threshold": thr,
        "cr_percent_010m": cr010,
        "sim_duration_s": float(sim_duration_s),
        "wall_duration_s": float(wall_duration_s),
        "real_time_factor": (float(sim_duration_s) / wall_duration_s) if wall_duration_s > 0 else None,
        "plant_contacts": int(plant_contacts),
        "cross_track_mean_m": ct_mean,
        "cross_track_max_m": ct_max,
    }
