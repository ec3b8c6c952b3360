"""Grid, geometry and costmap layers against hand-computed values."""
import math

import numpy as np
import pytest

from cottonsim_common.angles import shortest_angular_distance, wrap_angle
from cottonsim_common.pose import Pose2D, compose, inverse
from cottonsim_common.transforms import quaternion_to_yaw, yaw_to_quaternion
from cottonsim_navigation.core.footprint import footprint_cells, footprint_radii, pad_footprint, rectangle_footprint
from cottonsim_navigation.core.grid import (FREE_SPACE, INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE,
                                            NO_INFORMATION, GridSpec, occupancy_to_cost)
from cottonsim_common.raytrace import bresenham_cells
from cottonsim_navigation.planning.costmap import (Costmap2D, CostmapConfig, InflationLayer,
                                                   InflationLayerConfig, ObstacleLayer, ObstacleLayerConfig,
                                                   StaticLayer, inflation_cost, make_global_costmap,
                                                   make_local_costmap)


def test_grid_conversions_and_validation():
    s = GridSpec(0.05, 100, 50, -2.5, -1.0)
    mx, my = s.world_to_map(np.array([-2.5, -2.449, 2.499]), np.array([-1.0, -0.95, 1.49]))
    assert mx.tolist() == [0, 1, 99] and my.tolist() == [0, 1, 49]
    x, y = s.map_to_world(0, 0)
    assert (x, y) == pytest.approx((-2.475, -0.975))
    assert not s.in_bounds(100, 0) and s.in_bounds(99, 49)
    with pytest.raises(ValueError, match="resolution_m"):
        GridSpec(0.0, 10, 10)
    with pytest.raises(ValueError, match="width"):
        GridSpec(0.1, 0, 10)


def test_occupancy_thresholds():
    occ = np.array([-1, 0, 19, 50, 65, 66, 100])
    c = occupancy_to_cost(occ)
    assert c.tolist() == [NO_INFORMATION, 0, 0, 0, 0, LETHAL_OBSTACLE, LETHAL_OBSTACLE]
    assert occupancy_to_cost(occ, track_unknown_space=False)[0] == FREE_SPACE
    with pytest.raises(ValueError):
        occupancy_to_cost(np.array([101]))


def test_geometry_helpers():
    assert wrap_angle(3 * math.pi) == pytest.approx(-math.pi)
    assert shortest_angular_distance(math.radians(170), math.radians(-170)) == pytest.approx(math.radians(20))
    a = Pose2D(1.0, 2.0, 0.5)
    b = Pose2D(-0.3, 0.7, -1.2)
    ident = compose(a, inverse(a))
    assert (ident.x_m, ident.y_m, ident.yaw_rad) == pytest.approx((0, 0, 0), abs=1e-12)
    c = compose(a, b)
    assert c.x_m == pytest.approx(1.0 + math.cos(0.5) * -0.3 - math.sin(0.5) * 0.7)
    assert quaternion_to_yaw(*yaw_to_quaternion(2.0)) == pytest.approx(2.0)
    fp = pad_footprint(rectangle_footprint(0.8, 0.4), 0.005)
    assert np.max(fp[:, 0]) == pytest.approx(0.405)
    ins, circ = footprint_radii(fp)
    assert ins == pytest.approx(0.205) and circ == pytest.approx(math.hypot(0.405, 0.205))
    with pytest.raises(ValueError, match="yaw_rad"):
        Pose2D(0, 0, float("nan"))
    s = GridSpec(0.1, 40, 40, -2, -2)
    fx, fy = footprint_cells(s, Pose2D(0, 0, 0), rectangle_footprint(0.8, 0.4))
    assert 32 <= len(fx) <= 60          # 8 x 4 cells plus the outline's rim


def test_bresenham_known_line():
    assert bresenham_cells(0, 0, 4, 2).tolist() == [[0, 0], [1, 0], [2, 1], [3, 1], [4, 2]]


def test_inflation_cost_values():
    # hand-computed: 252 * exp(-10 * (d - r_in)) truncated
    r = 0.205
    d = np.array([0.0, 0.1, 0.205, 0.25, 0.3, 0.5])
    expect = [254, 253, 253, int(252 * math.exp(-10 * 0.045)), int(252 * math.exp(-10 * 0.095)),
              int(252 * math.exp(-10 * 0.295))]
    assert inflation_cost(d, r, 10.0).tolist() == expect


def test_inflation_layer_on_a_map():
    spec = GridSpec(0.05, 41, 41, 0, 0)
    occ = np.zeros(spec.shape, np.int8)
    occ[20, 20] = 100
    cm = make_global_costmap(occ, spec)
    assert cm.costs[20, 20] == LETHAL_OBSTACLE
    # the inscribed radius of the Husky's 0.99 x 0.67 m body padded by 0.03 m: 0.365 m
    assert cm.costs[20, 27] == INSCRIBED_INFLATED_OBSTACLE                   # 0.35 m <= 0.365
    assert cm.costs[20, 28] == int(252 * math.exp(-10 * (0.40 - 0.365)))   # 0.40 m
    assert cm.costs[26, 28] == int(252 * math.exp(-10 * (0.5 - 0.365)))    # (6,8) cells = 0.50 m
    assert cm.costs[20, 30] == int(252 * math.exp(-10 * (0.5 - 0.365)))    # 0.50 m, edge of radius
    assert cm.costs[20, 31] == 0                                             # 0.55 m: beyond
    assert cm.costs[20, 0] == 0


def test_obstacle_marking_clearing_and_height_band():
    cm = Costmap2D(CostmapConfig(rolling_window=True, width=5, height=5),
                   [ObstacleLayer(ObstacleLayerConfig(obstacle_range=2.0, raytrace_range=3.0,
                                                      min_obstacle_height=0.05, max_obstacle_height=1.0))])
    layer = cm.obstacle_layer
    pts = np.array([[1.0, 0.0, 0.3], [0.0, 1.5, 2.0], [-1.9, 0.0, 0.3], [2.2, 2.2, 0.3], [0.0, -1.0, 0.0]])
    layer.add_observation(pts, (0.0, 0.0, 0.5))
    cm.update_map(Pose2D(0, 0, 0))
    def cost(x, y):
        return int(cm.cost_at_world(x, y))
    assert cost(1.0, 0.0) == LETHAL_OBSTACLE
    assert cost(0.0, 1.5) == 0            # above max height
    assert cost(-1.9, 0.0) == LETHAL_OBSTACLE
    assert cost(2.2, 2.2) == 0            # beyond obstacle_range (3.1 m)
    assert cost(0.0, -1.0) == 0           # below min height
    # a later ray through the obstacle clears it; the new end point is marked
    layer.add_observation(np.array([[1.8, 0.0, 0.3]]), (0.0, 0.0, 0.5))
    cm.update_map(Pose2D(0, 0, 0))
    assert cost(1.0, 0.0) == 0 and cost(1.8, 0.0) == LETHAL_OBSTACLE
    assert cost(-1.9, 0.0) == LETHAL_OBSTACLE     # untouched by that ray
    with pytest.raises(ValueError, match="points"):
        layer.add_observation(np.zeros((3, 2)), (0, 0, 0))


def test_rolling_window_keeps_cells_in_view():
    cm = make_local_costmap(inflation=InflationLayerConfig(enabled=False))
    cm.obstacle_layer.add_observation(np.array([[1.0, 1.0, 0.3], [-2.0, -2.0, 0.3]]), (0, 0, 0.5))
    cm.update_map(Pose2D(0, 0, 0))
    assert cm.spec.origin_x_m == pytest.approx(-2.5)
    cm.update_map(Pose2D(1.0, 0.5, 0))
    assert cm.spec.origin_x_m == pytest.approx(-1.5) and cm.spec.origin_y_m == pytest.approx(-2.0)
    assert int(cm.cost_at_world(1.0, 1.0)) == LETHAL_OBSTACLE     # still in the window, same world place
    assert int(cm.cost_at_world(-2.0, -2.0)) == NO_INFORMATION    # now off the window
    assert (cm.costs == LETHAL_OBSTACLE).sum() == 1


def test_footprint_cost_and_config_validation():
    spec = GridSpec(0.05, 60, 60, -1.5, -1.5)
    occ = np.zeros(spec.shape, np.int8)
    occ[30, 42] = 100                         # obstacle at x = 0.625, y = 0.025 (footprint to 0.525)
    cm = make_global_costmap(occ, spec, inflation=InflationLayerConfig(enabled=False))
    assert cm.footprint_cost(Pose2D(0, 0, 0)) == 0
    assert cm.footprint_cost(Pose2D(0.2, 0, 0)) == LETHAL_OBSTACLE
    assert cm.footprint_cost(Pose2D(5, 5, 0)) == NO_INFORMATION
    with pytest.raises(ValueError, match="resolution"):
        CostmapConfig(resolution=0)
    with pytest.raises(ValueError, match="footprint"):
        CostmapConfig(footprint=((0, 0), (1, 0)))
    with pytest.raises(ValueError, match="raytrace_range"):
        ObstacleLayerConfig(raytrace_range=-1)
