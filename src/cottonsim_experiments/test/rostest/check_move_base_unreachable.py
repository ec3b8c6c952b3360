#!/usr/bin/env python3
"""rostest node: move_base aborts a goal on a stem, the route goes on, a goal beyond a row is reached around it.

~waypoints_file (str): the route ("lat lon" lines); its first waypoint lies on a stem.
~report_file (str): the recorder's report.json.
~row_x_m (float): world x of the row between the second and the third waypoint; the robot must not
    cross it between the row's first and last stem (its footprint's half width beyond them).
~max_abort_sim_s (float): sim time from the start to the first goal's abort [s].
"""
import math

import numpy as np
import rospy
import rostest
from nav_msgs.msg import Odometry

from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.geodesy import HectorGeodesy
from cottonsim_navigation.waypoints.files import load_gps_waypoints
from navigator_watch import NavigatorWatch

HUSKY_HALF_LENGTH_M = 0.5


class UnreachableGoalTest(NavigatorWatch):
    STATE_TOPIC = "/gps_waypoint_navigator/state"

    def setUp(self):
        super().setUp()
        self.truth = []
        self.first_abort_s = None
        rospy.Subscriber("/ground_truth/odom", Odometry, self._on_truth)

    def _on_truth(self, m):
        self.truth.append((m.pose.pose.position.x, m.pose.pose.position.y))
        if self.first_abort_s is None and self.state is not None and self.state.get("aborted", 0) > 0:
            self.first_abort_s = m.header.stamp.to_sec()

    def test_stem_goal_aborted_and_row_driven_around(self):
        report_file = rospy.get_param("~report_file")
        self.forget_old_report(report_file)
        wps = load_gps_waypoints(rospy.get_param("~waypoints_file"))
        config = simulator_config_from_dict(dict(rospy.get_param("/sim_bridge/sim", {}) or {}))
        geodesy = HectorGeodesy(*config.geodesy_reference)
        plant_xy = generate_farm(config.farm).plant_positions()
        s = self.wait_until_finished(560)
        rospy.loginfo("check_move_base_unreachable: navigator %s", s)
        # goal 1 (on a stem) aborted by move_base with its reason, not by the navigator's time-out
        self.assertEqual((s["succeeded"], s["aborted"], s["skipped"]), (len(wps) - 1, 1, 0), f"summary {s}")
        aborted = s["aborted_waypoints"]
        self.assertEqual([a["index"] for a in aborted], [1], f"aborted {aborted}")
        self.assertIn("ABORTED", aborted[0]["reason"])
        self.assertIn("obstacle", aborted[0]["reason"])
        self.assertNotIn("timed out", aborted[0]["reason"])
        self.assertIsNotNone(self.first_abort_s)
        self.assertLess(self.first_abort_s, float(rospy.get_param("~max_abort_sim_s")))
        # the route went on: the robot passed goals 2-4 (ground truth, the sim's own geodesy)
        traj = np.array(self.truth)
        for w in wps[1:]:
            wx, wy, _ = geodesy.geodetic_to_world(w.lat, w.lon, 0.0)
            self.assertLess(np.hypot(traj[:, 0] - wx, traj[:, 1] - wy).min(), 0.25, f"goal ({wx:.2f}, {wy:.2f})")
        # goal 3 lies beyond the row at row_x_m: the robot went around the row's end, never across the row
        row_x = float(rospy.get_param("~row_x_m"))
        stems_y = plant_xy[np.isclose(plant_xy[:, 0], row_x, atol=0.05), 1]
        self.assertGreater(len(stems_y), 0, f"no row at x = {row_x}")
        side = np.sign(traj[:, 0] - row_x)
        crossed = np.nonzero(side[1:] * side[:-1] < 0)[0]
        y_cross = 0.5 * (traj[crossed, 1] + traj[crossed + 1, 1])
        inside = (y_cross > stems_y.min() - HUSKY_HALF_LENGTH_M) & (y_cross < stems_y.max() + HUSKY_HALF_LENGTH_M)
        self.assertFalse(inside.any(), f"crossed the row at y = {y_cross[inside]}")
        self.assertTrue(len(crossed) > 0, "never crossed to the row's other side")
        # no plant touched over the whole run
        report = self.wait_for_report(report_file)
        rospy.loginfo("check_move_base_unreachable: report %s", report)
        self.assertEqual(report["plant_contacts"], 0)
        self.assertEqual(report["navigator"]["aborted_waypoints"][0]["index"], 1)
        self.assertTrue(math.isfinite(report["sim_duration_s"]))


if __name__ == "__main__":
    rospy.init_node("check_move_base_unreachable")
    rostest.rosrun("cottonsim_experiments", "move_base_unreachable_goal", UnreachableGoalTest)
