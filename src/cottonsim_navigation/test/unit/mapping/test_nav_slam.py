"""RBPF SLAM on a synthetic drive through a two-row field: map IoU and pose against the truth."""
import math

import numpy as np
import pytest

from cottonsim_navigation.localization.sensor_models import Scan, simulate_scan
from cottonsim_navigation.mapping.slam import RbpfSlam, SlamConfig
from cottonsim_navigation.mapping.tiled_map import TiledLogOddsMap
from nav_synthetic_maps import field_map


def _blocks(x, y, size=0.2):
    return set(zip(np.floor(np.asarray(x) / size).astype(int), np.floor(np.asarray(y) / size).astype(int)))


def test_slam_builds_the_field_map():
    spec, occ = field_map()
    start = np.array([0.0, -0.5, math.pi / 2])      # world pose of the map / odom origin
    cfg = SlamConfig(particles=10, xmin_m=-10, ymin_m=-10, xmax_m=25, ymax_m=10)
    slam = RbpfSlam(cfg, rng=np.random.default_rng(4))
    rng = np.random.default_rng(3)
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    true_o = np.zeros(3)
    odom = np.zeros(3)
    c, s = math.cos(start[2]), math.sin(start[2])
    for k in range(150):                            # 15 m along the lane
        true_o = true_o + [0.1, 0.0, 0.0]
        odom = odom + [0.102 * math.cos(odom[2]), 0.102 * math.sin(odom[2]), 0.001]   # 2 %, 0.01 rad/m
        world = (start[0] + c * true_o[0] - s * true_o[1], start[1] + s * true_o[0] + c * true_o[1], start[2])
        res = slam.update(odom, simulate_scan(occ, spec, world, angles, range_max_m=20.0, noise_sd_m=0.01,
                                              rng=rng), 0.1 * k)
    odom_err = math.hypot(odom[0] - true_o[0], odom[1] - true_o[1])
    slam_err = math.hypot(res.pose.x_m - true_o[0], res.pose.y_m - true_o[1])
    assert slam_err < 0.6 * odom_err                # the scans correct the heading drift
    assert abs(res.pose.yaw_rad) < 0.08 < abs(odom[2])
    m, ms = slam.occupancy()
    assert set(np.unique(m).tolist()) <= {-1, 0, 100}
    my, mx = np.nonzero(m == 100)
    x, y = ms.map_to_world(mx, my)
    est = _blocks(start[0] + c * x - s * y, start[1] + s * x + c * y)
    ty, tx = np.nonzero(occ == 100)
    gx, gy = spec.map_to_world(tx, ty)
    sel = (np.abs(gx) < 1.25) & (gy < 14.5)         # the plant halves facing the lane
    tru = _blocks(gx[sel], gy[sel])
    iou = len(est & tru) / len(est | tru)
    assert iou > 0.3
    assert 0 < res.entropy <= math.log(10) + 1e-9 and 1 <= res.neff <= 10


def test_slam_update_rules_and_copy_on_write():
    cfg = SlamConfig(particles=3, xmin_m=-5, ymin_m=-5, xmax_m=5, ymax_m=5, temporal_update_s=2.0)
    slam = RbpfSlam(cfg, rng=np.random.default_rng(0))
    scan = Scan(np.full(90, 2.0), np.linspace(-0.8, 0.8, 90))
    assert slam.update((0, 0, 0), scan, 0.0).updated              # first scan
    assert not slam.update((0.1, 0, 0), scan, 0.5).updated        # < linear_update 0.3 m, < 2 s
    assert slam.update((0.1, 0, 0), scan, 2.6).updated            # temporal update
    assert slam.update((0.1, 0, 0.6), scan, 2.7).updated          # > angular_update 0.5 rad
    m = slam.maps[0]
    clone = m.clone()
    key = next(iter(m.tiles))
    assert clone.tiles[key] is m.tiles[key]                       # shared until written
    tr = (key[1], key[0], key[1], key[0])
    dense = clone.read(tr)
    dense[0, 0] = 123
    clone.write(tr, dense, np.ones((1, 1), bool))
    assert clone.tiles[key][0, 0] == 123 and m.tiles[key][0, 0] != 123
    with pytest.raises(ValueError, match="max_urange_m"):
        SlamConfig(max_urange_m=7.0)
    with pytest.raises(ValueError, match="odom_pose"):
        slam.update((0, np.inf, 0), scan, 3.0)
    assert isinstance(TiledLogOddsMap(slam.spec).nbytes(), int)
