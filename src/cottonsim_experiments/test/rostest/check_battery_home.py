#!/usr/bin/env python3
"""rostest node: at <= 40 % battery the GPS navigator abandons the route, drives Home and stops."""
import json
import math
import time
import unittest

import rospy
import rostest
from nav_msgs.msg import Odometry
from sensor_msgs.msg import BatteryState
from std_msgs.msg import String

HOME_WORLD = (-6.0, 1.0)       # the default farm's spawn (cottonsim_world FarmConfig)


class BatteryHomeTest(unittest.TestCase):
    def setUp(self):
        self.state = None
        self.battery = None
        self.battery_at_return = None
        self.truth = []
        rospy.Subscriber("/battery/state", BatteryState, lambda m: setattr(self, "battery", m.percentage))
        rospy.Subscriber("/gps_waypoint_navigator/state", String, self._on_state)
        rospy.Subscriber("/ground_truth/odom", Odometry,
                         lambda m: self.truth.append((m.pose.pose.position.x, m.pose.pose.position.y)))

    def _on_state(self, msg):
        self.state = json.loads(msg.data)
        if self.state["state"] == "returning_home" and self.battery_at_return is None:
            self.battery_at_return = self.battery

    def test_returns_home_and_stops(self):
        end = time.monotonic() + 240
        while not rospy.is_shutdown() and time.monotonic() < end and not (
                self.state is not None and self.state["state"] == "finished"):
            rospy.rostime.wallsleep(0.2)
        s = self.state
        self.assertIsNotNone(s)
        self.assertEqual(s["state"], "finished", f"navigator state {s}")
        self.assertTrue(s["returned_home"], f"summary {s}")
        self.assertTrue(s["home_reached"], f"summary {s}")
        self.assertGreaterEqual(s["skipped"], 1, "the low battery should have cut the route short")
        # it went Home because of the battery: at that moment the charge was at or just below 40 %
        self.assertIsNotNone(self.battery_at_return)
        self.assertLessEqual(self.battery_at_return, 0.40 + 1e-6)
        self.assertGreater(self.battery_at_return, 0.35)
        # it had left Home, and came back to it (ground truth)
        far = max(math.hypot(x - HOME_WORLD[0], y - HOME_WORLD[1]) for x, y in self.truth)
        self.assertGreater(far, 0.5, "the robot never left Home")
        x, y = self.truth[-1]
        self.assertLess(math.hypot(x - HOME_WORLD[0], y - HOME_WORLD[1]), 0.3, f"ended at ({x:.2f}, {y:.2f})")
        # and it stays there: no further goals
        n = len(self.truth)
        rospy.rostime.wallsleep(3.0)
        x2, y2 = self.truth[-1]
        self.assertGreater(len(self.truth), n, "ground truth stopped")
        self.assertLess(math.hypot(x2 - x, y2 - y), 0.05, "the robot moved after the navigator finished")


if __name__ == "__main__":
    rospy.init_node("check_battery_home")
    rostest.rosrun("cottonsim_experiments", "battery_home", BatteryHomeTest)
