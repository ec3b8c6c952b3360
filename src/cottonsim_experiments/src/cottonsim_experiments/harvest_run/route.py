"""The harvest experiment's route: the lanes beside the harvested row(s), driven as a serpentine.

A row is harvested from both its lanes (row r lies between lane r and lane r + 1, see
cottonsim_world.farm.config), so the default route drives lane r northwards and lane r + 1
southwards; ``lanes='all'`` drives every lane of the farm, as the farm's own route does. Each lane
gets three waypoints on its centre line: entry (before the first stems), middle, exit (beyond the
last stems), at the farm's route entry and exit distances. Pure: world x/y [m] and yaw [rad].
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple, Union

LANES_ROW = "row"
LANES_ALL = "all"
LANE_CHOICES = (LANES_ROW, LANES_ALL)
TARGET_SOURCES = ("detections", "ground_truth")     # the harvest node's target_source


@dataclass(frozen=True)
class RouteWaypoint:
    """One waypoint: world x_m, y_m [m], the heading along its lane yaw_rad [rad], its lane and a label."""

    x_m: float
    y_m: float
    yaw_rad: float
    lane: int
    label: str


def harvest_lanes(farm_config, lanes: Union[str, Sequence[int]] = LANES_ROW, row: int = 1) -> List[int]:
    """The lanes the route drives, in order: ``'row'`` = the two lanes beside ``row`` (row, row + 1);
    ``'all'`` = every lane of the farm; or an explicit list of lane indices (each checked)."""
    count = int(farm_config.lane_count)
    if isinstance(lanes, str):
        if lanes == LANES_ROW:
            if isinstance(row, bool) or not isinstance(row, int) or not 0 <= row < int(farm_config.rows):
                raise ValueError(f"row must be a row of the farm (0 .. {int(farm_config.rows) - 1}), got {row!r}")
            return [row, row + 1]
        if lanes == LANES_ALL:
            return list(range(count))
        raise ValueError(f"lanes must be one of {LANE_CHOICES} or a list of lane indices, got {lanes!r}")
    chosen = list(lanes)
    if not chosen:
        raise ValueError("lanes must name at least one lane")
    for lane in chosen:
        if isinstance(lane, bool) or not isinstance(lane, int) or not 0 <= lane < count:
            raise ValueError(f"lane {lane!r} is not a lane of the farm (0 .. {count - 1})")
    if len(set(chosen)) != len(chosen):
        raise ValueError(f"lanes must not repeat, got {chosen}")
    return chosen


def serpentine_route(farm_config, lanes: Sequence[int]) -> List[RouteWaypoint]:
    """Entry, middle and exit of each lane in ``lanes`` (in that order), the first northwards (+y), the
    next southwards and so on; labels '<lane>-<k>' (lanes counted from 1, as the farm's route)."""
    if not lanes:
        raise ValueError("the route needs at least one lane")
    south = float(farm_config.first_plant_y_m)
    north = float(farm_config.last_plant_y_m)
    entry, leave = float(farm_config.route_entry_distance_m), float(farm_config.route_exit_distance_m)
    route: List[RouteWaypoint] = []
    for i, lane in enumerate(lanes):
        x = float(farm_config.lane_x_m(int(lane)))
        if i % 2 == 0:
            ys, yaw = (south - entry, 0.5 * (south + north), north + leave), 0.5 * math.pi
        else:
            ys, yaw = (north + entry, 0.5 * (south + north), south - leave), -0.5 * math.pi
        route.extend(RouteWaypoint(x, y, yaw, int(lane), f"{int(lane) + 1}-{k + 1}") for k, y in enumerate(ys))
    return route


def lane_headings(route: Sequence[RouteWaypoint]) -> Dict[int, float]:
    """Lane index -> the robot's heading along it on ``route`` [rad] (its first waypoint there)."""
    headings: Dict[int, float] = {}
    for waypoint in route:
        headings.setdefault(waypoint.lane, waypoint.yaw_rad)
    return headings


def rows_beside(farm_config, lanes: Sequence[int]) -> List[int]:
    """The rows whose plants face one of ``lanes`` (lane k runs between rows k - 1 and k), sorted."""
    rows = {r for lane in lanes for r in (int(lane) - 1, int(lane)) if 0 <= r < int(farm_config.rows)}
    return sorted(rows)

