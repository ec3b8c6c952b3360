#!/usr/bin/env python3
"""rostest node: the ROS contract of the segmentation, row-centring and boll-detection nodes.

The robot stands still in lane 1 (centre x = -3.23 m, facing north), between
row 0 (x = -2.33 m, on its right) and row 1 (x = -4.13 m, on its left).
"""
import math
import threading
import time
import unittest

import numpy as np
import rosnode
import rospy
import rostest
import tf2_ros
from cottonsim_msgs.msg import BollDetections, CottonEyeHealth
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Image
from std_msgs.msg import Bool, Float32, Float64MultiArray, Int16, String

from cottonsim_common.ros import conversions as conv

ROW_X = {"realsense_secondary": -4.13, "realsense_tertiary": -2.33}    # the near rows, left and right [m]
ROW_SPACING_M = 1.8
REACH_M = 0.85


class Collector:
    """Keeps the messages of one topic (the last 50)."""

    def __init__(self, topic, msg_type):
        self.msgs = []
        self.lock = threading.Lock()
        rospy.Subscriber(topic, msg_type, self._cb, queue_size=20, buff_size=1 << 24)

    def _cb(self, msg):
        with self.lock:
            self.msgs = (self.msgs + [msg])[-50:]

    def wait(self, count=1, timeout_s=60.0):
        """The messages so far, once there are ``count`` of them or after timeout_s of wall time."""
        wall_end = time.monotonic() + timeout_s
        while time.monotonic() < wall_end and not rospy.is_shutdown():
            with self.lock:
                if len(self.msgs) >= count:
                    return list(self.msgs)
            time.sleep(0.05)
        with self.lock:
            return list(self.msgs)


def wait_for_same_stamp(first, second, first_name, second_name, timeout_s=30.0):
    """The newest pair of messages, one from each collector, with the same header stamp.

    Both topics come from one camera frame, but each collector keeps only its last 50 messages
    and receives at its own pace, so one snapshot of both may not overlap yet: poll until they do.
    """
    wall_end = time.monotonic() + timeout_s
    while True:
        a, b = first.wait(1, timeout_s=1.0), second.wait(1, timeout_s=1.0)
        by_stamp = {m.header.stamp: m for m in a}
        pairs = [(by_stamp[m.header.stamp], m) for m in b if m.header.stamp in by_stamp]
        if pairs:
            return pairs[-1]
        if time.monotonic() > wall_end or rospy.is_shutdown():
            def span(msgs):
                return (f"{len(msgs)} messages, stamps {msgs[0].header.stamp.to_sec():.3f}.."
                        f"{msgs[-1].header.stamp.to_sec():.3f} s" if msgs else "no messages")
            raise AssertionError(f"no {second_name} shares a stamp with a {first_name} within {timeout_s} s: "
                                 f"{first_name}s {span(a)}, {second_name}s {span(b)}")
        time.sleep(0.2)


class PerceptionNodesTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.semantic = Collector("/realsense_p/ground_truth/semantic", Image)
        cls.labels = Collector("/segmentation/labels", Image)
        cls.ground = Collector("/segmentation/mask/ground", Image)
        cls.latency = Collector("/segmentation/latency_ms", Float32)
        cls.nw_labels = Collector("/segmentation_nw/labels", Image)
        cls.coords = Collector("/husky/cv/coords", Float64MultiArray)
        cls.intersection = Collector("/mask/intersection/centerskyground", Int16)
        cls.status = Collector("/row_centring/status", String)
        cls.probe_status = Collector("/row_centring_probe/status", String)
        cls.probe_coords = Collector("/probe/coords", Float64MultiArray)
        cls.left = Collector("/boll_detection_left/detections", BollDetections)
        cls.right = Collector("/boll_detection_right/detections", BollDetections)
        cls.in_reach = Collector("/cotton_eye/bolls_in_reach", Bool)
        cls.truth = Collector("/ground_truth/odom", Odometry)
        cls.bad_detections = Collector("/boll_detection_bad/detections", BollDetections)
        cls.health = Collector("/cotton_eye/health", CottonEyeHealth)
        cls.probe_pub = rospy.Publisher("/probe/labels", Image, queue_size=5)
        cls.tf_buffer = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)

    def test_labels_and_masks_follow_the_ground_truth(self):
        labels = self.labels.wait(3)
        self.assertGreaterEqual(len(labels), 3, "no /segmentation/labels")
        sem, lab = wait_for_same_stamp(self.semantic, self.labels, "semantic image", "label image")
        self.assertEqual(lab.encoding, "mono8")
        self.assertEqual(lab.header.frame_id, "realsense_p_color_optical_frame")
        s, l = conv.image_to_array(sem), conv.image_to_array(lab)
        np.testing.assert_array_equal(l, s)          # the oracle passes the classes through
        self.assertTrue({1, 2} <= set(np.unique(l).tolist()), "front view without ground and sky")
        lab, ground = wait_for_same_stamp(self.labels, self.ground, "label image", "ground mask")
        g = conv.image_to_array(ground)
        np.testing.assert_array_equal(g, (conv.image_to_array(lab) == 1) * 255)
        lat = self.latency.wait(1)
        self.assertTrue(lat and all(0.0 < m.data < 5000.0 for m in lat),
                        f"latencies [ms] {[round(m.data, 2) for m in lat[-10:]]}")

    def test_row_centring_outputs_when_centred(self):
        coords = self.coords.wait(3)
        self.assertGreaterEqual(len(coords), 3, "no /husky/cv/coords")
        for m in coords:
            self.assertEqual(len(m.data), 2)
            self.assertAlmostEqual(m.data[0], 0.5)                         # forward speed
            self.assertLessEqual(abs(m.data[1]), math.radians(5.0) + 1e-9)  # the paper's cap x gain 1
        xs = [m.data for m in self.intersection.wait(3)]
        self.assertTrue(xs)
        # centred and aligned in the lane: the vanishing point is (nearly) the image centre, 160 px
        self.assertLess(abs(np.median(xs) - 160.0), 8.0, f"intersections {xs[-5:]}")
        self.assertTrue(all(m.data.startswith("ok") for m in self.status.wait(3)[-3:]))

    def test_row_centring_bad_frames_give_no_estimate(self):
        def send(img):
            self.probe_pub.publish(img)
            rospy.rostime.wallsleep(0.4)
        while self.probe_pub.get_num_connections() == 0 and not rospy.is_shutdown():
            rospy.rostime.wallsleep(0.05)
        stamp = rospy.Time.now()
        send(conv.image_msg(np.zeros((60, 80, 3), np.uint8), stamp, "x"))                 # rgb8, not labels
        send(Image(height=0, width=0, encoding="mono8"))                                  # empty frame
        sky_only = np.zeros((60, 80), np.uint8)                                            # sky and plants only
        sky_only[:30] = 2
        send(conv.image_msg(sky_only, stamp, "x"))
        ok = np.full((120, 160), 0, np.uint8)                                              # a valid V: estimate
        ok[60:, :] = 1
        ok[:50, 40:120] = 2
        send(conv.image_msg(ok, stamp, "x"))
        texts = [m.data for m in self.probe_status.wait(4, timeout_s=10.0)]
        self.assertEqual(len(texts), 4, texts)
        self.assertTrue(texts[0].startswith("no_estimate") and "mono8" in texts[0], texts[0])
        self.assertTrue(texts[1].startswith("no_estimate") and "empty" in texts[1], texts[1])
        self.assertEqual(texts[2], "no_estimate: no ground mask")
        self.assertTrue(texts[3].startswith("ok"), texts[3])
        self.assertEqual(len(self.probe_coords.wait(1, timeout_s=2.0)), 1, "coords only for the valid frame")

    def test_network_source_without_weights_stays_up_and_silent(self):
        self.labels.wait(3)                          # the simulator is producing frames
        self.assertEqual(self.nw_labels.msgs, [], "published labels without weights")
        self.assertTrue(rosnode.rosnode_ping("/segmentation_nw", max_count=1), "node died")

    def _health_of(self, node, count=2, timeout_s=120.0):
        """The newest health reports of one node (at least ``count`` if they come within timeout_s)."""
        wall_end = time.monotonic() + timeout_s
        while True:
            mine = [m for m in self.health.wait(1, timeout_s=1.0) if m.node == node]
            if len(mine) >= count or time.monotonic() > wall_end or rospy.is_shutdown():
                return mine
            time.sleep(0.2)

    def test_a_weights_file_that_does_not_load_leaves_the_node_up_reporting_it(self):
        # both boll nodes report as "boll_detection": wait (bounded) for one from the one-camera node
        wall_end = time.monotonic() + 60.0
        while True:
            reports = self._health_of("boll_detection", count=1)
            bad = [m for m in reports if [c.camera for c in m.cameras] == ["realsense_secondary"]]
            if bad or time.monotonic() > wall_end or rospy.is_shutdown():
                break
            time.sleep(0.5)
        self.assertTrue(bad, f"no health report of boll_detection_bad: {[m.backend for m in reports]}")
        self.assertEqual(bad[-1].backend, "none")
        self.assertIn("cannot load weights", bad[-1].error)
        self.assertIn("README.md", bad[-1].error)
        self.assertTrue(rosnode.rosnode_ping("/boll_detection_bad", max_count=1), "node died")
        self.assertEqual(self.bad_detections.msgs, [], "published detections without a network")

    def test_health_counts_frames_and_names_the_source(self):
        seg = self._health_of("segmentation", count=2)
        ground_truth = [m for m in seg if m.backend == "ground_truth"]
        self.assertGreaterEqual(len(ground_truth), 2, f"segmentation reports: {[m.backend for m in seg]}")
        first, last = ground_truth[0].cameras[0], ground_truth[-1].cameras[0]
        self.assertEqual(last.camera, "realsense_p")
        self.assertGreater(last.frames_processed, first.frames_processed)
        self.assertLessEqual(last.frames_processed, last.frames_received)
        # (at real-time factor 0 the sim clock may outrun the renders: stale then is true, and must say so)
        self.assertEqual(last.stale, last.last_frame_age_s > 1.0, f"age {last.last_frame_age_s:.2f} s")
        self.assertEqual(last.frames_black, 0)
        no_weights = [m for m in seg if m.backend == "none"]
        self.assertTrue(no_weights and "does not exist" in no_weights[-1].error, "segmentation_nw's report")
        # the two-camera node: wait (bounded) for a report after both cameras' first processed frames
        # (at 2 Hz on a loaded machine the first reports may come before the second camera's first frame)
        wall_end = time.monotonic() + 60.0
        while True:
            bolls = [m for m in self._health_of("boll_detection", count=4) if len(m.cameras) == 2]
            if (bolls and all(c.frames_processed > 0 for c in bolls[-1].cameras)) or time.monotonic() > wall_end:
                break
            time.sleep(0.5)
        self.assertTrue(bolls, "no report of the two-camera boll_detection node")
        self.assertEqual([c.camera for c in bolls[-1].cameras], ["realsense_secondary", "realsense_tertiary"])
        self.assertTrue(all(c.frames_processed > 0 for c in bolls[-1].cameras),
                        f"frames processed per camera: {[c.frames_processed for c in bolls[-1].cameras]}")
        rows = self._health_of("row_centring", count=1)
        self.assertTrue(any(c.frames_processed > 0 for m in rows for c in m.cameras), "row_centring's report")

    def test_boll_detections_in_base_link_on_the_right_side(self):
        truth = self.truth.wait(1)[-1].pose.pose
        yaw = conv.yaw_from_quaternion_msg(truth.orientation)
        arm = self.tf_buffer.lookup_transform("base_link", "ur5e_base_link", rospy.Time(0), rospy.Duration(10.0))
        arm_xyz = np.array([arm.transform.translation.x, arm.transform.translation.y, arm.transform.translation.z])
        for collector, camera, side in ((self.left, "realsense_secondary", +1), (self.right, "realsense_tertiary", -1)):
            msgs = collector.wait(2)
            self.assertTrue(msgs, f"no detections of {camera}")
            msg = msgs[-1]
            self.assertEqual(msg.header.frame_id, "base_link")
            self.assertEqual(msg.camera, camera)
            located = [d for d in msg.detections if d.has_position]
            self.assertGreaterEqual(len(located), 3, f"{camera}: {len(msg.detections)} boxes, {len(located)} located")
            near, rows = [], []
            for d in located:
                self.assertLess(d.x_min, d.x_max)
                self.assertEqual(d.score, 1.0)
                p = d.position
                self.assertGreater(side * p.y, 0.2, f"{camera}: boll at y = {p.y:.2f} m is on the wrong side")
                # into the world with the true pose: near the row's stems, between ground and plant top
                wx = truth.position.x + math.cos(yaw) * p.x - math.sin(yaw) * p.y
                wz = truth.position.z + p.z
                # the camera sees the near row and, through its gaps, the rows beyond it (same side)
                k = round((wx - ROW_X[camera]) / (side * -ROW_SPACING_M))
                self.assertGreaterEqual(k, 0, f"{camera}: boll at world x {wx:.2f} m is behind the camera")
                self.assertLess(abs(wx - (ROW_X[camera] - side * k * ROW_SPACING_M)), 0.45,
                                f"{camera}: boll at world x {wx:.2f} m is not on a row")
                rows.append(k)
                self.assertTrue(0.0 < wz < 1.3, f"{camera}: boll at height {wz:.2f} m")
                near.append(np.linalg.norm(np.array([p.x, p.y, p.z]) - arm_xyz) <= REACH_M)
            self.assertIn(0, rows, f"{camera}: no boll on the near row")
            self.assertEqual(msg.in_reach, any(near))
        flags = [m.data for m in self.in_reach.wait(2)]
        self.assertTrue(flags)


if __name__ == "__main__":
    rospy.init_node("check_perception_nodes")
    rostest.rosrun("cottonsim_perception", "perception_nodes", PerceptionNodesTest)
