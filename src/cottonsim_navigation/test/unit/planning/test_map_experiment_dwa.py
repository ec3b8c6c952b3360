"""The map route's move_base overrides (config/map_navigation_move_base.yaml) with the port's DWA.

The map route's AE is the distance of the true trajectory to each waypoint, so the local planner
must stop inside its (tight) xy goal tolerance from any approach the route produces, without
dithering in place just outside it.
"""
import math
import pathlib

import numpy as np
import pytest
import yaml

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.planning.base import LocalPlannerStatus
from cottonsim_navigation.planning.costmap import make_local_costmap
from cottonsim_navigation.planning.local_planners.dwa import DWAConfig, DWAPlanner

PKG = pathlib.Path(__file__).resolve().parents[3]


def _dwa_params(override_file):
    params = dict(yaml.safe_load((PKG / "config" / "dwa.yaml").read_text())["DWAPlannerROS"])
    params.update(yaml.safe_load((PKG / "config" / override_file).read_text())["DWAPlannerROS"])
    return params


def test_map_route_uses_its_own_tighter_goal_tolerance():
    map_cfg = DWAConfig(**_dwa_params("map_navigation_move_base.yaml"))
    gps_cfg = DWAConfig(**_dwa_params("gps_navigation_move_base.yaml"))
    assert map_cfg.xy_goal_tolerance <= 0.05 < gps_cfg.xy_goal_tolerance
    assert map_cfg.latch_xy_goal_tolerance


@pytest.mark.parametrize("start_v", [0.0, 0.5])
@pytest.mark.parametrize("short_m,beside_m", [(0.045, 0.0), (0.06, 0.02), (0.083, 0.04), (0.3, 0.0),
                                               (0.3, 0.04), (1.5, 0.02)])
def test_map_route_dwa_stops_inside_the_tolerance_without_dithering(short_m, beside_m, start_v):
    # a robot on (or beside) the line to the goal, short_m before it, stopped or at cruise speed;
    # an ideal unicycle follows each command for one control period
    cfg = DWAConfig(**_dwa_params("map_navigation_move_base.yaml"))
    cm = make_local_costmap()
    cm.update_map(Pose2D(0.0, 0.0, 0.0))
    dwa = DWAPlanner(cfg)
    dwa.set_plan(np.column_stack([np.linspace(-3.0, 0.0, 121), np.zeros(121), np.zeros(121)]))
    x, y, yaw, v, w = -short_m, beside_m, 0.0, start_v, 0.0
    dt = 1.0 / cfg.controller_frequency
    steps = 0
    for steps in range(100):
        v, w, st = dwa.compute_velocity(Pose2D(x, y, yaw), (v, w), cm)
        if st is LocalPlannerStatus.GOAL_REACHED:
            break
        x += v * dt * math.cos(yaw)
        y += v * dt * math.sin(yaw)
        yaw += w * dt
    assert st is LocalPlannerStatus.GOAL_REACHED
    assert math.hypot(x, y) <= cfg.xy_goal_tolerance + 1e-9
    # arrives at the pace of the approach: the last centimetres take seconds, not a dithering minute
    assert steps * dt <= short_m / 0.5 + 4.0
