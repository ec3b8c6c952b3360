"""Checks of a goal and a plan against the global costmap: is the goal blocked, does the plan cross an obstacle.

A goal is blocked when the robot cannot stand there: its cell and every cell
within the planner's goal tolerance cost INSCRIBED_INFLATED_OBSTACLE or more
(an obstacle lies within the costmap's lethal radius, by default the
footprint's inscribed radius: the goal is in or next to an obstacle). A plan
is blocked when one of its poses still ahead of the robot lies on such a
cell (an obstacle was seen on it after planning).
"""
from __future__ import annotations

import math

import numpy as np

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.core.grid import INSCRIBED_INFLATED_OBSTACLE, NO_INFORMATION
from cottonsim_navigation.planning.costmap import Costmap2D


def _blocking(costs: np.ndarray) -> np.ndarray:
    return (costs >= INSCRIBED_INFLATED_OBSTACLE) & (costs != NO_INFORMATION)


def blocked_goal_reason(costmap: Costmap2D, goal: Pose2D, tolerance_m: float) -> str:
    """Why the robot cannot stand at ``goal`` (global costmap frame), or '' when it can."""
    spec = costmap.spec
    gx, gy = (int(v) for v in spec.world_to_map(goal.x_m, goal.y_m))
    if not spec.in_bounds(gx, gy):
        return f"goal ({goal.x_m:.2f}, {goal.y_m:.2f}) is off the global costmap"
    n = int(math.floor(max(tolerance_m, 0.0) / spec.resolution_m + 1e-9))
    win = costmap.costs[max(0, gy - n):gy + n + 1, max(0, gx - n):gx + n + 1]
    if win.size == 0 or not np.all(_blocking(win)):
        return ""
    return (f"goal ({goal.x_m:.2f}, {goal.y_m:.2f}) is in or next to an obstacle (cost "
            f"{int(costmap.costs[gy, gx])}: within {costmap.lethal_radius_m:.3f} m of it, the global "
            f"costmap's lethal radius) and no free cell within default_tolerance {tolerance_m:g} m")


def plan_blocked_at(costmap: Costmap2D, poses: np.ndarray, robot: Pose2D, ignore_near_m: float) -> int:
    """Index of the plan segment (from pose i to i + 1) ahead of the robot that crosses a blocking cell, or -1.

    Segments are checked at half-cell steps. Those before the pose nearest
    the robot are behind it; points within ``ignore_near_m`` of the robot are
    skipped too (the robot stands there, and its own inflation or a recovery
    deals with that), and so are points within the costmap's lethal radius
    of the goal (the last pose, left to :func:`blocked_goal_reason`).
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    if len(poses) < 2:
        return -1
    start = int(np.argmin(np.hypot(poses[:, 0] - robot.x_m, poses[:, 1] - robot.y_m)))
    step = 0.5 * costmap.spec.resolution_m
    seg, xs, ys = [], [], []
    for i in range(start, len(poses) - 1):
        (x0, y0), (x1, y1) = poses[i, :2], poses[i + 1, :2]
        t = np.linspace(0.0, 1.0, max(2, int(math.ceil(math.hypot(x1 - x0, y1 - y0) / step)) + 1))
        seg.append(np.full(t.size, i))
        xs.append(x0 + t * (x1 - x0))
        ys.append(y0 + t * (y1 - y0))
    if not seg:
        return -1
    seg, xs, ys = np.concatenate(seg), np.concatenate(xs), np.concatenate(ys)
    goal = poses[-1]
    keep = ((np.hypot(xs - robot.x_m, ys - robot.y_m) > ignore_near_m)
            & (np.hypot(xs - goal[0], ys - goal[1]) > costmap.lethal_radius_m))
    hit = np.zeros(xs.shape, dtype=bool)
    hit[keep] = _blocking(costmap.cost_at_world(xs[keep], ys[keep]))
    return int(seg[np.argmax(hit)]) if hit.any() else -1
