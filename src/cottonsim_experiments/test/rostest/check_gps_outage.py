#!/usr/bin/env python3
"""rostest node: a scheduled GPS outage while the robot drives lane 0 (config/waypoints/gps_test_lane.txt).

Parameters (private)
  ~waypoints_file, ~report_file: the route and the recorder's report.json
  ~outage_start_s, ~outage_duration_s: the outage the launch schedules (sim time [s])
  ~expect_pause (bool): false: the outage is shorter than gps_localization's dead-reckoning limit, the robot
      drives on on odometry and never pauses; true: it is longer, the navigator pauses once the limit is
      over (~state paused, reason "GPS lost ..."), the robot stands still, and the route goes on once the fix
      is back
  ~dead_reckoning_limit_s (float, 20.0): gps_localization's limit
  ~in_rows_after_start_s (list of s): times after the outage's start at which the robot must be between
      lane 0's plants (ground truth), so that the outage is known to have hit it in the lane
Both: the route completes (3/3, CR 100 %), no plant contacts, the outage happened inside the rows, and the
report counts one outage of the scheduled length.
"""
import math
import threading

import numpy as np
import rospy
import rostest
from cottonsim_msgs.msg import GpsLocalizationStatus
from nav_msgs.msg import Odometry

from navigator_watch import NavigatorWatch

ROWS_Y = (8.6, 22.6)      # lane 0's plants span these world y [m]; the lane's centre is at world x -1.43


class GpsOutageTest(NavigatorWatch):
    STATE_TOPIC = "/gps_waypoint_navigator/state"

    def setUp(self):
        self.lock = threading.Lock()
        self.truth = []                 # (t, x, y)
        self.states = []                # (sim t, state dict)
        super().setUp()
        self.loc_states = set()
        rospy.Subscriber("/ground_truth/odom", Odometry, self._on_truth, queue_size=100)
        rospy.Subscriber("/gps_localization/status", GpsLocalizationStatus,
                         lambda m: self.loc_states.add(m.state), queue_size=20)

    def _on_truth(self, m):
        p = m.pose.pose.position
        with self.lock:
            self.truth.append((m.header.stamp.to_sec(), p.x, p.y))

    def _on_state(self, msg):
        super()._on_state(msg)                    # NavigatorWatch keeps the latest; here every one, with its time
        with self.lock:
            self.states.append((rospy.get_time(), dict(self.state)))

    def truth_at(self, t):
        traj = np.array(self.truth)
        i = int(np.searchsorted(traj[:, 0], t))
        return traj[min(i, len(traj) - 1)]

    def test_outage_in_the_lane(self):
        start = float(rospy.get_param("~outage_start_s"))
        duration = float(rospy.get_param("~outage_duration_s"))
        expect_pause = bool(rospy.get_param("~expect_pause"))
        limit = float(rospy.get_param("~dead_reckoning_limit_s", 20.0))
        report_file = rospy.get_param("~report_file")
        self.forget_old_report(report_file)
        s = self.wait_until_finished(540)
        with self.lock:
            traj = np.array(self.truth)
            states = list(self.states)
        rospy.loginfo("check_gps_outage: rows entered at %.1f s, left at %.1f s (sim)",
                      traj[np.argmax(traj[:, 2] > ROWS_Y[0]), 0], traj[np.argmax(traj[:, 2] > ROWS_Y[1]), 0])
        self.assertEqual((s["succeeded"], s["aborted"], s["skipped"]), (3, 0, 0), f"summary {s}")
        # the outage hit the robot inside the rows (a lane, between plants)
        for t in [start + dt for dt in rospy.get_param("~in_rows_after_start_s")]:
            _, x, y = self.truth_at(t)
            self.assertTrue(ROWS_Y[0] < y < ROWS_Y[1] and abs(x + 1.43) < 0.3,
                            f"at {t:.1f} s the robot was at ({x:.2f}, {y:.2f}), not in lane 0's rows")
        paused = [(t, st) for t, st in states if st["state"] == "paused"]
        if expect_pause:
            # a long outage: one pause that begins once the limit is over and ends when the fix is back
            self.assertEqual(len(paused), 1, f"pauses {paused}")
            t_pause, st = paused[0]
            self.assertIn("GPS lost", st["reason"])
            self.assertAlmostEqual(t_pause, start + limit, delta=2.0)
            after = [(t, x) for t, x in states if t > t_pause]
            self.assertTrue(after, "the route did not go on after the pause")
            t_resume = after[0][0]
            self.assertEqual(after[0][1]["state"], "navigating")
            self.assertGreaterEqual(t_resume, start + duration - 0.5)
            self.assertLess(t_resume, start + duration + 5.0)
            # the robot stood still while paused (after braking)
            _, x0, y0 = self.truth_at(t_pause + 2.0)
            _, x1, y1 = self.truth_at(t_resume - 0.5)
            self.assertLess(math.hypot(x1 - x0, y1 - y0), 0.05, "the robot moved while paused")
            self.assertIn("gps_lost", self.loc_states)
        else:
            self.assertEqual(paused, [], "the navigator paused during a short outage")
            self.assertIn("dead_reckoning", self.loc_states)
            self.assertNotIn("gps_lost", self.loc_states)
        # the report: the route, and the outage with its effect
        report = self.wait_for_report(report_file)
        self.assertTrue(report["complete"])
        self.assertEqual(report["cr_percent"], 100.0)
        self.assertEqual(report["plant_contacts"], 0)
        self.assertEqual(report["gps_outages"], 1, report.get("gps_outage_list"))
        self.assertAlmostEqual(report["gps_outage_total_s"], duration, delta=0.5)
        outage = report["gps_outage_list"][0]
        self.assertAlmostEqual(outage["start_s"], start, delta=0.5)
        # dead reckoning (odometry + IMU) kept the pose well within the lane's clearance
        self.assertIsNotNone(report["gps_outage_max_position_error_m"])
        self.assertLess(report["gps_outage_max_position_error_m"], 0.15, report["gps_outage_list"])
        if expect_pause:
            self.assertEqual(report["navigator_pauses"], 1)
            self.assertAlmostEqual(report["navigator_paused_s"], duration - limit, delta=3.0)
            self.assertAlmostEqual(outage["paused_s"], duration - limit, delta=3.0)
        else:
            self.assertEqual((report["navigator_pauses"], report["navigator_paused_s"]), (0, 0.0))

if __name__ == "__main__":
    rospy.init_node("check_gps_outage")
    rostest.rosrun("cottonsim_experiments", "gps_outage", GpsOutageTest)
