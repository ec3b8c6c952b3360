"""The row-centring correction blended into move_base's angular velocity, and the inside-a-row test it needs."""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.core.grid import LETHAL_OBSTACLE
from cottonsim_navigation.move_base.config import VisionBiasConfig
from cottonsim_navigation.planning.costmap import Costmap2D


def blend_vision(w_radps: float, vision_w_radps: Optional[float], age_s: Optional[float], in_row: bool,
                 config: VisionBiasConfig) -> float:
    """The local planner's angular velocity plus the bounded vision correction.

    Returns ``w_radps`` unchanged unless the correction is enabled, an
    estimate exists, is finite and younger than ``max_age_s``, and the
    robot is inside a crop row; then adds ``vision_w_radps`` clipped to
    +/- ``max_vision_rate``.
    """
    if not config.enabled or vision_w_radps is None or age_s is None or not in_row:
        return w_radps
    if not (math.isfinite(vision_w_radps) and math.isfinite(age_s)) or age_s < 0 or age_s > config.max_age_s:
        return w_radps
    return w_radps + max(-config.max_vision_rate, min(config.max_vision_rate, vision_w_radps))


def inside_crop_row(costmap: Costmap2D, pose: Pose2D, reach_m: float = 1.0) -> bool:
    """True when LETHAL cells lie within ``reach_m`` to the left AND to the right of the robot.

    Samples lateral lines (perpendicular to the heading) at three points
    along the robot (-0.35, 0, +0.35 m, the plant spacing's half) so a single
    missing plant does not end the row.
    """
    step = 0.5 * costmap.spec.resolution_m
    lat = np.arange(step, reach_m + 1e-9, step)
    along = np.array([-0.35, 0.0, 0.35])
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    found = []
    for side in (1.0, -1.0):
        a, d = np.meshgrid(along, side * lat)
        x = pose.x_m + a * c - d * s
        y = pose.y_m + a * s + d * c
        found.append(bool(np.any(costmap.cost_at_world(x.ravel(), y.ravel()) == LETHAL_OBSTACLE)))
    return found[0] and found[1]
