"""The obstacle layer's miss-counted clearing and window updates of a fixed costmap."""
import numpy as np
import pytest

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.core.grid import FREE_SPACE, LETHAL_OBSTACLE, GridSpec
from cottonsim_navigation.planning.costmap import (Costmap2D, CostmapConfig, InflationLayer, StaticLayer)
from cottonsim_navigation.planning.obstacle_layer import ObstacleLayer, ObstacleLayerConfig

SENSOR = (0.0, 0.0, 0.5)
STEM = (2.0, 0.0)


def costmap(miss_count, size_m=10.0):
    spec = GridSpec(0.05, int(size_m / 0.05), int(size_m / 0.05), -size_m / 2, -size_m / 2)
    cm = Costmap2D(CostmapConfig(track_unknown_space=False),
                   [StaticLayer(), ObstacleLayer(ObstacleLayerConfig(clearing_miss_count=miss_count)),
                    InflationLayer()])
    cm.resize(spec)
    cm.static_layer.set_map(np.zeros(spec.shape, np.int8), spec, track_unknown_space=False)
    cm.update_map(Pose2D(0, 0, 0))
    return cm


def see(cm, *xy):
    cm.obstacle_layer.add_observation(np.array([[x, y, 0.5] for x, y in xy]), SENSOR)
    cm.update_map(Pose2D(0, 0, 0))


def stem_cost(cm):
    return int(cm.cost_at_world(np.array([STEM[0]]), np.array([STEM[1]]))[0])


@pytest.mark.parametrize("misses", [1, 2, 5])
def test_a_stem_stays_marked_until_that_many_observations_see_through_it(misses):
    cm = costmap(misses)
    see(cm, STEM)
    assert stem_cost(cm) == LETHAL_OBSTACLE
    for _ in range(misses - 1):
        see(cm, (4.0, 0.0))                     # a ray through the stem's cell to a point behind it
        assert stem_cost(cm) == LETHAL_OBSTACLE
    see(cm, (4.0, 0.0))
    assert stem_cost(cm) == FREE_SPACE


def test_seeing_the_stem_again_restarts_the_count():
    cm = costmap(3)
    see(cm, STEM)
    see(cm, (4.0, 0.0))
    see(cm, (4.0, 0.0))
    see(cm, STEM)
    see(cm, (4.0, 0.0))
    see(cm, (4.0, 0.0))
    assert stem_cost(cm) == LETHAL_OBSTACLE
    see(cm, (4.0, 0.0))
    assert stem_cost(cm) == FREE_SPACE


def test_free_cells_on_the_rays_are_cleared_at_once_and_the_count_is_validated():
    cm = costmap(4)
    cm.obstacle_layer.grid[100, 130] = 100     # a non-lethal remnant at (1.5, 0) on the ray
    see(cm, (4.0, 0.0))
    assert cm.obstacle_layer.grid[100, 130] == FREE_SPACE
    for bad in (0, 256, 1.5, True):
        with pytest.raises(ValueError, match="clearing_miss_count"):
            ObstacleLayerConfig(clearing_miss_count=bad)


def test_a_window_update_gives_the_full_update_costs_inside_and_keeps_the_rest():
    full, win = costmap(1, 30.0), costmap(1, 30.0)
    far = [(-12.0, 12.0)]
    for cm in (full, win):
        cm.obstacle_layer.add_observation(np.array([[x, y, 0.5] for x, y in far]), (-12.0, 11.0, 0.5))
        cm.update_map(Pose2D(0, 0, 0))
    stems = [(1.0, 0.9), (1.7, -0.9), (3.2, 0.4), (-2.5, 2.0)]
    for cm in (full, win):
        cm.obstacle_layer.add_observation(np.array([[x, y, 0.5] for x, y in stems]), SENSOR)
    full.update_map(Pose2D(0.3, 0.1, 0.0))
    win.update_map(Pose2D(0.3, 0.1, 0.0), window_m=10.0)
    assert np.array_equal(full.costs, win.costs)
    # cells outside the window are kept as they were, even when their layer changed
    win.obstacle_layer.clear_all()
    win.update_map(Pose2D(0.3, 0.1, 0.0), window_m=2.0)
    assert int(win.cost_at_world(np.array([-12.0]), np.array([12.0]))[0]) == LETHAL_OBSTACLE
    assert int(win.cost_at_world(np.array([1.0]), np.array([0.9]))[0]) == FREE_SPACE
    # after a clearing everywhere the next window update is a full one
    win.request_full_update()
    win.update_map(Pose2D(0.3, 0.1, 0.0), window_m=2.0)
    assert int(win.cost_at_world(np.array([-12.0]), np.array([12.0]))[0]) == FREE_SPACE
    with pytest.raises(ValueError, match="window_m"):
        win.update_map(Pose2D(0, 0, 0), window_m=-1.0)
