#!/usr/bin/env python3
"""rostest node: the arm's FollowJointTrajectory action and vacuum service on sim_bridge.

Client code as for a real UR (control_msgs' action, actionlib's SimpleActionClient): only the import differs.
"""
import math
import threading
import unittest

import actionlib
import numpy as np
import rospy
import rostest
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from cottonsim_msgs.msg import FollowJointTrajectoryAction, FollowJointTrajectoryGoal, FollowJointTrajectoryResult
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool
from std_srvs.srv import SetBool
from trajectory_msgs.msg import JointTrajectoryPoint

from cottonsim_common.kinematics.ur5e import inverse_kinematics
from cottonsim_manipulation.planning.approach import tool_rotations
from cottonsim_msgs.srv import SetRobotPose
from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.robot.urdf_model import UrdfModel
from cottonsim_world.robot.vacuum import VacuumConfig
from cottonsim_common.transforms import pose_matrix
from nav_msgs.msg import Odometry

ARM = ["ur5e_shoulder_pan_joint", "ur5e_shoulder_lift_joint", "ur5e_elbow_joint", "ur5e_wrist_1_joint",
       "ur5e_wrist_2_joint", "ur5e_wrist_3_joint"]
MOVE = np.array([0.6, 0.3, -0.4, 0.2, 0.3, -0.5])      # a move from wherever the arm is [rad]


class ArmTrajectoryActionTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.lock = threading.Lock()
        cls.states = []             # (sim time, positions, velocities) of the arm
        rospy.Subscriber("/joint_states", JointState, cls._on_joints, queue_size=50)
        cls.client = actionlib.SimpleActionClient("/arm_controller/follow_joint_trajectory",
                                                  FollowJointTrajectoryAction)
        assert cls.client.wait_for_server(rospy.Duration(120.0)), "no /arm_controller/follow_joint_trajectory"
        deadline = rospy.Time.now() + rospy.Duration(60.0)
        while not cls.states and rospy.Time.now() < deadline:
            rospy.sleep(0.1)

    @classmethod
    def _on_joints(cls, msg):
        index = [msg.name.index(j) for j in ARM]
        with cls.lock:
            cls.states.append((msg.header.stamp.to_sec(), np.array([msg.position[i] for i in index]),
                               np.array([msg.velocity[i] for i in index])))

    def current(self):
        with self.lock:
            return self.states[-1]

    def states_between(self, t0, t1):
        with self.lock:
            return [s for s in self.states if t0 <= s[0] <= t1]

    def goal(self, positions, time_s, names=ARM, velocities=None):
        g = FollowJointTrajectoryGoal()
        g.trajectory.joint_names = list(names)
        point = JointTrajectoryPoint(positions=list(positions), time_from_start=rospy.Duration(time_s))
        if velocities is not None:
            point.velocities = list(velocities)
        g.trajectory.points = [point]
        return g

    def test_a_valid_goal_is_tracked_to_its_goal_within_tolerance(self):
        start = self.current()[1]
        target = start + MOVE
        feedback = []
        self.client.send_goal(self.goal(target, 2.0, velocities=[0.0] * 6), feedback_cb=feedback.append)
        self.assertTrue(self.client.wait_for_result(rospy.Duration(30.0)))
        self.assertEqual(self.client.get_state(), GoalStatus.SUCCEEDED, self.client.get_goal_status_text())
        self.assertEqual(self.client.get_result().error_code, FollowJointTrajectoryResult.SUCCESSFUL)
        rospy.sleep(0.2)
        t_end, q_end, _ = self.current()
        self.assertLess(np.max(np.abs(q_end - target)), 0.01)
        # tracked, not teleported: the joint states on the way lie between start and target
        path = self.states_between(t_end - 2.0, t_end)
        mids = [q for _, q, _ in path if 0.2 < np.min((q - start) / MOVE) and np.max((q - start) / MOVE) < 0.8]
        self.assertGreater(len(mids), 10)
        self.assertTrue(all(np.max(np.abs(v)) <= math.pi + 1e-6 for _, _, v in path))
        # feedback at ~50 Hz of sim time, desired - actual = error
        stamps = np.array([f.header.stamp.to_sec() for f in feedback])
        self.assertGreater(len(feedback), 40)
        self.assertAlmostEqual(float(np.median(np.diff(stamps))), 0.02, delta=0.006)
        last = feedback[-1]
        self.assertEqual(list(last.joint_names), ARM)
        self.assertTrue(np.allclose(np.array(last.desired.positions) - last.actual.positions, last.error.positions))

    def test_bad_goals_are_rejected_with_their_reason(self):
        q = self.current()[1]
        bad = [
            (self.goal(q + [0, 0, math.nan, 0, 0, 0], 1.0), FollowJointTrajectoryResult.INVALID_GOAL,
             "ur5e_elbow_joint is nan"),
            (self.goal(q, 1.0, names=ARM[:5] + ["gripper_joint"]), FollowJointTrajectoryResult.INVALID_JOINTS,
             "unknown joints ['gripper_joint']"),
            (self.goal(np.where(np.arange(6) == 2, 4.0, q), 10.0), FollowJointTrajectoryResult.INVALID_GOAL,
             "ur5e_elbow_joint = 4 rad is outside its limits"),
            (self.goal(q, 1.0, names=ARM[:5]), FollowJointTrajectoryResult.INVALID_JOINTS, "lacks joints"),
            (self.goal(q + [1.0, 0, 0, 0, 0, 0], 0.1), FollowJointTrajectoryResult.INVALID_GOAL,
             "ur5e_shoulder_pan_joint must move 10 rad/s on average"),
        ]
        two_points = self.goal(q, 1.0)
        two_points.trajectory.points.append(JointTrajectoryPoint(positions=list(q), time_from_start=rospy.Duration(1)))
        bad.append((two_points, FollowJointTrajectoryResult.INVALID_GOAL, "times must increase"))
        for goal, code, words in bad:
            self.client.send_goal(goal)
            self.assertTrue(self.client.wait_for_result(rospy.Duration(30.0)))
            self.assertEqual(self.client.get_state(), GoalStatus.REJECTED, words)
            result = self.client.get_result()
            self.assertEqual(result.error_code, code, result.error_string)
            self.assertIn(words, result.error_string)
            self.assertIn(words, self.client.get_goal_status_text())
        rospy.sleep(0.2)
        self.assertLess(np.max(np.abs(self.current()[1] - q)), 1e-3)      # the arm did not move (it may settle)

    def test_a_cancelled_goal_leaves_the_arm_stopped_where_it_was(self):
        start = self.current()[1]
        target = start - MOVE
        self.client.send_goal(self.goal(target, 3.0, velocities=[0.0] * 6))
        rospy.sleep(1.5)
        moving = self.current()
        self.assertGreater(np.max(np.abs(moving[2])), 0.1)
        self.client.cancel_goal()
        self.assertTrue(self.client.wait_for_result(rospy.Duration(30.0)))
        self.assertEqual(self.client.get_state(), GoalStatus.PREEMPTED, self.client.get_goal_status_text())
        t_stop = self.current()[0]
        rospy.sleep(1.0)
        after = self.states_between(t_stop + 0.05, t_stop + 1.0)
        self.assertGreater(len(after), 20)
        q_rest = after[0][1]
        for _, q, v in after:
            self.assertLess(np.max(np.abs(v)), 1e-3)
            self.assertLess(np.max(np.abs(q - q_rest)), 1e-3)
        self.assertLess(np.max(np.abs(q_rest - moving[1])), 0.3)             # near where it was cancelled
        self.assertGreater(np.max(np.abs(q_rest - target)), 0.2)              # not at the goal

    def _tip_pose(self, position, z_axis):
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = tool_rotations(np.asarray(z_axis, dtype=float), np.zeros(1))[0], position
        return pose

    def _joints_for(self, world_T_base, world_T_tip, reference):
        """Joints that put the nozzle tip at world_T_tip (IK of the flange pose), or None."""
        arm_T_tool0 = np.linalg.inv(world_T_base @ self.base_T_arm) @ world_T_tip @ np.linalg.inv(self.tool0_T_tip)
        result = inverse_kinematics(arm_T_tool0, reference)
        return result.best if result.ok and abs(result.best[2]) < 3.0 else None

    def test_picking_a_boll_through_the_ros_api(self):
        """Beside a plant: a goal puts the nozzle on a boll (the truth), the vacuum takes it, a goal to the bin,
        vacuum off: into the bin."""
        urdf = UrdfModel.from_string(rospy.get_param("/robot_description"))
        self.base_T_arm = urdf.fixed_transform("base_link", "ur5e_base")
        self.tool0_T_tip = urdf.fixed_transform("ur5e_tool0", "ur5e_nozzle_tip")
        farm = generate_farm(simulator_config_from_dict(rospy.get_param("/sim_bridge/sim")).farm)
        lane = farm.lanes[0]
        plant = min((p for p in farm.plants if len(p.model.boll_centres)),
                    key=lambda p: (abs(p.x_m - lane.x_m), abs(p.y_m - 0.5 * (lane.y_start_m + lane.y_end_m))))
        teleport = rospy.ServiceProxy("/sim/set_robot_pose", SetRobotPose)
        self.assertTrue(teleport(lane.x_m, plant.y_m - 0.345, math.pi / 2).success)   # arm base beside the stem
        rospy.sleep(0.5)
        odom = rospy.wait_for_message("/ground_truth/odom", Odometry, 10.0)
        p, o = odom.pose.pose.position, odom.pose.pose.orientation
        world_T_base = pose_matrix((p.x, p.y, p.z), (o.x, o.y, o.z, o.w))
        q_now = self.current()[1]
        picks = []
        for centre in plant.boll_centres_world():
            outward = centre - [plant.x_m, plant.y_m, centre[2]]
            q = self._joints_for(world_T_base, self._tip_pose(centre, -outward), q_now)
            if q is not None:
                picks.append((np.max(np.abs(q - q_now)), q, centre))
        self.assertTrue(picks, "no boll of the plant is reachable")
        _, q_pick, centre = min(picks, key=lambda c: c[0])
        vacuum = rospy.ServiceProxy("/arm_controller/vacuum", SetBool)
        self.assertTrue(vacuum(True).success)
        duration = max(2.0, 2.0 * np.max(np.abs(q_pick - q_now)) / math.pi)
        self.client.send_goal(self.goal(q_pick, duration, velocities=[0.0] * 6))
        self.assertTrue(self.client.wait_for_result(rospy.Duration(60.0)))
        self.assertEqual(self.client.get_state(), GoalStatus.SUCCEEDED, self.client.get_goal_status_text())
        rospy.sleep(0.3)
        self.assertTrue(rospy.wait_for_message("/arm_controller/vacuum/holding", Bool, 5.0).data)
        bin_tip = world_T_base @ self._tip_pose(VacuumConfig().bin_centre_m, [0.0, 0.0, -1.0])
        q_bin = self._joints_for(world_T_base, bin_tip, q_pick)
        self.assertIsNotNone(q_bin)
        duration = max(2.0, 2.0 * np.max(np.abs(q_bin - q_pick)) / math.pi)
        self.client.send_goal(self.goal(q_bin, duration, velocities=[0.0] * 6))
        self.assertTrue(self.client.wait_for_result(rospy.Duration(60.0)))
        self.assertEqual(self.client.get_state(), GoalStatus.SUCCEEDED, self.client.get_goal_status_text())
        answer = vacuum(False)
        self.assertIn("into the bin", answer.message)
        rospy.sleep(0.3)
        self.assertFalse(rospy.wait_for_message("/arm_controller/vacuum/holding", Bool, 5.0).data)

    def test_the_nozzle_tip_frame_is_in_tf(self):
        buffer = tf2_ros.Buffer()
        tf2_ros.TransformListener(buffer)
        tip = buffer.lookup_transform("ur5e_tool0", "ur5e_nozzle_tip", rospy.Time(0), rospy.Duration(30.0))
        t = tip.transform.translation
        self.assertTrue(np.allclose([t.x, t.y, t.z], [0.0, 0.0, 0.15], atol=1e-9))
        buffer.lookup_transform("base_link", "ur5e_nozzle_tip", rospy.Time(0), rospy.Duration(30.0))

    def test_vacuum_service_switches_the_nozzle(self):
        holding = []
        rospy.Subscriber("/arm_controller/vacuum/holding", Bool, lambda m: holding.append(m.data))
        rospy.wait_for_service("/arm_controller/vacuum", 30.0)
        vacuum = rospy.ServiceProxy("/arm_controller/vacuum", SetBool)
        answer = vacuum(True)
        self.assertTrue(answer.success)
        self.assertIn("vacuum on", answer.message)
        # off with nothing held: it says so, and how close the tip came to an open boll while it was on
        self.assertRegex(vacuum(False).message,
                         r"^vacuum off(: nothing captured; the tip came within [0-9.]+ mm of boll \d+, .*)?$")
        rospy.sleep(0.5)
        self.assertEqual(holding, [False])          # the stowed nozzle is nowhere near a boll


if __name__ == "__main__":
    rospy.init_node("check_arm_trajectory_action")
    rostest.rosrun("cottonsim_world", "arm_trajectory_action", ArmTrajectoryActionTest)
