#!/usr/bin/env python3
"""rostest node of harvest_route.test: the route with the harvest on completes, the picked bolls are in the bin.

~report_file (str): the experiment recorder's report.json; ~harvest_file (str): the harvest recorder's harvest.json.
"""
import json
import os

import rospy
import rostest
from cottonsim_msgs.msg import Boll, BollArray
from std_msgs.msg import String

from cottonsim_experiments.harvest_run.outcomes import boll_outcomes
from navigator_watch import NavigatorWatch


class HarvestRouteTest(NavigatorWatch):
    STATE_TOPIC = "/gps_waypoint_navigator/state"

    def setUp(self):
        super().setUp()
        self.bolls = None
        self.status = None
        rospy.Subscriber("/sim/bolls", BollArray, lambda m: setattr(self, "bolls", m))
        rospy.Subscriber("/harvest/status", String, lambda m: setattr(self, "status", json.loads(m.data)))

    def test_route_with_the_harvest(self):
        report_file = rospy.get_param("~report_file")
        harvest_file = rospy.get_param("~harvest_file")
        self.forget_old_report(report_file)
        if os.path.exists(harvest_file):
            os.remove(harvest_file)
        s = self.wait_until_finished(360)
        self.assertEqual((s["aborted"], s["skipped"]), (0, 0), f"navigator {s}")
        self.assertGreaterEqual(s["route_holds"], 1, f"the harvest never held the route: {s}")
        self.assertEqual(s["state"], "finished", f"navigator {s}")
        report = self.wait_for_report(report_file)
        self.assertTrue(report["complete"], report.get("incomplete_reason"))
        self.assertEqual(report["plant_contacts"], 0)
        # the arm-stem contact events, split by plant part and by arm link, add up to their count
        self.assertEqual(sum(report["arm_stem_contacts_by_part"].values()), report["arm_stem_contacts"])
        self.assertEqual(sum(report["arm_stem_contacts_by_link"].values()), report["arm_stem_contacts"])
        self.assertLessEqual(set(report["arm_stem_contacts_by_part"]), {"stem", "branch"})
        # the truth: what the harvest node picked is in the bin; nothing dropped or left in the nozzle
        self.wait_for(lambda: self.bolls is not None and self.status is not None, 10.0, "/sim/bolls and status")
        states = [b.state for b in self.bolls.bolls]
        in_bin = states.count(Boll.IN_BIN)
        self.assertGreaterEqual(self.status["picked"], 2, f"harvest status {self.status}")
        self.assertEqual(in_bin, self.status["picked"], f"harvest status {self.status}")
        self.assertEqual(states.count(Boll.DROPPED) + states.count(Boll.HELD), 0)
        # the recorder's harvest.json tells the same, and every binned boll is matched to its picked target
        self.wait_for(lambda: os.path.isfile(harvest_file), 10.0, "harvest.json")
        with open(harvest_file, "r", encoding="utf-8") as fh:
            harvest = json.load(fh)
        self.assertEqual(sum(b["state"] == "in_bin" for b in harvest["bolls_end"]["bolls"]), in_bin)
        outcomes = boll_outcomes(harvest, reachable_ids=[])
        binned = [o for o in outcomes if o["in_bin"]]
        self.assertEqual(len(binned), in_bin)
        self.assertTrue(all(o["detected"] for o in binned), binned)
        self.assertEqual(len(harvest["status"]["cycle_times_s"]), in_bin, harvest["status"])
        self.assertTrue(any(o["cycle_time_s"] is not None for o in binned), binned)
        self.assertLess(max(o["localization_error_m"] for o in binned), 0.03, binned)


if __name__ == "__main__":
    rospy.init_node("check_harvest_route")
    rostest.rosrun("cottonsim_experiments", "harvest_route", HarvestRouteTest)
