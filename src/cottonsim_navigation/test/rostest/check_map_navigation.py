#!/usr/bin/env python3
"""rostest node: a 3-waypoint map route completes on the shipped SLAM map with AMCL (navigator state + report)."""
import json
import os
import time
import unittest

import rospy
import rostest
from std_msgs.msg import String


class MapNavigationTest(unittest.TestCase):
    def setUp(self):
        self.state = None
        rospy.Subscriber("/map_waypoint_navigator/state", String, self._on_state)

    def _on_state(self, msg):
        self.state = json.loads(msg.data)

    def wait_for(self, cond, wall_timeout_s, what):
        end = time.monotonic() + wall_timeout_s
        while not cond() and not rospy.is_shutdown() and time.monotonic() < end:
            rospy.rostime.wallsleep(0.2)
        self.assertTrue(cond(), f"timed out waiting for {what} (last navigator state {self.state})")

    def test_route_completes(self):
        report_file = rospy.get_param("~report_file")
        if os.path.exists(report_file):
            os.remove(report_file)           # a report of an earlier run must not pass this one
        self.wait_for(lambda: self.state is not None and self.state["state"] == "finished", 380, "the route")
        s = self.state
        self.assertEqual((s["succeeded"], s["aborted"], s["skipped"]), (3, 0, 0), f"summary {s}")
        self.wait_for(lambda: os.path.exists(report_file), 60, report_file)
        rospy.rostime.wallsleep(0.5)
        with open(report_file) as fh:
            report = json.load(fh)
        self.assertEqual(report["mode"], "map")
        self.assertTrue(report["complete"])
        self.assertEqual(report["waypoints"], 3)
        self.assertEqual(report["cr_percent"], 100.0, report)         # within 0.25 m of every waypoint
        self.assertEqual(report["plant_contacts"], 0, report)
        # AMCL against ground truth (the full route measures ~0.13 m mean; the aim is 0.05 m)
        self.assertLess(report["localization_error_mean_m"], 0.25, report)
        self.assertLess(report["localization_error_max_m"], 0.5, report)


if __name__ == "__main__":
    rospy.init_node("check_map_navigation")
    rostest.rosrun("cottonsim_navigation", "map_navigation", MapNavigationTest)
