#!/usr/bin/env python3
"""rostest node: the harvest node on a standing robot beside one plant per side (harvest_node.test).

In order, on one simulator: a PickBoll goal for a point out of the arm's reach ends 'unreachable'; a pick
cancelled during its transit leaves the arm at rest and every boll on its plant; then automatic picking is
switched on and the node holds the route, picks the bolls in reach into the bin (the simulator's truth
says IN_BIN for each one the node reports picked) and the base touches no plant.
"""
import json
import threading
import time
import unittest

import actionlib
import numpy as np
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from cottonsim_msgs.msg import Boll, BollArray, BollTargetArray, PickBollAction, PickBollGoal, PlantContacts
from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String
from std_srvs.srv import SetBool

UNREACHABLE = ("unreachable", "ik_failed", "collision")      # the planner's verdicts: no motion from here
ARM = ["ur5e_shoulder_pan_joint", "ur5e_shoulder_lift_joint", "ur5e_elbow_joint", "ur5e_wrist_1_joint",
       "ur5e_wrist_2_joint", "ur5e_wrist_3_joint"]


class HarvestNodeTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.lock = threading.RLock()
        cls.status, cls.targets, cls.bolls, cls.joints = None, None, None, []
        cls.holds, cls.contact_events, cls.feedback = [], 0, []
        rospy.Subscriber("/harvest/status", String, cls._keep("status", json.loads), queue_size=10)
        rospy.Subscriber("/harvest/targets", BollTargetArray, cls._keep("targets"), queue_size=10)
        rospy.Subscriber("/sim/bolls", BollArray, cls._keep("bolls"), queue_size=10)
        rospy.Subscriber("/harvest/hold_route", Bool, cls._on_hold, queue_size=50)
        rospy.Subscriber("/joint_states", JointState, cls._on_joints, queue_size=50)
        rospy.Subscriber("/ground_truth/plant_contacts", PlantContacts, cls._on_contacts, queue_size=50)
        cls.pick = actionlib.SimpleActionClient("/harvest/pick", PickBollAction)
        assert cls.pick.wait_for_server(rospy.Duration(120.0)), "no /harvest/pick action server"

    @classmethod
    def _keep(cls, name, convert=lambda m: m):
        def callback(msg):
            with cls.lock:
                setattr(cls, name, convert(msg.data) if isinstance(msg, String) else convert(msg))
        return callback

    @classmethod
    def _on_hold(cls, msg):
        with cls.lock:
            cls.holds.append(bool(msg.data))

    @classmethod
    def _on_joints(cls, msg):
        index = [msg.name.index(j) for j in ARM]
        with cls.lock:
            cls.joints.append((msg.header.stamp.to_sec(), np.array([msg.velocity[i] for i in index])))

    @classmethod
    def _on_contacts(cls, msg):
        with cls.lock:
            cls.contact_events = max(cls.contact_events, msg.total_contact_events)

    def wait_for(self, what, condition, wall_timeout_s=120.0):
        """Poll condition() under the lock every 50 ms of wall time; fail naming `what` after the timeout."""
        deadline = time.monotonic() + wall_timeout_s
        while not rospy.is_shutdown() and time.monotonic() < deadline:
            with self.lock:
                if condition():
                    return
            rospy.rostime.wallsleep(0.05)
        self.fail("shut down" if rospy.is_shutdown() else f"timed out waiting for {what}")

    def on_plant(self):
        return sum(b.state == Boll.ON_PLANT for b in self.bolls.bolls)

    def test_harvest_through_the_ros_api(self):
        self.wait_for("confirmed targets in reach", lambda: self.status is not None and self.status["in_reach"]
                      and self.bolls is not None and self.targets is not None)
        total = len(self.bolls.bolls)
        self.assertEqual(self.on_plant(), total)

        # a point far out of reach (3 m ahead of the robot): unreachable, nothing moves
        far = PickBollGoal(target_id=-1, point=PointStamped())
        far.point.header.frame_id = "base_link"
        far.point.point.x, far.point.point.z = 3.0, 0.5
        self.pick.send_goal(far)
        self.assertTrue(self.pick.wait_for_result(rospy.Duration(60.0)))
        result = self.pick.get_result()
        self.assertEqual((result.success, result.reason), (False, "unreachable"), result.message)
        # a target id that does not exist: rejected with the reason
        self.pick.send_goal(PickBollGoal(target_id=99999))
        self.assertTrue(self.pick.wait_for_result(rospy.Duration(60.0)))
        self.assertEqual(self.pick.get_result().reason, "rejected")
        self.assertIn("no boll target 99999", self.pick.get_result().message)

        # a pick cancelled during its transit: the arm stops where it is, no boll leaves its plant
        with self.lock:
            in_reach = list(self.status["in_reach"])
        for target_id in in_reach:            # the nearest target whose approach can be planned
            phases = []
            self.pick.send_goal(PickBollGoal(target_id=target_id), feedback_cb=lambda f: phases.append(f.phase))
            self.wait_for("the pick's approach phase or its end", lambda: "approach" in phases or
                          self.pick.get_state() not in (GoalStatus.PENDING, GoalStatus.ACTIVE))
            if "approach" in phases:
                break
        self.assertIn("approach", phases, f"no target of {in_reach} could be planned")
        self.pick.cancel_goal()
        self.assertTrue(self.pick.wait_for_result(rospy.Duration(60.0)))
        self.assertEqual(self.pick.get_state(), GoalStatus.PREEMPTED)
        self.assertEqual(self.pick.get_result().reason, "cancelled")
        t_cancel = rospy.get_time()
        self.wait_for("1 s of sim time after the cancel", lambda: self.joints and self.joints[-1][0] > t_cancel + 1.0)
        with self.lock:
            after = [v for t, v in self.joints if t > t_cancel + 0.8]
        self.assertTrue(after and max(np.abs(v).max() for v in after) < 0.01, "the arm still moves after the cancel")
        self.assertEqual(self.on_plant(), total, "a boll left its plant in a cancelled pick")

        # automatic picking: the route is held, the bolls in reach go to the bin
        self.assertEqual(rospy.ServiceProxy("/harvest/enable", SetBool)(True).success, True)
        self.wait_for("a stop", lambda: self.status["stops"] >= 1, wall_timeout_s=60.0)
        self.wait_for("the harvest of every boll in reach", lambda: self.status["state"] == "idle"
                      and not self.status["in_reach"], wall_timeout_s=240.0)
        rospy.rostime.wallsleep(1.0)
        with self.lock:
            status, bolls, holds = dict(self.status), list(self.bolls.bolls), list(self.holds)
            targets = list(self.targets.targets)
        in_bin = sum(b.state == Boll.IN_BIN for b in bolls)
        dropped = sum(b.state == Boll.DROPPED for b in bolls)
        # reachable: a target the planner found a motion for from this stop (picked, or failed after planning)
        reachable = [t for t in targets if t.state == t.PICKED or (t.state == t.ABANDONED and t.last_result
                                                                   not in UNREACHABLE)]
        tried = status["targets"]["picked"] + status["targets"]["abandoned"]
        print(f"harvest: {status['picked']} picked of {len(reachable)} reachable targets ({tried} tried) in "
              f"{status['stops']} stops; "
              f"results {status['results']}; in the bin {in_bin}, dropped {dropped} of {total} bolls; "
              f"cycle time median {status['cycle_time_median_s']} s, p95 {status['cycle_time_p95_s']} s; "
              f"cycle times {status['cycle_times_s']}", flush=True)
        self.assertTrue(True in holds, "the route was never held")
        self.assertFalse(holds[-1], "the route is still held after the harvest")
        self.assertEqual(in_bin, status["picked"], "the bolls the node reports picked are not the bolls in the bin")
        self.assertEqual(dropped, 0)
        self.assertGreaterEqual(status["picked"], 0.9 * len(reachable), status["results"])
        self.assertGreaterEqual(status["picked"], 3)
        self.assertEqual(self.contact_events, 0, "the base touched a plant")


if __name__ == "__main__":
    rospy.init_node("check_harvest_node")
    rostest.rosrun("cottonsim_experiments", "harvest_node", HarvestNodeTest)
