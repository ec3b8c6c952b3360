"""Recovery behaviours: clearing costmaps and rotating in place."""
import math

import numpy as np
import pytest

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.core.grid import FREE_SPACE, LETHAL_OBSTACLE
from cottonsim_navigation.move_base.recovery import (ClearCostmapConfig, ClearCostmapRecovery, RotateRecovery,
                                                     RotateRecoveryConfig, clear_obstacles_outside, make_recovery)
from cottonsim_navigation.planning.costmap import make_local_costmap


def local_with_points(points, pose=Pose2D(0, 0, 0)):
    cm = make_local_costmap()
    cm.update_map(pose)
    cm.obstacle_layer.add_observation(np.asarray(points, float), (pose.x_m, pose.y_m, 0.5))
    cm.update_map(pose)
    return cm


def test_clear_obstacles_outside_keeps_the_square_around_the_robot():
    cm = local_with_points([[0.8, 0.0, 0.3], [2.0, 0.0, 0.3], [0.0, -1.9, 0.3]])
    assert cm.cost_at_world(np.array([0.8, 2.0, 0.0]), np.array([0.0, 0.0, -1.9])).tolist() == [LETHAL_OBSTACLE] * 3
    n = clear_obstacles_outside(cm, 0.0, 0.0, 3.0)          # keeps |dx|, |dy| <= 1.5
    assert n == 2
    cm.update_map(Pose2D(0, 0, 0))
    assert cm.cost_at_world(np.array([0.8, 2.0, 0.0]), np.array([0.0, 0.0, -1.9])).tolist() == [
        LETHAL_OBSTACLE, FREE_SPACE, FREE_SPACE]


def test_clear_costmap_recovery_clears_every_costmap_around_its_own_pose():
    a = local_with_points([[1.0, 0.0, 0.3]])
    b = local_with_points([[1.0, 0.0, 0.3]])
    rec = ClearCostmapRecovery(ClearCostmapConfig(1.0))
    # in b the robot is 1 m away from the obstacle's side: only a keeps it
    rec.start(Pose2D(0, 0, 0), [(a, Pose2D(0.8, 0.0, 0.0)), (b, Pose2D(-0.5, 0.0, 0.0))])
    assert rec.cells_cleared == 1
    assert rec.step(Pose2D(0, 0, 0), (0, 0), a, 0.2) == (0.0, 0.0, True)
    assert make_recovery("clear_costmap").config.reset_distance_m == 0.0
    with pytest.raises(ValueError, match="reset_distance_m"):
        ClearCostmapConfig(-1.0)
    with pytest.raises(ValueError, match="unknown recovery"):
        make_recovery("backup")


def spin(rec, cm, pose, dt=0.2, max_steps=200):
    rec.start(pose, [(cm, pose)])
    ws = []
    for _ in range(max_steps):
        v, w, done = rec.step(pose, (0.0, 0.0), cm, dt)
        if done:
            break
        assert v == 0.0
        ws.append(w)
        pose = Pose2D(pose.x_m, pose.y_m, pose.yaw_rad + w * dt)
    return ws, done


def test_rotate_recovery_turns_once_and_stops():
    cm = local_with_points(np.zeros((0, 3)))
    cfg = RotateRecoveryConfig()
    ws, done = spin(RotateRecovery(cfg), cm, Pose2D(0.0, 0.0, 0.3))
    assert done
    turned = sum(w * 0.2 for w in ws)
    assert 2 * math.pi - cfg.tolerance_rad <= turned <= 2 * math.pi + cfg.max_rotational_vel * 0.2
    assert all(cfg.min_in_place_rotational_vel <= w <= cfg.max_rotational_vel for w in ws)


def test_rotate_recovery_stops_before_hitting_an_obstacle():
    # a point 0.5 m to the left of the robot: the padded 1.05 x 0.73 m footprint's corner sweeps through it
    cm = local_with_points([[0.0, 0.5, 0.3]])
    rec = RotateRecovery()
    ws, done = spin(rec, cm, Pose2D(0.0, 0.0, 0.0))
    assert done and rec.blocked
    assert sum(w * 0.2 for w in ws) < math.pi / 2
    with pytest.raises(ValueError, match="min_in_place_rotational_vel"):
        RotateRecoveryConfig(max_rotational_vel=0.1, min_in_place_rotational_vel=0.2)
