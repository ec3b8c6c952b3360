"""Shared by the rostest check nodes of the waypoint navigators: follow a navigator's JSON state, wait on it."""
import json
import os
import time
import unittest

import rospy
from std_msgs.msg import String


class NavigatorWatch(unittest.TestCase):
    """A test case that keeps the latest state of the navigator publishing on ``STATE_TOPIC``."""

    STATE_TOPIC = ""

    def setUp(self):
        self.state = None
        rospy.Subscriber(self.STATE_TOPIC, String, self._on_state)

    def _on_state(self, msg):
        self.state = json.loads(msg.data)

    def wait_for(self, cond, wall_timeout_s, what):
        """Wait (wall clock) until ``cond()`` holds; fail naming ``what`` and the last navigator state."""
        end = time.monotonic() + wall_timeout_s
        while not cond() and not rospy.is_shutdown() and time.monotonic() < end:
            rospy.rostime.wallsleep(0.2)
        self.assertTrue(cond(), f"timed out waiting for {what} (last navigator state {self.state})")

    def forget_old_report(self, report_file):
        """Delete a report of an earlier run, so that it cannot pass this one."""
        if os.path.exists(report_file):
            os.remove(report_file)

    def wait_for_report(self, report_file, wall_timeout_s=180.0):
        """The recorder's report.json once it is written (a short pause lets the write finish).

        The recorder scores the run and draws its plots first: on a loaded machine that takes minutes."""
        self.wait_for(lambda: os.path.exists(report_file), wall_timeout_s, report_file)
        rospy.rostime.wallsleep(0.5)
        with open(report_file) as fh:
            return json.load(fh)

    def wait_until_finished(self, wall_timeout_s):
        self.wait_for(lambda: self.state is not None and self.state["state"] == "finished", wall_timeout_s,
                      "the route")
        return self.state
