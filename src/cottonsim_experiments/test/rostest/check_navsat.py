#!/usr/bin/env python3
"""rostest node: navsat_transform's datum and /odometry/gps, gps_localization's map -> base_link."""
import math
import unittest

import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import NavSatFix

from cottonsim_common.angles import wrap_angle_scalar
from cottonsim_common.ros.conversions import yaw_from_quaternion_msg
from cottonsim_common.ros.testing import wait_until
from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.geodesy import HectorGeodesy
from truth_drive import drive_until


class NavsatTest(unittest.TestCase):
    def setUp(self):
        self.truth = None
        self.gps = None
        rospy.Subscriber("/ground_truth/odom", Odometry, lambda m: setattr(self, "truth", m))
        rospy.Subscriber("/odometry/gps", Odometry, lambda m: setattr(self, "gps", m))
        self.cmd = rospy.Publisher("/cmd_vel", Twist, queue_size=1)
        self.tf_buffer = tf2_ros.Buffer()
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)

    def enu_truth(self):
        """Ground truth (world: x north, y west) -> ENU at the datum: (east, north, yaw 0 = east)."""
        p = self.truth.pose.pose
        return (-(p.position.y - self.datum_world[1]), p.position.x - self.datum_world[0],
                wrap_angle_scalar(yaw_from_quaternion_msg(p.orientation) + math.pi / 2))

    def map_base_link(self, wall_timeout_s=60.0):
        """map -> base_link (x, y, yaw), waiting up to wall_timeout_s of *wall* time for it.

        The bridge runs as fast as it can (real_time_factor 0), so a timeout in sim time is a
        fraction of a wall second; under load gps_localization's first map -> odom can come later.
        """
        self.assertTrue(wait_until(lambda: self.tf_buffer.can_transform("map", "base_link", rospy.Time(0)),
                                   wall_timeout_s), f"no TF map -> base_link within {wall_timeout_s} s (wall)")
        t = self.tf_buffer.lookup_transform("map", "base_link", rospy.Time(0))
        tr = t.transform
        return tr.translation.x, tr.translation.y, yaw_from_quaternion_msg(tr.rotation)

    def drive(self, v, w, travelled_m):
        """Command (v, w) until the truth has moved travelled_m from where it is now; then stop and settle."""
        drive_until(self.cmd, lambda: self.truth, v, w, distance_m=travelled_m, period_s=0.02)
        rospy.sleep(1.5)

    def test_datum_gps_odometry_and_map_pose(self):
        datum = rospy.wait_for_message("/navsat_transform/datum", NavSatFix, timeout=120.0)
        self.assertGreaterEqual(datum.header.stamp.to_sec(), 3.0, "datum taken before the 3 s delay")
        self.assertTrue(wait_until(lambda: self.truth is not None and self.gps is not None, 60.0),
                        "no /ground_truth/odom or /odometry/gps within 60 s (wall)")
        rospy.sleep(0.5)
        # the datum is the spawn (Home: world (-6, 1)), heading west = pi in ENU
        # the simulator's own GPS reference (its settings, its default when they set none)
        reference = simulator_config_from_dict(rospy.get_param("/sim_bridge/sim", {}) or {}).geodesy_reference
        x, y, _ = HectorGeodesy(*reference).geodetic_to_world(datum.latitude, datum.longitude, 0.0)
        self.datum_world = (x, y)
        self.assertAlmostEqual(x, -6.0, delta=0.05)
        self.assertAlmostEqual(y, 1.0, delta=0.05)
        p = self.truth.pose.pose.position
        self.assertLess(math.hypot(p.x - x, p.y - y), 0.02, "datum is not the robot's position")
        datum_yaw = rospy.get_param("/navsat_transform/datum_yaw")
        self.assertLess(abs(wrap_angle_scalar(datum_yaw - math.pi)), 0.03, f"datum yaw {datum_yaw}")
        # at rest: /odometry/gps at the origin of the ENU map
        g = self.gps.pose.pose.position
        self.assertEqual(self.gps.header.frame_id, "map")
        self.assertLess(math.hypot(g.x, g.y), 0.02, f"/odometry/gps at rest ({g.x:.3f}, {g.y:.3f})")
        mx, my, myaw = self.map_base_link()
        self.assertLess(math.hypot(mx, my), 0.02)
        self.assertLess(abs(wrap_angle_scalar(myaw - math.pi)), 0.03)

        # 3 m straight ahead = west: /odometry/gps moves 3 m towards -x
        self.drive(0.5, 0.0, 3.0)
        e, n, _ = self.enu_truth()
        g = self.gps.pose.pose.position
        travelled = math.hypot(e, n)
        self.assertTrue(3.0 <= travelled < 3.5, f"travelled {travelled:.3f} m")
        self.assertAlmostEqual(g.x, -travelled, delta=0.1)
        self.assertAlmostEqual(g.y, 0.0, delta=0.1)
        self.assertLess(math.hypot(g.x - e, g.y - n), 0.1, f"gps ({g.x:.3f}, {g.y:.3f}) truth ({e:.3f}, {n:.3f})")

        # 2 m more on a gentle left curve: map -> base_link matches the truth within 5 cm
        self.drive(0.5, 0.25, 2.0)
        e, n, th = self.enu_truth()
        mx, my, myaw = self.map_base_link()
        err = math.hypot(mx - e, my - n)
        rospy.loginfo("check_navsat: map pose (%.3f, %.3f, %.3f), truth (%.3f, %.3f, %.3f), error %.3f m",
                      mx, my, myaw, e, n, th, err)
        self.assertGreater(abs(wrap_angle_scalar(th - math.pi)), 0.15, "the robot did not turn")
        self.assertLess(err, 0.05, f"map pose ({mx:.3f}, {my:.3f}) vs truth ({e:.3f}, {n:.3f})")
        self.assertLess(abs(wrap_angle_scalar(myaw - th)), 0.05, f"map yaw {myaw:.3f} vs truth {th:.3f}")


if __name__ == "__main__":
    rospy.init_node("check_navsat")
    rostest.rosrun("cottonsim_experiments", "navsat_check", NavsatTest)
