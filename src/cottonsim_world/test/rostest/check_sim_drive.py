#!/usr/bin/env python3
"""rostest node: straight-line accuracy of the drive and plant-contact counting."""
import math
import unittest

import rospy
import rostest
from cottonsim_msgs.msg import PlantContacts
from cottonsim_msgs.srv import SetRobotPose
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from cottonsim_common.ros.conversions import yaw_from_quaternion_msg
from cottonsim_common.ros.testing import wait_until

ARM_JOINTS = ["ur5e_shoulder_pan_joint", "ur5e_shoulder_lift_joint", "ur5e_elbow_joint",
              "ur5e_wrist_1_joint", "ur5e_wrist_2_joint", "ur5e_wrist_3_joint"]


class SimDriveTest(unittest.TestCase):
    def setUp(self):
        self.truth = None
        self.odom = None
        self.contacts = None
        rospy.Subscriber("/ground_truth/odom", Odometry, lambda m: setattr(self, "truth", m))
        rospy.Subscriber("/odometry/filtered", Odometry, lambda m: setattr(self, "odom", m))
        rospy.Subscriber("/ground_truth/plant_contacts", PlantContacts, lambda m: setattr(self, "contacts", m))
        self.cmd = rospy.Publisher("/cmd_vel", Twist, queue_size=1)
        self.assertTrue(wait_until(lambda: self.truth is not None and self.odom is not None, 60.0),
                        "no /ground_truth/odom or /odometry/filtered within 60 s (wall)")

    def drive(self, v, w, duration_s, until_travelled_m=None):
        """Publish a constant command for duration_s of sim time, or until the truth moved far enough."""
        x0, y0, _ = self.pose(self.truth)
        end = rospy.Time.now() + rospy.Duration(duration_s)
        msg = Twist()
        msg.linear.x, msg.angular.z = v, w
        speeds = []
        while rospy.Time.now() < end and not rospy.is_shutdown():
            x, y, _ = self.pose(self.truth)
            travelled = math.hypot(x - x0, y - y0)
            if until_travelled_m is not None and travelled >= until_travelled_m:
                break
            if 1.0 < travelled < until_travelled_m - 1.0 if until_travelled_m else False:
                speeds.append(self.truth.twist.twist.linear.x)
            self.cmd.publish(msg)
            rospy.sleep(0.02)
        self.cmd.publish(Twist())
        rospy.sleep(1.0)
        return speeds

    def test_arm_follows_joint_commands_within_limits(self):
        states = []
        rospy.Subscriber("/joint_states", JointState, states.append, queue_size=500)
        arm = rospy.Publisher("/arm_controller/command", JointTrajectory, queue_size=1, latch=True)
        target = [0.5, -1.8, 2.0, -1.5, -1.57, 7.0]          # wrist 3 beyond its +2 pi limit
        arm.publish(JointTrajectory(joint_names=ARM_JOINTS,
                                    points=[JointTrajectoryPoint(positions=target)]))
        rospy.sleep(3.0)
        last = states[-1]
        pos = dict(zip(last.name, last.position))
        for joint, want in zip(ARM_JOINTS[:5], target[:5]):
            self.assertAlmostEqual(pos[joint], want, delta=1e-3, msg=joint)
        self.assertAlmostEqual(pos["ur5e_wrist_3_joint"], 2 * math.pi, delta=1e-3, msg="not clamped to the limit")
        speeds = [abs(v) for m in states for n, v in zip(m.name, m.velocity) if n in ARM_JOINTS]
        self.assertLessEqual(max(speeds), math.pi + 1e-6, "a joint moved faster than its velocity limit")
        self.assertGreater(max(speeds), 0.5 * math.pi, "the arm did not move at speed")

    @staticmethod
    def pose(odom):
        p = odom.pose.pose
        return p.position.x, p.position.y, yaw_from_quaternion_msg(p.orientation)

    def test_straight_then_into_a_row(self):
        x0, y0, th0 = self.pose(self.truth)
        ox0, oy0, _ = self.pose(self.odom)
        speeds = self.drive(0.5, 0.0, 30.0, until_travelled_m=5.0)
        x1, y1, th1 = self.pose(self.truth)
        ox1, oy1, _ = self.pose(self.odom)
        travelled = math.hypot(x1 - x0, y1 - y0)
        # (the test node stops the robot a little late when the sim runs faster than real time)
        self.assertTrue(5.0 <= travelled < 5.5, f"travelled {travelled:.3f} m")
        # the controller holds the commanded speed while cruising
        self.assertTrue(speeds)
        mean_speed = sum(speeds) / len(speeds)
        self.assertAlmostEqual(mean_speed, 0.5, delta=0.03, msg=f"cruise speed {mean_speed:.3f} m/s")
        # straight: the truth stays on the start heading's line
        lateral = -(x1 - x0) * math.sin(th0) + (y1 - y0) * math.cos(th0)
        self.assertLess(abs(lateral), 0.05, f"lateral drift {lateral:.3f} m")
        # the robot's own estimate (/odometry/filtered) ends within 5 cm of the truth
        odom_travelled = math.hypot(ox1 - ox0, oy1 - oy0)
        self.assertAlmostEqual(odom_travelled, travelled, delta=0.05,
                               msg=f"odometry {odom_travelled:.3f} m vs truth {travelled:.3f} m")
        self.assertEqual(self.contacts.total_contact_events, 0, "contacts on the open field")
        # From Home (-6, 1) heading north, row 2's plants stand ahead (x ~ -5.93, from y ~ 8.95).
        self.drive(0.8, 0.0, 6.0)
        rospy.sleep(0.5)
        self.assertGreater(self.contacts.total_contact_events, 0, "driving into a row registered no contact")
        self.assertTrue(self.contacts.plants_touched)
        rows = {pid // 20 for pid in self.contacts.plants_touched}
        self.assertEqual(rows, {2}, f"touched plants of rows {rows}")

    def test_teleport_moves_the_truth_not_the_odometry(self):
        # (runs after test_straight_then_into_a_row: unittest orders by name)
        rospy.wait_for_service("/sim/set_robot_pose", 30.0)
        teleport = rospy.ServiceProxy("/sim/set_robot_pose", SetRobotPose)
        rospy.sleep(0.5)
        ox0, oy0, _ = self.pose(self.odom)
        resp = teleport(-8.0, -1.0, 0.3)              # the open field south-east of Home, 3 m from it
        self.assertTrue(resp.success, resp.message)
        rospy.sleep(1.0)
        x, y, th = self.pose(self.truth)
        self.assertAlmostEqual(x, -8.0, delta=0.03)
        self.assertAlmostEqual(y, -1.0, delta=0.03)
        self.assertAlmostEqual(th, 0.3, delta=0.03)
        ox1, oy1, _ = self.pose(self.odom)
        self.assertLess(math.hypot(ox1 - ox0, oy1 - oy0), 0.03, "odometry saw the teleport")
        bad = teleport(float("nan"), 0.0, 0.0)
        self.assertFalse(bad.success)
        self.assertIn("finite", bad.message)
        x2, y2, _ = self.pose(self.truth)
        self.assertLess(math.hypot(x2 - x, y2 - y), 0.01, "a refused teleport moved the robot")


if __name__ == "__main__":
    rospy.init_node("check_sim_drive")
    rostest.rosrun("cottonsim_world", "sim_drive", SimDriveTest)
