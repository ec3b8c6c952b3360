"""GPS outages of a run and what they did: how many, how long, how far the robot's pose went off, how long
the navigator stood paused.

Why: a farm robot loses its RTK fix under trees and next to buildings; the
report must say when that happened and whether navigation coped (the short
outages bridged on odometry, the long ones paused). The outages are read from
the receiver's output (/navsat/fix), not from the robot's software: a gap
between usable fixes (status >= FIX, finite position) longer than
``min_gap_s``, inside the route's time span, is an outage. The position error
compares the robot's own map pose (gps_localization's ~status, brought into
the world frame) with ground truth at the same stamps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np


@dataclass(frozen=True)
class GpsOutageConfig:
    """min_gap_s [s]: a gap between usable fixes longer than this is an outage (the fix comes at 40 Hz);
    default 1.0."""

    min_gap_s: float = 1.0

    def __post_init__(self) -> None:
        v = self.min_gap_s
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0.0):
            raise ValueError(f"min_gap_s must be a finite time > 0 [s], got {v!r}")


def fix_outages(fix_stamps_s: Sequence[float], start_s: float, end_s: float,
                config: GpsOutageConfig = GpsOutageConfig()) -> np.ndarray:
    """(K, 2) [start, end] sim times [s] of the gaps without a usable fix within [start_s, end_s].

    fix_stamps_s: stamps of the usable fixes (any order). A gap runs from the last fix before it to the
    first after it, cut to the span; one that reaches the span's end is open (ends at end_s).
    """
    if not (math.isfinite(start_s) and math.isfinite(end_s)):
        raise ValueError(f"start_s and end_s must be finite, got {start_s!r}, {end_s!r}")
    if end_s <= start_s:
        return np.zeros((0, 2))
    stamps = np.sort(np.asarray(fix_stamps_s, dtype=float).reshape(-1))
    stamps = stamps[np.isfinite(stamps)]
    inside = stamps[(stamps > start_s) & (stamps < end_s)]
    before = stamps[stamps <= start_s]
    after = stamps[stamps >= end_s]
    bounds = np.concatenate([[before[-1] if len(before) else start_s], inside,
                             [after[0] if len(after) else end_s]])
    gaps = np.stack([bounds[:-1], bounds[1:]], axis=1)
    gaps = gaps[gaps[:, 1] - gaps[:, 0] > config.min_gap_s]
    gaps[:, 0] = np.maximum(gaps[:, 0], start_s)
    gaps[:, 1] = np.minimum(gaps[:, 1], end_s)
    return gaps[gaps[:, 1] > gaps[:, 0]].reshape(-1, 2)


def paused_intervals(states: Sequence[Tuple[float, str]], end_s: float, paused: str = "paused") -> np.ndarray:
    """(K, 2) sim-time intervals [s] in which the navigator's state was ``paused``.

    states: (time [s], state name) in arrival order; a pause still on at the end lasts until end_s.
    """
    out: List[Tuple[float, float]] = []
    since: Optional[float] = None
    for t, name in states:
        if name == paused and since is None:
            since = float(t)
        elif name != paused and since is not None:
            out.append((since, float(t)))
            since = None
    if since is not None and end_s > since:
        out.append((since, float(end_s)))
    return np.array(out, dtype=float).reshape(-1, 2)


def estimates_in_world(estimates_map, map_to_latlon: Callable[[float, float], Tuple[float, float]],
                       geodesy) -> np.ndarray:
    """(N, 3) t_s, x_m, y_m of map-frame pose estimates -> the same in the simulator's world frame.

    map_to_latlon: the robot's own map -> lat/lon conversion (navsat's ``NavsatTransform.map_to_latlon``
    with its datum); geodesy: the simulator's lat/lon -> world mapping (``HectorGeodesy``). Rows with
    NaN are dropped.
    """
    est = np.asarray(estimates_map, dtype=float).reshape(-1, 3)
    est = est[np.all(np.isfinite(est), axis=1)]
    out = np.empty_like(est)
    for i, (t, x, y) in enumerate(est):
        lat, lon = map_to_latlon(float(x), float(y))
        wx, wy, _ = geodesy.geodetic_to_world(lat, lon, 0.0)
        out[i] = (t, wx, wy)
    return out


def position_errors(estimates_world, trajectory) -> np.ndarray:
    """(N, 2) sim time [s], distance [m] of world-frame estimates (t_s, x_m, y_m) from the true trajectory
    (M, >=3: t_s, x_m, y_m, ...; sorted) interpolated at their stamps; estimates outside its span are left out."""
    est = np.asarray(estimates_world, dtype=float).reshape(-1, 3)
    traj = np.asarray(trajectory, dtype=float)
    if traj.ndim != 2 or traj.shape[1] < 3:
        raise ValueError(f"trajectory must be (M, >=3) rows of t_s, x_m, y_m, got shape {traj.shape}")
    if len(traj) < 2 or len(est) == 0:
        return np.zeros((0, 2))
    est = est[(est[:, 0] >= traj[0, 0]) & (est[:, 0] <= traj[-1, 0])]
    tx = np.interp(est[:, 0], traj[:, 0], traj[:, 1])
    ty = np.interp(est[:, 0], traj[:, 0], traj[:, 2])
    return np.stack([est[:, 0], np.hypot(est[:, 1] - tx, est[:, 2] - ty)], axis=1)


def _overlap_s(a: np.ndarray, b: Tuple[float, float]) -> float:
    if len(a) == 0:
        return 0.0
    return float(np.clip(np.minimum(a[:, 1], b[1]) - np.maximum(a[:, 0], b[0]), 0.0, None).sum())


def gps_outage_report(outages: np.ndarray, position_errors: Optional[np.ndarray],
                      paused: np.ndarray) -> Dict[str, object]:
    """The report keys of the GPS outages of a run.

    outages: (K, 2) from :func:`fix_outages`; position_errors: (N, 2) sim time [s], error of the robot's
    pose [m] (None: no pose estimates were recorded); paused: (P, 2) from :func:`paused_intervals`.
    Keys: gps_outages (count), gps_outage_total_s, gps_outage_max_s, gps_outage_max_position_error_m
    (largest error during any outage; None without estimates there), navigator_pauses,
    navigator_paused_s, gps_outage_list (per outage: start_s, end_s, duration_s,
    max_position_error_m, paused_s = the navigator's pause within it).
    """
    outages = np.asarray(outages, dtype=float).reshape(-1, 2)
    paused = np.asarray(paused, dtype=float).reshape(-1, 2)
    errors = None if position_errors is None else np.asarray(position_errors, dtype=float).reshape(-1, 2)
    items = []
    worst: Optional[float] = None
    for t0, t1 in outages:
        err = None
        if errors is not None:
            inside = errors[(errors[:, 0] >= t0) & (errors[:, 0] <= t1), 1]
            inside = inside[np.isfinite(inside)]
            if inside.size:
                err = float(inside.max())
                worst = err if worst is None else max(worst, err)
        items.append({"start_s": float(t0), "end_s": float(t1), "duration_s": float(t1 - t0),
                      "max_position_error_m": err, "paused_s": _overlap_s(paused, (t0, t1))})
    durations = outages[:, 1] - outages[:, 0]
    return {"gps_outages": int(len(outages)),
            "gps_outage_total_s": float(durations.sum()),
            "gps_outage_max_s": float(durations.max()) if len(durations) else 0.0,
            "gps_outage_max_position_error_m": worst,
            "navigator_pauses": int(len(paused)),
            "navigator_paused_s": float((paused[:, 1] - paused[:, 0]).sum()) if len(paused) else 0.0,
            "gps_outage_list": items}
