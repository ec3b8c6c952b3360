#!/usr/bin/env python3
"""rostest node for display.test: the URDF on /robot_description becomes a complete TF tree.

Every link of the URDF must be reachable from base_link in TF, every non-fixed joint must
appear in /joint_states, and the sensor frames the simulator's topics use must be links.
"""
import time
import unittest
import xml.etree.ElementTree as ET

import rospy
import rostest
import tf2_ros
from sensor_msgs.msg import JointState

SENSOR_FRAMES = ("velodyne", "imu_link", "gps_link")


class DisplayTest(unittest.TestCase):
    def test_every_link_is_in_tf(self):
        urdf = ET.fromstring(rospy.get_param("/robot_description"))
        links = [link.get("name") for link in urdf.findall("link")]
        movable = [j.get("name") for j in urdf.findall("joint") if j.get("type") != "fixed"]
        self.assertGreater(len(links), 10)
        for frame in SENSOR_FRAMES:
            self.assertIn(frame, links)

        states = []
        rospy.Subscriber("/joint_states", JointState, states.append, queue_size=5)
        buf = tf2_ros.Buffer()
        tf2_ros.TransformListener(buf)
        end = time.monotonic() + 30.0
        while time.monotonic() < end and not states:
            time.sleep(0.1)
        self.assertTrue(states, "no /joint_states")
        self.assertEqual(set(movable) - set(states[-1].name), set(), "movable joints missing in /joint_states")

        missing = []
        for link in links:
            try:
                buf.lookup_transform("base_link", link, rospy.Time(0), rospy.Duration(10.0))
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException):
                missing.append(link)
        self.assertEqual(missing, [], "links without a TF path to base_link")


if __name__ == "__main__":
    rospy.init_node("check_display")
    rostest.rosrun("cottonsim_description", "display_check", DisplayTest)
