#!/usr/bin/env python3
"""rostest node: a short GPS route completes (navigator state, ground truth, recorder report).

~waypoints_file (str): the route the navigator drives ("lat lon" lines).
~report_file (str): the recorder's report.json.
~expected_passed (int, 0): how many waypoints the navigator must report as driven through.
~max_cross_track_m (float, 0 = not checked): the largest in-row cross-track error the report may
    give [m] (the route must then run through a lane).
The waypoints' world positions come from the simulator's own GPS convention and reference
(/sim_bridge/sim, as the recorder rebuilds them), independent of the robot's map frame.
"""
import math

import numpy as np
import rospy
import rostest
from nav_msgs.msg import Odometry

from cottonsim_navigation.waypoints.files import load_gps_waypoints
from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.geodesy import HectorGeodesy
from navigator_watch import NavigatorWatch


class GpsNavigatorTest(NavigatorWatch):
    STATE_TOPIC = "/gps_waypoint_navigator/state"

    def setUp(self):
        super().setUp()
        self.truth = []
        rospy.Subscriber("/ground_truth/odom", Odometry,
                         lambda m: self.truth.append((m.pose.pose.position.x, m.pose.pose.position.y)))

    def test_route_completes(self):
        path = rospy.get_param("~waypoints_file")
        report_file = rospy.get_param("~report_file")
        self.forget_old_report(report_file)
        wps = load_gps_waypoints(path)
        settings = rospy.get_param("/sim_bridge/sim", {}) or {}
        geodesy = HectorGeodesy(*simulator_config_from_dict(dict(settings)).geodesy_reference)
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
        self.assertGreater(report["sim_duration_s"], 5.0)      # 6.5 m at <= 0.7 m/s takes > 9 s


if __name__ == "__main__":
    rospy.init_node("check_gps_navigator")
    rostest.rosrun("cottonsim_experiments", "gps_navigator", GpsNavigatorTest)
