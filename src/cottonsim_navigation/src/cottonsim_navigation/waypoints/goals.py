"""Turn a waypoint route into move_base goal poses (position + heading), free of ROS.

Why: move_base needs a full pose for every goal, but a GPS route only gives
positions, and the original map route carries defective headings (yaw = 1 rad
on return passes). The original GPS node took the goal yaw from the
waypoint's y coordinate, which points the robot in an arbitrary direction.
Here every goal faces the *next* waypoint, so the robot arrives already
turned towards where it drives next and never spins in place in the middle of
a straight pass; the last goal keeps the heading of the final leg.

GPS waypoints become map-frame goals through a
:class:`~cottonsim_navigation.geodesy.navsat.NavsatTransform` (the same ENU
map frame as the navsat/GPS localisation, so a goal and the robot's own
GPS-based position share any projection error and it cancels).
"""
from __future__ import annotations

import math
from typing import List, Optional, Sequence

import numpy as np

from cottonsim_navigation.geodesy.navsat import NavsatTransform
from cottonsim_navigation.waypoints.files import GpsWaypoint, MapWaypoint

GOAL_YAW_MODES = ("toward_next", "file")


def pass_through_flags(xy_m, max_turn_rad: float, min_step_m: float = 1e-3) -> np.ndarray:
    """Which waypoints the robot may drive through without stopping: (N,) bool.

    Waypoint i (neither the first nor the last) qualifies when the route turns
    there by at most ``max_turn_rad`` [rad]: the direction of the leg leaving it
    differs from the leg reaching it by no more than that. A mid-lane waypoint
    of a serpentine route qualifies; the lane ends (90 deg turns) do not.
    Legs shorter than ``min_step_m`` [m] have no direction and disqualify.
    """
    p = np.asarray(xy_m, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) == 0:
        raise ValueError(f"xy_m must be a non-empty (N, 2) array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("xy_m contains non-finite values")
    if not (math.isfinite(max_turn_rad) and 0.0 <= max_turn_rad <= math.pi):
        raise ValueError(f"max_turn_rad must be in [0, pi], got {max_turn_rad}")
    out = np.zeros(len(p), dtype=bool)
    if len(p) < 3:
        return out
    leg = np.diff(p, axis=0)
    ok = np.hypot(leg[:, 0], leg[:, 1]) >= max(min_step_m, 1e-12)
    yaw = np.arctan2(leg[:, 1], leg[:, 0])
    turn = np.abs(np.angle(np.exp(1j * (yaw[1:] - yaw[:-1]))))
    out[1:-1] = ok[:-1] & ok[1:] & (turn <= max_turn_rad)
    return out


def route_headings(xy_m, final_yaw_rad: Optional[float] = None, min_step_m: float = 1e-3) -> np.ndarray:
    """Heading [rad] of each waypoint: the direction from it to the next waypoint.

    xy_m: (N, 2) positions [m]. The last waypoint takes the direction of the
    leg that reaches it (or ``final_yaw_rad`` when given). Legs shorter than
    ``min_step_m`` have no direction: such a waypoint takes the heading of the
    next waypoint that has one (or the previous one at the end of the route);
    a route whose points all coincide gets ``final_yaw_rad`` or 0.
    """
    p = np.asarray(xy_m, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"xy_m must be an (N, 2) array, got shape {p.shape}")
    if len(p) == 0:
        raise ValueError("xy_m has no waypoints")
    if not np.all(np.isfinite(p)):
        raise ValueError("xy_m contains non-finite values")
    if not (math.isfinite(min_step_m) and min_step_m >= 0.0):
        raise ValueError(f"min_step_m must be finite and >= 0, got {min_step_m}")
    if final_yaw_rad is not None and not math.isfinite(final_yaw_rad):
        raise ValueError(f"final_yaw_rad must be finite, got {final_yaw_rad}")
    n = len(p)
    leg = np.diff(p, axis=0)                                  # leg i goes from waypoint i to i + 1
    leg_ok = np.hypot(leg[:, 0], leg[:, 1]) >= max(min_step_m, 1e-12)
    leg_yaw = np.arctan2(leg[:, 1], leg[:, 0])
    yaw = np.full(n, np.nan)
    # each waypoint faces along its outgoing leg, or the next usable one
    nxt = np.nan
    for i in range(n - 2, -1, -1):
        if leg_ok[i]:
            nxt = leg_yaw[i]
        yaw[i] = nxt
    # the last waypoint: its incoming leg (the last usable one), unless told otherwise
    if final_yaw_rad is not None:
        yaw[n - 1] = final_yaw_rad
    else:
        usable = np.flatnonzero(leg_ok)
        yaw[n - 1] = leg_yaw[usable[-1]] if usable.size else np.nan
    # waypoints after the last usable leg take the heading before them
    prev = final_yaw_rad if final_yaw_rad is not None else 0.0
    for i in range(n):
        if np.isnan(yaw[i]):
            yaw[i] = prev
        prev = yaw[i]
    return yaw


def gps_goals_in_map(waypoints: Sequence[GpsWaypoint], navsat: NavsatTransform,
                     final_yaw_rad: Optional[float] = None, lanes_m=None, lane_snap_max_m: float = 0.5,
                     lane_snap_margin_m: float = 5.0) -> List[MapWaypoint]:
    """GPS waypoints -> map-frame goals [m, rad] facing the next waypoint.

    ``navsat`` must have its datum set (it fixes where the map origin lies).
    Labels carry over; an unlabelled waypoint is named by its 1-based index.
    lanes_m: optional (L, 2, 2) lane centre lines in the map frame (see
    :func:`gps_lanes_in_map`); waypoints near a lane are then moved onto it
    first (:func:`snap_to_lanes` with lane_snap_max_m / lane_snap_margin_m [m])
    and the headings follow the moved positions.
    """
    if len(waypoints) == 0:
        raise ValueError("no GPS waypoints")
    if not navsat.has_datum:
        raise ValueError("the navsat transform has no datum yet: cannot place GPS waypoints in the map")
    xy = np.array([navsat.fix_to_map(w.lat, w.lon)[:2] for w in waypoints], dtype=float)
    if lanes_m is not None:
        xy, _ = snap_to_lanes(xy, lanes_m, lane_snap_max_m, lane_snap_margin_m)
    yaw = route_headings(xy, final_yaw_rad)
    return [MapWaypoint(float(x), float(y), float(a), w.label or str(i + 1))
            for i, (w, (x, y), a) in enumerate(zip(waypoints, xy, yaw))]


def gps_lanes_in_map(lanes: Sequence[tuple], navsat: NavsatTransform) -> np.ndarray:
    """Lane centre lines given as (GpsWaypoint start, GpsWaypoint end) pairs -> (L, 2, 2) map [m]."""
    if len(lanes) == 0:
        raise ValueError("no lanes")
    if not navsat.has_datum:
        raise ValueError("the navsat transform has no datum yet: cannot place lanes in the map")
    return np.array([[navsat.fix_to_map(a.lat, a.lon)[:2], navsat.fix_to_map(b.lat, b.lon)[:2]] for a, b in lanes],
                    dtype=float)


def map_goals(waypoints: Sequence[MapWaypoint], goal_yaw: str = "toward_next") -> List[MapWaypoint]:
    """Map waypoints -> goals; goal_yaw 'toward_next' recomputes headings, 'file' keeps the file's yaw."""
    if goal_yaw not in GOAL_YAW_MODES:
        raise ValueError(f"goal_yaw must be one of {GOAL_YAW_MODES}, got {goal_yaw!r}")
    if len(waypoints) == 0:
        raise ValueError("no map waypoints")
    if goal_yaw == "file":
        return [MapWaypoint(w.x_m, w.y_m, w.yaw_rad, w.label or str(i + 1)) for i, w in enumerate(waypoints)]
    yaw = route_headings(np.array([[w.x_m, w.y_m] for w in waypoints], dtype=float))
    return [MapWaypoint(w.x_m, w.y_m, float(a), w.label or str(i + 1)) for i, (w, a) in enumerate(zip(waypoints, yaw))]


def snap_to_lanes(xy_m, lanes_m, max_offset_m: float, margin_m: float):
    """Move waypoints sideways onto the nearest lane centre line: (snapped (N, 2), snapped mask (N,)).

    xy_m: (N, 2) waypoints [m]; lanes_m: (L, 2, 2) lane centre lines, each
    [start, end] [m], in the same frame. A waypoint is snapped when it lies
    within ``max_offset_m`` [m] sideways of a lane's line and along it between
    ``margin_m`` [m] before its start and after its end (the headlands where a
    route enters and leaves the lane); it then moves perpendicular onto the
    line of the nearest such lane (its position along the lane is kept).
    Other waypoints stay where they are.

    Why: a route surveyed on another farm, or the original's (whose lanes
    were unevenly spaced), puts in-row waypoints up to ~0.35 m off this farm's
    lane centres, where the robot would brush the plants; snapping keeps the
    route's order and along-lane positions but drives the lanes' centres.
    """
    p = np.asarray(xy_m, dtype=float)
    lanes = np.asarray(lanes_m, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"xy_m must be an (N, 2) array, got shape {p.shape}")
    if lanes.ndim != 3 or lanes.shape[1:] != (2, 2) or len(lanes) == 0:
        raise ValueError(f"lanes_m must be an (L, 2, 2) array of [start, end] points, got shape {lanes.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(lanes))):
        raise ValueError("xy_m and lanes_m must be finite")
    for name, v in (("max_offset_m", max_offset_m), ("margin_m", margin_m)):
        if not (math.isfinite(v) and v >= 0.0):
            raise ValueError(f"{name} must be finite and >= 0, got {v}")
    a = lanes[:, 0, :]                                  # (L, 2)
    d = lanes[:, 1, :] - a
    length = np.hypot(d[:, 0], d[:, 1])
    if np.any(length <= 0.0):
        raise ValueError("a lane's start and end coincide")
    u = d / length[:, None]
    rel = p[:, None, :] - a[None, :, :]                 # (N, L, 2)
    along = rel[..., 0] * u[None, :, 0] + rel[..., 1] * u[None, :, 1]
    side = rel[..., 0] * -u[None, :, 1] + rel[..., 1] * u[None, :, 0]
    ok = (np.abs(side) <= max_offset_m) & (along >= -margin_m) & (along <= length[None, :] + margin_m)
    score = np.where(ok, np.abs(side), np.inf)
    best = np.argmin(score, axis=1)
    snapped = np.isfinite(score[np.arange(len(p)), best])
    out = p.copy()
    k = best[snapped]
    t = along[snapped, k]
    out[snapped] = a[k] + t[:, None] * u[k]
    return out, snapped
