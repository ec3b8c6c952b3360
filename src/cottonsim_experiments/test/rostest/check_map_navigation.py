#!/usr/bin/env python3
"""rostest node: a 3-waypoint map route completes on the shipped SLAM map with AMCL (navigator state + report)."""

import rospy
import rostest

from navigator_watch import NavigatorWatch


class MapNavigationTest(NavigatorWatch):
    STATE_TOPIC = "/map_waypoint_navigator/state"

    def test_route_completes(self):
        report_file = rospy.get_param("~report_file")
        self.forget_old_report(report_file)
        s = self.wait_until_finished(380)
        self.assertEqual((s["succeeded"], s["aborted"], s["skipped"]), (3, 0, 0), f"summary {s}")
        report = self.wait_for_report(report_file)
        self.assertEqual(report["mode"], "map")
        self.assertTrue(report["complete"])
        self.assertEqual(report["waypoints"], 3)
        self.assertEqual(report["cr_percent"], 100.0, report)         # within 0.25 m of every waypoint
        self.assertEqual(report["plant_contacts"], 0, report)
        # AMCL against ground truth (the full route measures ~0.13 m mean; the aim is 0.05 m)
        self.assertLess(report["localization_error_mean_m"], 0.25, report)
        self.assertLess(report["localization_error_max_m"], 0.5, report)


if __name__ == "__main__":
    rospy.init_node("check_map_navigation")
    rostest.rosrun("cottonsim_experiments", "map_navigation", MapNavigationTest)
