#!/usr/bin/env python3
"""rostest node: topics, types, rates, TF tree and the spawn GPS fix of sim_bridge."""
import collections
import math
import unittest

import rospy
import rostest
import tf2_ros
from cottonsim_msgs.msg import ArmContacts, PlantContacts, SimStats
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState, LaserScan, NavSatFix, PointCloud2

CAMERAS = ("realsense_p", "realsense_secondary", "realsense_tertiary")
# topic -> (type, expected rate in sim time [Hz]); rates from sim.launch's defaults + sim_ci.yaml
EXPECTED = {
    "/points": (PointCloud2, 10.0),
    "/passthrough/output": (PointCloud2, 10.0),
    "/scan": (LaserScan, 10.0),
    "/vlp/scan": (LaserScan, 10.0),
    "/scan_360": (LaserScan, 10.0),
    "/imu/data": (Imu, 50.0),
    "/navsat/fix": (NavSatFix, 40.0),
    "/husky_velocity_controller/odom": (Odometry, 50.0),
    "/odometry/filtered": (Odometry, 50.0),
    "/joint_states": (JointState, 50.0),
    "/ground_truth/odom": (Odometry, 50.0),
    "/ground_truth/plant_contacts": (PlantContacts, 10.0),
    "/ground_truth/arm_contacts": (ArmContacts, 10.0),
}
for cam in CAMERAS:
    EXPECTED[f"/{cam}/color/image_raw"] = (Image, 30.0)
    EXPECTED[f"/{cam}/color/camera_info"] = (CameraInfo, 30.0)
    EXPECTED[f"/{cam}/depth/color/points"] = (PointCloud2, 30.0)
    EXPECTED[f"/{cam}/ground_truth/semantic"] = (Image, 30.0)

FRAMES = ["base_footprint", "top_plate_link", "velodyne", "imu_link", "gps_link",
          "front_left_wheel_link", "front_right_wheel_link", "rear_left_wheel_link", "rear_right_wheel_link",
          "ur5e_base_link", "ur5e_tool0"] + [f"{c}_color_optical_frame" for c in CAMERAS]
WINDOW_S = 2.0   # sim seconds over which rates are measured


class SimTopicsTest(unittest.TestCase):
    def setUp(self):
        self.stamps = collections.defaultdict(list)
        self.first = {}
        self.subs = [rospy.Subscriber(t, typ, self._cb, callback_args=t, queue_size=200)
                     for t, (typ, _) in EXPECTED.items()]
        self.stats = []
        rospy.Subscriber("/sim/stats", SimStats, self.stats.append)

    def _cb(self, msg, topic):
        self.first.setdefault(topic, msg)
        # rospy numbers every message it publishes on a topic (header.seq), so the publication
        # rate can be measured even when this (busy) test node misses messages of big topics
        self.stamps[topic].append((msg.header.stamp.to_sec(), msg.header.seq))

    def test_topics_types_rates_tf_and_gps(self):
        deadline = rospy.Time.now().to_sec() + 300.0
        while rospy.Time.now().to_sec() < 1.0 + WINDOW_S:   # sim time
            rospy.rostime.wallsleep(0.1)
            self.assertFalse(rospy.is_shutdown())
        missing = [t for t in EXPECTED if not self.stamps[t]]
        self.assertEqual(missing, [], f"topics never published: {missing}")
        for topic, (_, rate) in EXPECTED.items():
            got = sorted(s for s in self.stamps[topic] if 0.5 < s[0] <= 0.5 + WINDOW_S)
            # the rate comes from the publisher's sequence numbers: a few received messages spread
            # over the window suffice (a loaded machine makes this node miss some of the big ones)
            self.assertGreaterEqual(len(got), 3, f"{topic}: received only {len(got)}")
            (t0, seq0), (t1, seq1) = got[0], got[-1]
            self.assertGreaterEqual(t1 - t0, 0.5 * WINDOW_S,
                                    f"{topic}: received messages span only {t1 - t0:.2f} s of the window")
            measured = (seq1 - seq0) / (t1 - t0)
            self.assertAlmostEqual(measured, rate, delta=0.1 * rate + 1.0,
                                   msg=f"{topic}: published at {measured:.1f} Hz in sim time, expected {rate} Hz")
        # each topic's messages are stamped in publication order (also with pipelined sensors,
        # whose readings leave the simulator late but in order)
        for topic in EXPECTED:
            by_seq = sorted(self.stamps[topic], key=lambda s: s[1])
            backwards = [(a, b) for a, b in zip(by_seq, by_seq[1:]) if b[0] < a[0]]
            self.assertEqual(backwards, [], f"{topic}: stamps go back ((stamp, seq) pairs)")
        # image / cloud contents are sane
        img = self.first["/realsense_p/color/image_raw"]
        self.assertEqual((img.encoding, img.width, img.height), ("rgb8", 320, 240))
        self.assertEqual(img.header.frame_id, "realsense_p_color_optical_frame")
        self.assertGreater(self.first["/points"].width, 1000)
        self.assertEqual(self.first["/points"].header.frame_id, "velodyne")
        self.assertIn("ring", [f.name for f in self.first["/points"].fields])
        self.assertIn("rgb", [f.name for f in self.first["/realsense_p/depth/color/points"].fields])
        # TF tree
        buf = tf2_ros.Buffer()
        tf2_ros.TransformListener(buf)
        for frame in ["base_link"] + FRAMES:
            src = "odom" if frame == "base_link" else "base_link"
            ok = buf.can_transform(src, frame, rospy.Time(0), rospy.Duration(5.0))
            self.assertTrue(ok, f"no TF {src} -> {frame}")
        # spawn fix = the original's start point (robot at rest at Home)
        fix = self.first["/navsat/fix"]
        self.assertAlmostEqual(fix.latitude, 49.899946, delta=1e-6)
        self.assertAlmostEqual(fix.longitude, 8.899986, delta=1e-6)
        self.assertTrue(self.stats, "no /sim/stats")
        self.assertLess(rospy.Time.now().to_sec(), deadline)


if __name__ == "__main__":
    rospy.init_node("check_sim_topics")
    rostest.rosrun("cottonsim_world", "sim_topics", SimTopicsTest)
