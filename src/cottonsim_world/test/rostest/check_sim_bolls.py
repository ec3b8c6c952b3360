#!/usr/bin/env python3
"""rostest node: sim_bridge's boll ground truth (/sim/bolls) and /sim/set_boll_state.

The robot is teleported into lane 1 of the 2 x 3 farm (sim_bolls_ci.yaml), where its cameras and LiDAR
see bolls; one boll is taken by a "nozzle" and carried, then every boll goes to the bin through the
service, and the ground-truth masks and the LiDAR returns stamped afterwards hold no boll.
"""
import threading
import unittest

import numpy as np
import rospy
import rostest
from cottonsim_msgs.msg import Boll, BollArray
from cottonsim_msgs.srv import SetBollState, SetRobotPose
from geometry_msgs.msg import Point
from sensor_msgs.msg import Image, PointCloud2
from sensor_msgs import point_cloud2

from cottonsim_common.ros.testing import wait_until
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.farm.model import SemanticClass
from cottonsim_world.sensors.lidar import LidarConfig

CAMERAS = ("realsense_p", "realsense_secondary", "realsense_tertiary")
BOLL_INTENSITY = LidarConfig().reflectivity[SemanticClass.BOLL] * 100.0


class SimBollsTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.RLock()            # wait_for holds it while its condition takes it again
        self.arrays = []                     # BollArray messages
        self.held = []                       # /sim/bolls/held messages
        self.masks = []                      # (stamp, boll pixels) of every camera's semantic image
        self.returns = []                    # (stamp, LiDAR returns on bolls)
        rospy.Subscriber("/sim/bolls", BollArray, self._on_bolls, queue_size=100)
        rospy.Subscriber("/sim/bolls/held", BollArray, lambda m: self._keep(self.held, m), queue_size=100)
        for cam in CAMERAS:
            rospy.Subscriber(f"/{cam}/ground_truth/semantic", Image, self._on_mask, queue_size=50)
        rospy.Subscriber("/points", PointCloud2, self._on_points, queue_size=50)

    def _on_bolls(self, msg):
        self._keep(self.arrays, msg)

    def _keep(self, messages, msg):
        with self.lock:
            messages.append(msg)

    def _on_mask(self, msg):
        count = int(np.count_nonzero(np.frombuffer(msg.data, np.uint8) == SemanticClass.BOLL))
        with self.lock:
            self.masks.append((msg.header.stamp.to_sec(), count))

    def _on_points(self, msg):
        intensity = np.array([p[0] for p in point_cloud2.read_points(msg, ("intensity",))], np.float32)
        with self.lock:
            self.returns.append((msg.header.stamp.to_sec(), int(np.count_nonzero(
                np.isclose(intensity, BOLL_INTENSITY)))))

    def wait_for(self, what, condition, wall_timeout_s=120.0):
        def holds():
            with self.lock:
                return condition()
        self.assertTrue(wait_until(holds, wall_timeout_s), f"timed out waiting for {what}")

    def last_array(self):
        with self.lock:
            return self.arrays[-1]

    def seen_since(self, t_s):
        """(boll pixels, boll returns) summed over the masks and scans stamped after t_s."""
        with self.lock:
            return (sum(n for t, n in self.masks if t > t_s), sum(n for t, n in self.returns if t > t_s),
                    len([t for t, _ in self.masks if t > t_s]), len([t for t, _ in self.returns if t > t_s]))

    def sensed_bolls(self, what):
        """(boll pixels, boll returns) of the next 6+ camera masks and 3+ scans, those stamped 0.2 s after now."""
        t_s = rospy.get_time() + 0.2
        self.wait_for(what, lambda: self.seen_since(t_s)[2] >= 6 and self.seen_since(t_s)[3] >= 3)
        return self.seen_since(t_s)[:2]

    def test_truth_follows_the_service_and_the_sensors_follow_the_truth(self):
        self.wait_for("/sim/bolls", lambda: self.arrays)
        first = self.last_array()
        count = len(first.bolls)
        self.assertGreater(count, 20)
        self.assertEqual(first.header.frame_id, "world")
        self.assertEqual(first.revision, 0)
        self.assertEqual([b.id for b in first.bolls], list(range(count)))
        self.assertTrue(all(b.state == Boll.ON_PLANT and 0.03 < b.diameter_m < 0.08 for b in first.bolls))
        self.assertEqual(sorted({b.plant_id for b in first.bolls}), list(range(6)))

        # stand in lane 1, between the two rows
        farm = generate_farm(FarmConfig(rows=2, plants_per_row=3, plant_detail="low"))
        lane = farm.lanes[1]
        rospy.wait_for_service("/sim/set_robot_pose", 30.0)
        res = rospy.ServiceProxy("/sim/set_robot_pose", SetRobotPose)(
            lane.x_m, 0.5 * (lane.y_start_m + lane.y_end_m), 1.5708)
        self.assertTrue(res.success, res.message)
        pixels, returns = self.sensed_bolls("camera masks and scans in the lane")
        self.assertGreater(pixels, 0, "the cameras see no boll in the lane")
        self.assertGreater(returns, 0, "the LiDAR hits no boll in the lane")

        rospy.wait_for_service("/sim/set_boll_state", 30.0)
        set_state = rospy.ServiceProxy("/sim/set_boll_state", SetBollState)
        # bad requests: refused with the reason, nothing changes
        for args, words in (((count + 5, Boll.HELD, "nozzle", False, Point()), "unknown boll id"),
                            ((0, 9, "nozzle", False, Point()), "unknown boll state"),
                            ((0, Boll.HELD, "", False, Point()), "holder must be a non-empty name")):
            res = set_state(*args)
            self.assertFalse(res.success, f"{args} was accepted")
            self.assertIn(words, res.message)
        # take boll 0 with the nozzle, carry it
        res = set_state(0, Boll.HELD, "nozzle", True, Point(1.0, 2.0, 0.9))
        self.assertTrue(res.success, res.message)
        self.assertEqual((res.boll.state, res.boll.holder), (Boll.HELD, "nozzle"))
        self.wait_for("/sim/bolls with boll 0 held", lambda: self.arrays[-1].bolls[0].state == Boll.HELD)
        held = self.last_array().bolls[0]
        self.assertEqual((held.holder, held.position.x, held.position.y, held.position.z), ("nozzle", 1.0, 2.0, 0.9))
        self.assertGreaterEqual(self.last_array().revision, 1)
        self.wait_for("/sim/bolls/held with boll 0", lambda: self.held and [b.id for b in self.held[-1].bolls] == [0])
        self.assertEqual(self.held[-1].bolls[0].position, held.position)
        res = set_state(1, Boll.HELD, "nozzle", False, Point())
        self.assertFalse(res.success)
        self.assertIn("already holds 1 boll", res.message)
        res = set_state(0, Boll.ON_PLANT, "", False, Point())
        self.assertFalse(res.success)
        self.assertIn("cannot go back on its plant", res.message)
        # every boll to the bin
        for i in range(count):
            res = set_state(i, Boll.IN_BIN, "", False, Point())
            self.assertTrue(res.success, f"boll {i}: {res.message}")
        self.wait_for("/sim/bolls with every boll in the bin",
                      lambda: all(b.state == Boll.IN_BIN for b in self.arrays[-1].bolls))
        final = self.last_array()
        self.wait_for("/sim/bolls/held empty", lambda: self.held and not self.held[-1].bolls)
        self.assertEqual(final.bolls[0].position.x, 1.0)           # where the nozzle released it
        self.assertEqual(final.bolls[5].position, first.bolls[5].position)
        pixels, returns = self.sensed_bolls("camera masks and scans after the harvest")
        self.assertEqual(pixels, 0, "boll pixels in the masks after every boll went to the bin")
        self.assertEqual(returns, 0, "LiDAR returns on bolls after every boll went to the bin")


if __name__ == "__main__":
    rospy.init_node("check_sim_bolls")
    rostest.rosrun("cottonsim_world", "sim_bolls", SimBollsTest)
