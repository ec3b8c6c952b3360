"""Shared by the rostest check nodes that score a SLAM map against the farm's ground truth.

The bounds separate a working mapper from a broken one on short drives (they are not the
full-farm targets IoU >= 0.7 / rotation <= 0.5 deg): the simulated VLP-16 hits leaves and
branches while the truth holds collision volumes, so even a perfect short map covers only part
of each plant (IoU 0.37-0.47 seen), whereas a map built half a row spacing sideways scores IoU
< 0.25 and precision < 0.5 (unit test test_nav_map_quality).
"""
import rospy

from cottonsim_navigation.evaluation.map_quality import MapQualityConfig, evaluate_map
from cottonsim_world.farm.export import OccupancyMapConfig, rasterize_occupancy


def assert_map_matches_truth(test, farm, grid, resolution_m, origin, label):
    """Score ``grid`` against ``farm``'s occupancy in the Home frame (0.25 m cells) and assert the bounds."""
    truth, tres, torigin = rasterize_occupancy(farm, OccupancyMapConfig(resolution_m=resolution_m),
                                               frame=farm.spawn)
    q = evaluate_map(grid, resolution_m, origin, truth, tres, torigin, MapQualityConfig(cell_m=0.25))
    rospy.loginfo("%s: %d x %d cells, IoU %.3f precision %.3f recall %.3f rotation %.3f deg shift %.3f m (x %.2f, y %.2f)",
                  label, grid.shape[1], grid.shape[0], q.iou, q.precision, q.recall, q.rotation_deg, q.shift_m,
                  q.shift_x_m, q.shift_y_m)
    test.assertGreaterEqual(q.iou, 0.25)
    test.assertGreaterEqual(q.precision, 0.8)
    test.assertLessEqual(q.rotation_error_deg, 1.5)
    test.assertLessEqual(q.shift_m, 0.3)
    return q
