#!/usr/bin/env python3
"""rostest node: a short vision-guided GPS route completes, with the row-centring correction applied by
move_base and halts at bolls.

~waypoints_file (str): the route the navigator drives ("lat lon" lines).
~report_file (str): the recorder's report.json.
Checks: the navigator finishes with every waypoint succeeded; /move_base/vision_correction carried at least
one correction (the row-centring estimate reached move_base and changed its command); the navigator's state
went "halted" at least once, each halt followed by "navigating" again (the route went on); the ground truth
shows the robot standing (speed < 0.05 m/s) during every halt; /cotton_eye/bolls_in_reach said true; the
recorder's report is complete with CR 100 %, no plant contacts and the navigator's halt count.
"""
import math

import rospy
import rostest
from nav_msgs.msg import Odometry
from std_msgs.msg import Bool, Float64

from navigator_watch import NavigatorWatch

STANDING_MPS = 0.05


class VisionRouteTest(NavigatorWatch):
    STATE_TOPIC = "/gps_waypoint_navigator/state"

    def setUp(self):
        super().setUp()
        self.corrections = []
        self.in_reach_true = 0
        self.states = []             # (sim s, state name)
        self.speeds = []             # (sim s, ground-truth speed m/s)
        rospy.Subscriber("/move_base/vision_correction", Float64, lambda m: self.corrections.append(m.data))
        rospy.Subscriber("/cotton_eye/bolls_in_reach", Bool, self._on_in_reach)
        rospy.Subscriber("/ground_truth/odom", Odometry, self._on_truth)

    def _on_state(self, msg):
        super()._on_state(msg)
        if not self.states or self.states[-1][1] != self.state["state"]:
            self.states.append((rospy.get_time(), self.state["state"]))

    def _on_in_reach(self, msg):
        self.in_reach_true += bool(msg.data)

    def _on_truth(self, msg):
        v = msg.twist.twist.linear
        self.speeds.append((msg.header.stamp.to_sec(), math.hypot(v.x, v.y)))

    def test_route_with_vision(self):
        report_file = rospy.get_param("~report_file")
        self.forget_old_report(report_file)
        n = sum(1 for line in open(rospy.get_param("~waypoints_file")) if line.strip() and not line.startswith("#"))
        s = self.wait_until_finished(480)
        self.assertEqual((s["succeeded"], s["aborted"], s["skipped"]), (n, 0, 0), f"summary {s}")
        self.assertGreater(len(self.corrections), 0, "move_base never applied a row-centring correction")
        self.assertTrue(all(math.isfinite(c) for c in self.corrections))
        self.assertGreater(self.in_reach_true, 0, "no boll detection node ever reported a boll in reach")
        halts = [(t, self.states[i + 1][0]) for i, (t, name) in enumerate(self.states[:-1]) if name == "halted"]
        names = [name for _, name in self.states]
        rospy.loginfo("check_vision_route: %d corrections, %d in-reach verdicts, halts %s, states %s",
                      len(self.corrections), self.in_reach_true, halts, names)
        self.assertGreater(len(halts), 0, f"the robot never halted at bolls (states {names})")
        self.assertEqual(s["halts"], len(halts), f"summary {s}")
        for i, name in enumerate(names[:-1]):
            if name == "halted":
                self.assertEqual(names[i + 1], "navigating", f"after a halt: {names}")
        for t0, t1 in halts:
            window = [v for t, v in self.speeds if t0 <= t <= t1]
            self.assertTrue(window, f"no ground truth during the halt {t0:.1f}..{t1:.1f} s")
            self.assertLess(min(window), STANDING_MPS, f"the robot never stood during the halt {t0:.1f}..{t1:.1f} s")
        report = self.wait_for_report(report_file)
        rospy.loginfo("check_vision_route: report %s", report)
        self.assertTrue(report["complete"])
        self.assertEqual(report["cr_percent"], 100.0)
        self.assertEqual(report["plant_contacts"], 0)
        self.assertEqual(report["navigator"]["halts"], len(halts))
        self.assertGreater(report["navigator"]["halt_time_s"], 0.0)


if __name__ == "__main__":
    rospy.init_node("check_vision_route")
    rostest.rosrun("cottonsim_experiments", "vision_route", VisionRouteTest)
