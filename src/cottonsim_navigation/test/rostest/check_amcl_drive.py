#!/usr/bin/env python3
"""rostest node for amcl_drive.test: a recorded drive of our simulator replayed into amcl.launch's defaults.

The recording (~recording, npz of benchmarks/amcl_replay.py: its "short" route, 24 s: from Home, 7.6 m
before the rows in the open headland, into lane -0.97 and 8 m along it) holds every /scan_360 with the EKF
odometry (odom -> base_link) and the true pose in the Home frame (= the map frame of the shipped SLAM map).
This node plays the clock: for each scan it publishes /clock, odom -> base_link and the scan, then waits (wall
time) until amcl has published its map -> odom for that scan, so no scan is dropped however slow the machine.
AMCL's map -> base_link (its map -> odom after that scan composed with the odometry) is compared with the
truth. Checks: mean error over the drive < ~max_mean_error_m (0.15 m), final error < ~max_final_error_m
(0.3 m), and no kidnap fired (amcl's "kidnapped?" warning on /rosout): the robot was never moved.
"""
import math
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import TransformStamped
from rosgraph_msgs.msg import Clock, Log
from sensor_msgs.msg import LaserScan
from tf2_msgs.msg import TFMessage

LASER_FRAME = "amcl_drive_laser"
ACK_TIMEOUT_S = 10.0             # wall time amcl may take for one scan
TRANSFORM_TOLERANCE_S = 1.0      # amcl.yaml's post-dating of map -> odom


def transform(parent, child, x, y, yaw, stamp):
    t = TransformStamped()
    t.header.frame_id, t.child_frame_id, t.header.stamp = parent, child, stamp
    t.transform.translation.x, t.transform.translation.y = float(x), float(y)
    t.transform.rotation.z, t.transform.rotation.w = math.sin(yaw / 2.0), math.cos(yaw / 2.0)
    return t


def compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


class AmclDriveTest(unittest.TestCase):
    def setUp(self):
        d = np.load(rospy.get_param("~recording"))
        self.stamps, self.ranges, self.odom, self.truth = d["t"], d["ranges"], d["odom"], d["truth"]
        self.laser_pose, self.scan_geometry = d["laser_pose"], d["scan"]
        self.lock = threading.Lock()
        self.map_to_odom = {}            # post-dated stamp [ns] -> (x, y, yaw)
        self.kidnap_warnings = []
        self.clock_pub = rospy.Publisher("/clock", Clock, queue_size=10)
        self.tf_pub = rospy.Publisher("/tf", TFMessage, queue_size=10)
        self.scan_pub = rospy.Publisher("/scan_360", LaserScan, queue_size=10)
        self.static = tf2_ros.StaticTransformBroadcaster()
        rospy.Subscriber("/tf", TFMessage, self.on_tf, queue_size=50)
        rospy.Subscriber("/rosout", Log, self.on_log, queue_size=50)

    def on_tf(self, msg):
        for t in msg.transforms:
            if t.header.frame_id == "map" and t.child_frame_id == "odom":
                q = t.transform.rotation
                yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
                with self.lock:
                    self.map_to_odom[t.header.stamp.to_nsec()] = (t.transform.translation.x,
                                                                   t.transform.translation.y, yaw)

    def on_log(self, msg):
        if "kidnapped?" in msg.msg:
            self.kidnap_warnings.append(msg.msg)

    def play(self, i, timeout_s=ACK_TIMEOUT_S):
        """Publish scan i with its clock and odometry; returns amcl's map -> odom for it (None: no answer
        within ``timeout_s`` of wall time)."""
        stamp = rospy.Time.from_sec(float(self.stamps[i]))
        self.clock_pub.publish(Clock(clock=stamp))
        ox, oy, oyaw = self.odom[i]
        self.tf_pub.publish(TFMessage([transform("odom", "base_link", ox, oy, oyaw, stamp)]))
        time.sleep(0.01)                 # the odometry first: amcl looks it up at the scan's stamp
        a0, da, rmin, rmax = (float(v) for v in self.scan_geometry)
        scan = LaserScan()
        scan.header.stamp, scan.header.frame_id = stamp, LASER_FRAME
        scan.angle_min, scan.angle_increment = a0, da
        scan.angle_max = a0 + da * (self.ranges.shape[1] - 1)
        scan.range_min, scan.range_max = rmin, rmax
        scan.ranges = [float(r) for r in self.ranges[i]]
        self.scan_pub.publish(scan)
        key = (stamp + rospy.Duration(TRANSFORM_TOLERANCE_S)).to_nsec()
        end = time.monotonic() + timeout_s
        while time.monotonic() < end and not rospy.is_shutdown():
            with self.lock:
                if key in self.map_to_odom:
                    return self.map_to_odom[key]
            time.sleep(0.002)
        return None

    def test_default_amcl_tracks_the_recorded_drive(self):
        lx, ly, lyaw = (float(v) for v in self.laser_pose)
        self.static.sendTransform(transform("base_link", LASER_FRAME, lx, ly, lyaw, rospy.Time(0)))
        # the first scan again until amcl answers: it has its map and our topics are connected
        end = time.monotonic() + 60.0
        first = None
        while first is None and time.monotonic() < end and not rospy.is_shutdown():
            first = self.play(0, 1.0)
        self.assertIsNotNone(first, "amcl did not answer the first scan within 60 s")
        errors, missing = [], 0
        for i in range(len(self.stamps)):
            m2o = first if i == 0 else self.play(i)
            if m2o is None:
                missing += 1
                continue
            x, y, _ = compose(m2o, self.odom[i])
            errors.append(math.hypot(x - self.truth[i][0], y - self.truth[i][1]))
        time.sleep(0.5)                  # late /rosout messages
        errors = np.array(errors)
        rospy.loginfo("amcl_drive: %d scans, %d unanswered; error mean %.3f m, first %.3f m, final %.3f m, "
                      "max %.3f m; kidnap warnings %d", len(self.stamps), missing, errors.mean(), errors[0],
                      errors[-1], errors.max(), len(self.kidnap_warnings))
        self.assertLess(missing, 0.05 * len(self.stamps), "amcl did not answer most scans")
        self.assertEqual(self.kidnap_warnings, [], "a kidnap was detected although the robot was never moved")
        self.assertLess(errors.mean(), rospy.get_param("~max_mean_error_m", 0.15))
        self.assertLess(errors[-1], rospy.get_param("~max_final_error_m", 0.3))


if __name__ == "__main__":
    rospy.init_node("amcl_drive_check")
    rostest.rosrun("cottonsim_navigation", "amcl_drive_check", AmclDriveTest)
