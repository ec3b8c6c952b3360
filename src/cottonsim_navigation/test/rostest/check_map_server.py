#!/usr/bin/env python3
"""rostest node: map_server serves file and empty maps; map_saver round trip; bad file exits non-zero."""
import os
import subprocess
import tempfile
import unittest

import numpy as np
import rospy
import rostest
from nav_msgs.msg import MapMetaData, OccupancyGrid
from nav_msgs.srv import GetMap

from cottonsim_common.map_files import load_map_yaml


def wait_for_message(topic, msg_type, timeout_s=30.0):
    return rospy.wait_for_message(topic, msg_type, timeout=timeout_s)


def as_grid(msg):
    return np.asarray(msg.data, dtype=np.int8).reshape(msg.info.height, msg.info.width)


class MapServerTest(unittest.TestCase):
    def test_file_map_matches_the_file(self):
        expected, res, origin = load_map_yaml(rospy.get_param("/test_map_file"))
        msg = wait_for_message("/map", OccupancyGrid)
        self.assertEqual(msg.header.frame_id, "map")
        self.assertEqual((msg.info.width, msg.info.height), (20, 12))
        self.assertAlmostEqual(msg.info.resolution, 0.1, places=6)
        self.assertAlmostEqual(msg.info.origin.position.x, -1.0, places=6)
        self.assertAlmostEqual(msg.info.origin.position.y, 2.0, places=6)
        self.assertAlmostEqual(msg.info.origin.orientation.w, 1.0, places=6)
        grid = as_grid(msg)
        # hand-placed content of test_map (row 0 = bottom): obstacle block, single cell, unknown strip
        self.assertTrue((grid[2:5, 3:8] == 100).all())
        self.assertEqual(grid[9, 0], 100)
        self.assertTrue((grid[:, 15:] == -1).all())
        self.assertEqual(int((grid == 100).sum()), 16)
        self.assertEqual(int((grid == 0).sum()), 12 * 15 - 16)
        np.testing.assert_array_equal(grid, expected)
        meta = wait_for_message("/map_metadata", MapMetaData)
        self.assertEqual((meta.width, meta.height), (20, 12))
        rospy.wait_for_service("/static_map", timeout=30.0)
        served = rospy.ServiceProxy("/static_map", GetMap)().map
        np.testing.assert_array_equal(as_grid(served), grid)

    def test_empty_map(self):
        msg = wait_for_message("/empty/map", OccupancyGrid)
        self.assertEqual(msg.header.frame_id, "gps_map")
        self.assertEqual((msg.info.width, msg.info.height), (16, 12))   # 4 m x 3 m at 0.25 m
        self.assertAlmostEqual(msg.info.origin.position.x, -2.0, places=6)
        self.assertAlmostEqual(msg.info.origin.position.y, -1.5, places=6)
        self.assertTrue((as_grid(msg) == 0).all())
        rospy.wait_for_service("/empty/static_map", timeout=30.0)
        served = rospy.ServiceProxy("/empty/static_map", GetMap)().map
        self.assertEqual(len(served.data), 16 * 12)

    def test_map_saver_round_trip(self):
        wait_for_message("/map", OccupancyGrid)
        with tempfile.TemporaryDirectory() as folder:
            base = os.path.join(folder, "saved")
            proc = subprocess.run(["rosrun", "cottonsim_navigation", "map_saver", "-f", base,
                                   "__name:=map_saver_check", "_timeout_s:=30"],
                                  capture_output=True, text=True, timeout=60)
            self.assertEqual(proc.returncode, 0, proc.stdout + proc.stderr)
            saved, res, origin = load_map_yaml(base + ".yaml")
            expected, _, _ = load_map_yaml(rospy.get_param("/test_map_file"))
            np.testing.assert_array_equal(saved, expected)
            self.assertAlmostEqual(res, 0.1, places=6)
            np.testing.assert_allclose(origin, (-1.0, 2.0, 0.0), atol=1e-6)
            # the image itself: map_saver's trinary values, top row first
            with open(base + ".pgm", "rb") as fh:
                raw = fh.read()
            pixels = np.frombuffer(raw[-20 * 12:], dtype=np.uint8).reshape(12, 20)
            self.assertEqual(set(np.unique(pixels).tolist()), {0, 205, 254})
            self.assertEqual(pixels[11 - 9, 0], 0)                 # the single occupied cell, flipped

    def test_missing_map_file_exits_non_zero(self):
        proc = subprocess.run(["rosrun", "cottonsim_navigation", "map_server", "/nonexistent/map.yaml",
                               "__name:=bad_map_server"], capture_output=True, text=True, timeout=60)
        self.assertNotEqual(proc.returncode, 0)
        self.assertIn("map YAML not found", proc.stdout + proc.stderr)
        self.assertNotIn("Traceback", proc.stdout + proc.stderr)


if __name__ == "__main__":
    rospy.init_node("check_map_server")
    rostest.rosrun("cottonsim_navigation", "map_server_check", MapServerTest)
