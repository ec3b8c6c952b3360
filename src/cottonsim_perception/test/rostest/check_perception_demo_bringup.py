#!/usr/bin/env python3
"""rostest node for perception_demo_bringup.test: the perception bringup starts, drives and records.

Checks that the route driver moves the robot (>= 2 m of ground truth travel from Home, no plant
contact), that the segmentation overlay, the row-centring outputs and both boll detectors publish
while it drives, and that rosbag is recording into ~bag_dir (run.bag.active grows by > 100 kB within 45 s). The
content of the perception outputs is checked by perception_nodes.test; here the bringup is.
"""
import math
import os
import time
import unittest

import rospy
import rostest
from cottonsim_msgs.msg import BollDetections, PlantContacts
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Image
from std_msgs.msg import Float64MultiArray, Int16


class PerceptionDemoBringupTest(unittest.TestCase):
    def test_drives_perceives_and_records(self):
        counts = {"overlay": 0, "coords": 0, "intersection": 0, "left": 0, "right": 0}
        state = {"start": None, "last": None, "contacts": 0}

        def count(key):
            return lambda _msg: counts.__setitem__(key, counts[key] + 1)

        def on_truth(msg):
            p = msg.pose.pose.position
            state["start"] = state["start"] or (p.x, p.y)
            state["last"] = (p.x, p.y)

        rospy.Subscriber("/segmentation/overlay", Image, count("overlay"), queue_size=2, buff_size=1 << 22)
        rospy.Subscriber("/husky/cv/coords", Float64MultiArray, count("coords"))
        rospy.Subscriber("/mask/intersection/centerskyground", Int16, count("intersection"))
        rospy.Subscriber("/boll_detection_left/detections", BollDetections, count("left"))
        rospy.Subscriber("/boll_detection_right/detections", BollDetections, count("right"))
        rospy.Subscriber("/ground_truth/odom", Odometry, on_truth)
        rospy.Subscriber("/ground_truth/plant_contacts", PlantContacts,
                         lambda m: state.__setitem__("contacts", m.total_contact_events))

        def travelled():
            if state["start"] is None:
                return 0.0
            return math.hypot(state["last"][0] - state["start"][0], state["last"][1] - state["start"][1])

        end = time.monotonic() + 180.0
        while time.monotonic() < end and not rospy.is_shutdown():
            if travelled() >= 2.0 and min(counts.values()) >= 3:
                break
            time.sleep(0.2)
        rospy.loginfo("perception demo bringup: travelled %.2f m, messages %s", travelled(), counts)
        self.assertGreaterEqual(travelled(), 2.0, "the route driver did not move the robot 2 m")
        for key, n in counts.items():
            self.assertGreaterEqual(n, 3, f"too few messages on the {key} output while driving")
        self.assertEqual(state["contacts"], 0)

        # the recording in progress is run.bag.active (a run.bag beside it is an earlier run's, left in /tmp);
        # rosbag writes whole chunks (768 kB by default) as its buffer fills: wait for data past the first size
        active = os.path.join(rospy.get_param("~bag_dir"), "run.bag.active")
        self.assertTrue(os.path.isfile(active), f"rosbag is not recording into {active}")
        first_size = os.path.getsize(active)
        end = time.monotonic() + 45.0
        while time.monotonic() < end and not rospy.is_shutdown() and os.path.getsize(active) <= first_size + 100_000:
            time.sleep(0.5)
        rospy.loginfo("perception demo bringup: bag %d -> %d bytes", first_size, os.path.getsize(active))
        self.assertGreater(os.path.getsize(active), first_size + 100_000, "the bag does not grow while the demo runs")


if __name__ == "__main__":
    rospy.init_node("check_perception_demo_bringup")
    rostest.rosrun("cottonsim_perception", "perception_demo_bringup", PerceptionDemoBringupTest)
