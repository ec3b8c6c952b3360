#!/usr/bin/env python3
"""rostest node: a short GPS route completes (navigator state, ground truth, recorder report).

~waypoints_file (str): the route the navigator drives ("lat lon" lines).
~report_file (str): the recorder's report.json.
~expected_passed (int, 0): how many waypoints the navigator must report as driven through.
~max_cross_track_m (float, 0 = not checked): the largest in-row cross-track error the report may
    give [m] (the route must then run through a lane).
~max_heading_error_deg (float, 0 = not checked): the largest median difference between the robot's
    heading in the map frame (TF map -> base_link) and its true ENU heading while it drives straight
    [deg]: the map frame must be the ENU frame the IMU's true-north heading is in.
The waypoints' world positions come from the simulator's own GPS convention and reference
(/sim_bridge/sim, as the recorder rebuilds them), independent of the robot's map frame.
"""
import math

import numpy as np
import rospy
import rostest
import tf2_ros
from nav_msgs.msg import Odometry

from cottonsim_common.transforms import quaternion_to_yaw

from cottonsim_navigation.waypoints.files import load_gps_waypoints
from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.geodesy import HectorGeodesy
from navigator_watch import NavigatorWatch


class GpsNavigatorTest(NavigatorWatch):
    STATE_TOPIC = "/gps_waypoint_navigator/state"

    def setUp(self):
        super().setUp()
        self.truth = []
        self.heading_errors_rad = []
        self.tf_buffer = tf2_ros.Buffer()
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        settings = rospy.get_param("/sim_bridge/sim", {}) or {}
        self.geodesy = HectorGeodesy(*simulator_config_from_dict(dict(settings)).geodesy_reference)
        # the ENU direction of the world's x axis, from the simulator's own geodesy (at the farm)
        lat, lon, _ = self.geodesy.world_to_geodetic(np.array([0.0, 10.0]), np.array([0.0, 0.0]))
        north = math.radians(lat[1] - lat[0])
        east = math.radians(lon[1] - lon[0]) * math.cos(math.radians(lat[0]))
        self.world_x_enu_yaw_rad = math.atan2(north, east)
        rospy.Subscriber("/ground_truth/odom", Odometry, self._on_truth, queue_size=50)

    def _on_truth(self, m: Odometry):
        self.truth.append((m.pose.pose.position.x, m.pose.pose.position.y))
        # heading samples while driving straight (a TF that lags the truth by 0.1 s then errs < 0.005 deg)
        if len(self.truth) % 10 or abs(m.twist.twist.angular.z) > 0.01 or abs(m.twist.twist.linear.x) < 0.1:
            return
        try:
            tf = self.tf_buffer.lookup_transform("map", "base_link", rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException):
            return
        q = m.pose.pose.orientation
        r = tf.transform.rotation
        true_enu = quaternion_to_yaw(q.x, q.y, q.z, q.w) + self.world_x_enu_yaw_rad
        err = quaternion_to_yaw(r.x, r.y, r.z, r.w) - true_enu
        self.heading_errors_rad.append(math.atan2(math.sin(err), math.cos(err)))

    def test_route_completes(self):
        path = rospy.get_param("~waypoints_file")
        report_file = rospy.get_param("~report_file")
        self.forget_old_report(report_file)
        wps = load_gps_waypoints(path)
        geodesy = self.geodesy
        s = self.wait_until_finished(420)
        self.assertEqual((s["succeeded"], s["aborted"], s["skipped"]), (len(wps), 0, 0), f"summary {s}")
        # straight-on waypoints are driven through (counted among the succeeded)
        self.assertEqual(s["passed"], int(rospy.get_param("~expected_passed", 0)), f"summary {s}")
        self.assertFalse(s["returned_home"])
        # ground truth: the robot stands on the last waypoint (its world position from the sim's geodesy,
        # independent of the navigator's map frame), within move_base's goal tolerance + margin
        gx, gy, _ = geodesy.geodetic_to_world(wps[-1].lat, wps[-1].lon, 0.0)
        x, y = self.truth[-1]
        self.assertLess(math.hypot(x - gx, y - gy), 0.25, f"ends at ({x:.2f}, {y:.2f}), goal ({gx:.2f}, {gy:.2f})")
        # every waypoint was passed within 0.25 m
        traj = np.array(self.truth)
        for w in wps:
            wx, wy, _ = geodesy.geodetic_to_world(w.lat, w.lon, 0.0)
            self.assertLess(np.hypot(traj[:, 0] - wx, traj[:, 1] - wy).min(), 0.25)
        # the recorder's report
        report = self.wait_for_report(report_file)
        self.assertEqual(report["mode"], "gps")
        self.assertTrue(report["complete"])
        rospy.loginfo("check_gps_navigator: report %s", report)
        self.assertEqual(report["waypoints"], len(wps))
        self.assertEqual(report["cr_percent"], 100.0)
        self.assertLess(report["ae_m"], 0.25)
        self.assertEqual(report["plant_contacts"], 0)
        max_cross_track_m = float(rospy.get_param("~max_cross_track_m", 0.0))
        if max_cross_track_m > 0.0:
            self.assertIsNotNone(report["cross_track_max_m"], "the route never ran through a lane")
            self.assertLess(report["cross_track_max_m"], max_cross_track_m, f"report {report}")
        max_heading_error_deg = float(rospy.get_param("~max_heading_error_deg", 0.0))
        if max_heading_error_deg > 0.0:
            self.assertGreaterEqual(len(self.heading_errors_rad), 20, "too few straight-driving heading samples")
            median_deg = math.degrees(float(np.median(self.heading_errors_rad)))
            rospy.loginfo("check_gps_navigator: map heading - true ENU heading: median %.3f deg over %d samples",
                          median_deg, len(self.heading_errors_rad))
            self.assertLess(abs(median_deg), max_heading_error_deg,
                            f"the map frame's heading is {median_deg:.2f} deg off the true ENU heading")
        self.assertGreater(report["sim_duration_s"], 5.0)      # 6.5 m at <= 0.7 m/s takes > 9 s


if __name__ == "__main__":
    rospy.init_node("check_gps_navigator")
    rostest.rosrun("cottonsim_experiments", "gps_navigator", GpsNavigatorTest)
