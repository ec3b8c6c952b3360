#!/usr/bin/env python3
"""rostest node: sim_bridge's sensor faults, scheduled (sim_faults_ci.yaml + ~faults) and at run time.

The robot stands at the spawn pose; every window of the schedule is checked on the topics:
  [2, 4) s  no /navsat/fix, black realsense_p frames, no /points or /scan
  [5, 6) s  fixes with status NO_FIX, no realsense_secondary frames, LiDAR messages without returns
  [7, 9) s  float fixes (status GBAS_FIX) with 0.5 m noise and that variance in the covariance
  [10, 11) s  fixes 3 m north of the spawn (a ~faults entry)
then /sim/inject_fault starts a GPS outage and a LiDAR dropout, /sim/clear_faults ends the dropout.
"""
import collections
import math
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
from cottonsim_msgs.msg import SensorFaults
from cottonsim_msgs.srv import ClearFaults, InjectFault
from sensor_msgs.msg import Image, LaserScan, NavSatFix, NavSatStatus, PointCloud2

from cottonsim_world.geodesy import HectorGeodesy

SPAWN_XY = (-6.0, 1.0)


def in_window(stamps, start, end):
    return [t for t in stamps if start <= t < end]


class SimFaultsTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.fixes = []                      # (stamp, msg)
        self.images = collections.defaultdict(list)   # camera -> [(stamp, all black)]
        self.points = []                     # (stamp, width)
        self.scans = []                      # (stamp, all inf)
        self.active = []                     # SensorFaults messages
        rospy.Subscriber("/navsat/fix", NavSatFix, self._on_fix, queue_size=500)
        for cam in ("realsense_p", "realsense_secondary"):
            rospy.Subscriber(f"/{cam}/color/image_raw", Image, self._on_image, callback_args=cam, queue_size=50)
        rospy.Subscriber("/points", PointCloud2, self._on_points, queue_size=50)
        rospy.Subscriber("/scan", LaserScan, self._on_scan, queue_size=50)
        rospy.Subscriber("/sim/faults/active", SensorFaults, self._on_active, queue_size=50)

    def _on_fix(self, msg):
        with self.lock:
            self.fixes.append((msg.header.stamp.to_sec(), msg))

    def _on_image(self, msg, cam):
        with self.lock:
            self.images[cam].append((msg.header.stamp.to_sec(), not any(msg.data)))

    def _on_points(self, msg):
        with self.lock:
            self.points.append((msg.header.stamp.to_sec(), msg.width))

    def _on_scan(self, msg):
        with self.lock:
            self.scans.append((msg.header.stamp.to_sec(), all(math.isinf(r) for r in msg.ranges)))

    def _on_active(self, msg):
        with self.lock:
            self.active.append(msg)

    def wait_sim(self, t_s, wall_timeout_s=300.0):
        """Wait (wall clock) until sim time reaches t_s."""
        wall_end = time.monotonic() + wall_timeout_s
        while rospy.get_time() < t_s:
            self.assertFalse(rospy.is_shutdown())
            self.assertLess(time.monotonic(), wall_end, f"sim time did not reach {t_s} s (at {rospy.get_time()})")
            rospy.rostime.wallsleep(0.05)

    def fix_xy(self, msg):
        x, y, _ = HectorGeodesy().geodetic_to_world(msg.latitude, msg.longitude, 0.0)
        return np.array([x, y])

    def test_scheduled_then_run_time_faults(self):
        self.wait_sim(11.5)
        with self.lock:
            fixes, points, scans = list(self.fixes), list(self.points), list(self.scans)
            images = {k: list(v) for k, v in self.images.items()}
            active = list(self.active)
        stamps = [t for t, _ in fixes]
        # --- GPS outage [2, 4): no messages, fixes just before and after
        self.assertEqual(in_window(stamps, 2.0, 4.0), [])
        self.assertTrue(in_window(stamps, 1.5, 2.0) and in_window(stamps, 4.0, 4.5), "fixes around the outage")
        # --- no fix [5, 6): status NO_FIX, NaN position, covariance unknown
        no_fix = [m for t, m in fixes if 5.0 <= t < 6.0]
        self.assertGreater(len(no_fix), 10)
        for m in no_fix:
            self.assertEqual(m.status.status, NavSatStatus.STATUS_NO_FIX)
            self.assertTrue(math.isnan(m.latitude) and math.isnan(m.longitude))
            self.assertEqual(m.position_covariance_type, NavSatFix.COVARIANCE_TYPE_UNKNOWN)
        # --- degraded float fix [7, 9): GBAS status, 0.5 m noise, covariance = its variance
        degraded = [m for t, m in fixes if 7.0 <= t < 9.0]
        self.assertGreater(len(degraded), 30)
        for m in degraded:
            self.assertEqual(m.status.status, NavSatStatus.STATUS_GBAS_FIX)
            self.assertEqual(m.position_covariance_type, NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN)
            self.assertAlmostEqual(m.position_covariance[0], 0.25, delta=1e-6)
            self.assertAlmostEqual(m.position_covariance[4], 0.25, delta=1e-6)
        spread = np.array([self.fix_xy(m) for m in degraded]).std(axis=0)
        self.assertTrue(np.all((spread > 0.3) & (spread < 0.7)), f"degraded fix spread {spread} m, expected ~0.5")
        # nominal fixes before it: status FIX, tiny covariance, at the spawn
        nominal = [m for t, m in fixes if 6.2 <= t < 7.0]
        self.assertTrue(nominal)
        for m in nominal:
            self.assertEqual(m.status.status, NavSatStatus.STATUS_FIX)
            self.assertLess(m.position_covariance[0], 1e-6)
            self.assertLess(np.linalg.norm(self.fix_xy(m) - SPAWN_XY), 0.05)
        # --- jump [10, 11) from ~faults: 3 m north (world +x), status still FIX
        jumped = [m for t, m in fixes if 10.0 <= t < 11.0]
        self.assertTrue(jumped)
        for m in jumped:
            self.assertEqual(m.status.status, NavSatStatus.STATUS_FIX)
            self.assertLess(np.linalg.norm(self.fix_xy(m) - (SPAWN_XY[0] + 3.0, SPAWN_XY[1])), 0.05)
        # --- cameras: realsense_p black in [2, 4) (frames keep coming), realsense_secondary none in [5, 6)
        primary = images["realsense_p"]
        black = [t for t, b in primary if b]
        self.assertTrue(black, "no black realsense_p frames")
        self.assertTrue(all(2.0 <= t < 4.0 for t in black), f"black frames outside [2, 4): {black}")
        self.assertTrue(all(b for t, b in primary if 2.0 <= t < 4.0))
        self.assertGreaterEqual(len(in_window([t for t, _ in primary], 2.0, 4.0)), 5)
        secondary = [t for t, _ in images["realsense_secondary"]]
        self.assertEqual(in_window(secondary, 5.0, 6.0), [])
        self.assertTrue(in_window(secondary, 4.0, 5.0) and in_window(secondary, 6.0, 7.0))
        self.assertFalse(any(b for _, b in images["realsense_secondary"]))
        # --- LiDAR: nothing in [2, 4), empty clouds / all-inf scans in [5, 6), returns elsewhere
        self.assertEqual(in_window([t for t, _ in points], 2.0, 4.0), [])
        self.assertEqual(in_window([t for t, _ in scans], 2.0, 4.0), [])
        empty = [w for t, w in points if 5.0 <= t < 6.0]
        self.assertTrue(empty and all(w == 0 for w in empty), f"/points widths in [5, 6): {empty}")
        self.assertTrue(all(inf for t, inf in scans if 5.0 <= t < 6.0))
        self.assertTrue(all(w > 1000 for t, w in points if 6.0 <= t < 11.0))
        # --- /sim/faults/active followed the schedule (latched, changes only)
        kinds_at = lambda t: sorted(f.kind for f in [m for m in active if m.header.stamp.to_sec() <= t][-1].active)
        self.assertEqual(kinds_at(3.0), ["camera_blackout", "gps_outage", "lidar_dropout"])
        self.assertEqual(kinds_at(5.5), ["camera_blackout", "gps_no_fix", "lidar_dropout"])
        self.assertEqual(kinds_at(8.0), ["gps_degraded"])
        self.assertEqual(kinds_at(10.5), ["gps_jump"])
        self.assertEqual(kinds_at(4.5), [])
        by_kind = {f.kind: f for f in [m for m in active if m.header.stamp.to_sec() <= 8.0][-1].active}
        self.assertEqual((by_kind["gps_degraded"].start_s, by_kind["gps_degraded"].end_s), (7.0, 9.0))
        self.assertIn('"fix_type": "float"', by_kind["gps_degraded"].parameters)

        # --- run time: bad requests are refused with a reason
        rospy.wait_for_service("/sim/inject_fault", 30.0)
        inject = rospy.ServiceProxy("/sim/inject_fault", InjectFault)
        clear = rospy.ServiceProxy("/sim/clear_faults", ClearFaults)
        for args, words in ((("gps_blackout", "", 1.0, ""), "kind must be one of"),
                            (("gps_degraded", "", 1.0, "{fix_type: rtk}"), "fix_type"),
                            (("gps_outage", "", -1.0, ""), "duration_s"),
                            (("camera_blackout", "realsense_tertiary", 1.0, ""), "not a simulated camera"),
                            (("lidar_dropout", "", 1.0, "{camera: realsense_p}"), "camera"),
                            (("gps_degraded", "", 1.0, "[1, 2"), "YAML")):
            res = inject(*args)
            self.assertFalse(res.success, f"{args} was accepted")
            self.assertIn(words, res.message)
        # a 1 s GPS outage and an endless LiDAR dropout, the dropout ended by clear_faults
        res = inject("gps_outage", "", 1.0, "")
        self.assertTrue(res.success, res.message)
        res = inject("lidar_dropout", "lidar", float("inf"), "{mode: drop}")
        self.assertTrue(res.success, res.message)
        t_inject = rospy.get_time()
        self.wait_sim(t_inject + 2.0)
        with self.lock:
            stamps = [t for t, _ in self.fixes if t > t_inject - 0.5]
            point_stamps = [t for t, _ in self.points if t > t_inject + 0.3]
        gaps = np.diff(sorted(stamps))
        self.assertTrue(np.any((gaps > 0.8) & (gaps < 1.3)), "no ~1 s gap in the fixes after the injection")
        self.assertEqual(point_stamps, [], "LiDAR messages during the injected dropout")
        res = clear()
        self.assertGreaterEqual(res.cleared, 1, res.message)
        t_clear = rospy.get_time()
        self.wait_sim(t_clear + 1.0)
        with self.lock:
            resumed = [t for t, _ in self.points if t > t_clear]
            last_active = self.active[-1]
        self.assertTrue(resumed, "/points did not resume after /sim/clear_faults")
        self.assertEqual(list(last_active.active), [])


if __name__ == "__main__":
    rospy.init_node("check_sim_faults")
    rostest.rosrun("cottonsim_world", "sim_faults", SimFaultsTest)
