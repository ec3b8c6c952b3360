#!/usr/bin/env python3
"""rostest node: the perception nodes through a 5 s camera blackout (black frames) and a 5 s camera drop.

The fault schedule (perception_faults_ci.yaml): from 4 s to 9 s of sim time realsense_p sends black
frames and realsense_secondary sends nothing.
"""
import threading
import time
import unittest

import rosnode
import rospy
import rostest
from cottonsim_msgs.msg import CottonEyeHealth

FAULT_START_S, FAULT_END_S = 4.0, 9.0
DONE_S = 16.0           # sim time by which both cameras have been back for several seconds


class HealthLog:
    """Every health report, as (node, input) -> [(stamp s, CottonEyeCamera)]."""

    def __init__(self):
        self.reports = {}
        self.backends = {}
        self.lock = threading.Lock()
        rospy.Subscriber("/cotton_eye/health", CottonEyeHealth, self._cb, queue_size=50)

    def _cb(self, msg):
        with self.lock:
            self.backends[msg.node] = msg.backend
            for cam in msg.cameras:
                self.reports.setdefault((msg.node, cam.camera), []).append((msg.header.stamp.to_sec(), cam))

    def of(self, node, camera):
        with self.lock:
            return list(self.reports.get((node, camera), []))


class PerceptionFaultsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.log = HealthLog()
        wall_end = time.monotonic() + 240.0
        while rospy.get_time() < DONE_S and time.monotonic() < wall_end and not rospy.is_shutdown():
            time.sleep(0.2)
        cls.reached_s = rospy.get_time()

    def _wait_for(self, node, camera, predicate, timeout_s=120.0):
        """The first (stamp, report) of node/camera that satisfies predicate, polling while the sim runs
        (a loaded machine may delay a node's slots by seconds of sim time), or None."""
        wall_end = time.monotonic() + timeout_s
        while not rospy.is_shutdown():
            for stamp, report in self.log.of(node, camera):
                if predicate(stamp, report):
                    return stamp, report
            if time.monotonic() > wall_end:
                return None
            time.sleep(0.2)
        return None

    def test_the_run_got_past_the_faults(self):
        self.assertGreaterEqual(self.reached_s, DONE_S, "sim time did not get past the faults")
        self.assertEqual(self.log.backends.get("segmentation"), "onnxruntime")
        self.assertEqual(self.log.backends.get("boll_detection"), "onnxruntime")

    def test_black_frames_are_counted_and_the_camera_is_used_again(self):
        before = [c for t, c in self.log.of("segmentation", "realsense_p") if t < FAULT_START_S]
        self.assertTrue(before and before[-1].frames_black == 0, "black frames before the fault")
        at_end = self._wait_for("segmentation", "realsense_p", lambda t, c: t >= FAULT_END_S)
        self.assertIsNotNone(at_end, "no segmentation report after the fault")
        self.assertGreaterEqual(at_end[1].frames_black, 10, "5 s of black frames at 5 Hz")
        again = self._wait_for("segmentation", "realsense_p",
                               lambda t, c: c.frames_processed > at_end[1].frames_processed + 5)
        self.assertIsNotNone(again, "the front camera's frames are not processed again after the fault")
        self.assertEqual(again[1].frames_black, at_end[1].frames_black, "black frames after the fault")
        self.assertTrue(rosnode.rosnode_ping("/segmentation", max_count=1), "segmentation died")

    def test_a_camera_without_frames_goes_stale_and_comes_back(self):
        stale = self._wait_for("boll_detection", "realsense_secondary", lambda t, c: c.stale)
        self.assertIsNotNone(stale, "the left camera was never reported stale")
        self.assertGreater(stale[0], FAULT_START_S, "stale before the fault")
        back = self._wait_for("boll_detection", "realsense_secondary",
                              lambda t, c: t > stale[0] and not c.stale
                              and c.frames_processed > stale[1].frames_processed)
        self.assertIsNotNone(back, "the left camera is not used again after the fault")
        self.assertGreater(back[1].frames_stale, 0)
        right = self._wait_for("boll_detection", "realsense_tertiary", lambda t, c: t >= back[0])
        self.assertIsNotNone(right)
        self.assertEqual(right[1].frames_stale, 0, "the right camera was hit")
        self.assertTrue(rosnode.rosnode_ping("/boll_detection", max_count=1), "boll_detection died")


if __name__ == "__main__":
    rospy.init_node("check_perception_faults")
    rostest.rosrun("cottonsim_perception", "perception_faults", PerceptionFaultsTest)
