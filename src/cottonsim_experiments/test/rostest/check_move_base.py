#!/usr/bin/env python3
"""rostest node for move_base: plans, aborts with reasons, and drives the simulated robot to a goal.

The node itself plays map_server and the localisation: it publishes the farm's
ground-truth occupancy map rasterised in the Home frame (origin = spawn pose,
so map == odom at the start) on /map, latched, and map -> odom = identity.
"""
import math
import time
import unittest

import actionlib
import numpy as np
import rospy
import rostest
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped, TransformStamped
from move_base_msgs.msg import MoveBaseAction, MoveBaseActionResult, MoveBaseGoal
from nav_msgs.msg import OccupancyGrid, Odometry
from nav_msgs.srv import GetPlan, GetPlanRequest

from cottonsim_common.pose import world_to_frame
from cottonsim_common.ros.conversions import occupancy_grid_msg
from cottonsim_common.ros.testing import wait_until
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.export import OccupancyMapConfig, rasterize_occupancy
from cottonsim_world.farm.generator import generate_farm

FARM = generate_farm(FarmConfig())
HOME = FARM.spawn


def pose_stamped(x, y, yaw, frame="map"):
    ps = PoseStamped()
    ps.header.frame_id = frame
    ps.header.stamp = rospy.Time.now()
    ps.pose.position.x, ps.pose.position.y = x, y
    ps.pose.orientation.z, ps.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return ps



class MoveBaseTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        grid, res, origin = rasterize_occupancy(FARM, OccupancyMapConfig(), frame=HOME)
        cls.grid, cls.res, cls.origin = grid, res, origin
        cls.map_pub = rospy.Publisher("/map", OccupancyGrid, queue_size=1, latch=True)
        cls.map_pub.publish(occupancy_grid_msg(grid, res, origin, "map", rospy.Time.now()))
        cls.tf_pub = tf2_ros.StaticTransformBroadcaster()
        t = TransformStamped()
        t.header.frame_id, t.child_frame_id = "map", "odom"
        t.transform.rotation.w = 1.0
        cls.tf_pub.sendTransform(t)
        cls.truth = None
        rospy.Subscriber("/ground_truth/odom", Odometry, lambda msg: setattr(cls, "truth", msg))
        cls.costmap = None
        rospy.Subscriber("/move_base/global_costmap/costmap", OccupancyGrid, lambda msg: setattr(cls, "costmap", msg))
        cls.client = actionlib.SimpleActionClient("move_base", MoveBaseAction)
        assert cls.client.wait_for_server(rospy.Duration(60.0)), "no move_base action server"
        rospy.wait_for_service("/move_base/make_plan", 30.0)
        assert wait_until(lambda: cls.costmap is not None and cls.truth is not None, 60.0), \
            "move_base never published its global costmap (map not received?)"

    def truth_in_home(self):
        p = self.truth.pose.pose.position
        x, y = world_to_frame(HOME, p.x, p.y)
        return float(x), float(y)

    def send(self, goal_ps, timeout_s):
        rospy.sleep(0.5)       # let the previous goal's last status pass before a new goal handle
        goal = MoveBaseGoal(target_pose=goal_ps)
        self.client.send_goal(goal)
        t0 = time.monotonic()
        finished = self.client.wait_for_result(rospy.Duration(timeout_s))
        return finished, self.client.get_state(), self.client.get_goal_status_text(), time.monotonic() - t0

    def test_1_make_plan_returns_a_path_to_a_reachable_goal(self):
        plan = rospy.ServiceProxy("/move_base/make_plan", GetPlan)
        req = GetPlanRequest(start=pose_stamped(0.0, 0.0, 0.0), goal=pose_stamped(4.0, 1.0, 0.0), tolerance=0.0)
        resp = plan(req)
        self.assertGreater(len(resp.plan.poses), 10)
        first, last = resp.plan.poses[0].pose.position, resp.plan.poses[-1].pose.position
        self.assertLess(math.hypot(first.x, first.y), 0.1)
        self.assertLess(math.hypot(last.x - 4.0, last.y - 1.0), 0.1)
        # the path is at least as long as the straight line and not much longer on the open field
        xy = np.array([[p.pose.position.x, p.pose.position.y] for p in resp.plan.poses])
        length = np.sum(np.hypot(*np.diff(xy, axis=0).T))
        self.assertTrue(math.hypot(4.0, 1.0) - 0.05 <= length <= 1.2 * math.hypot(4.0, 1.0), length)

    def test_2_goal_inside_a_plant_row_aborts_with_a_reason(self):
        plant = FARM.plants[45]                     # row 2, the row straight ahead of Home
        gx, gy = world_to_frame(HOME, plant.x_m, plant.y_m)
        ix = int((gx - self.origin[0]) / self.res)
        iy = int((gy - self.origin[1]) / self.res)
        self.assertEqual(self.grid[iy, ix], 100, "the chosen goal is not an occupied map cell")
        finished, state, text, took = self.send(pose_stamped(float(gx), float(gy), 0.0), 30.0)
        self.assertTrue(finished, "no result for a goal inside a plant row")
        self.assertEqual(state, GoalStatus.ABORTED, text)
        self.assertIn("obstacle", text)
        self.assertIn("cost 254", text)
        self.assertLess(took, 15.0)

    def test_2b_simple_goal_topic_is_forwarded_to_the_action_server(self):
        results = []
        sub = rospy.Subscriber("/move_base/result", MoveBaseActionResult, results.append)
        pub = rospy.Publisher("/move_base_simple/goal", PoseStamped, queue_size=1)
        self.assertTrue(wait_until(lambda: pub.get_num_connections() > 0 and sub.get_num_connections() > 0, 10.0))
        plant = FARM.plants[50]
        gx, gy = world_to_frame(HOME, plant.x_m, plant.y_m)
        pub.publish(pose_stamped(float(gx), float(gy), 0.0))
        self.assertTrue(wait_until(lambda: any("obstacle" in r.status.text for r in results), 15.0),
                        f"no aborted result for the simple goal: {[r.status.text for r in results]}")
        self.assertEqual([r.status.status for r in results if "obstacle" in r.status.text][0], GoalStatus.ABORTED)
        sub.unregister()
        pub.unregister()

    def test_3_nan_goal_is_rejected_with_a_reason(self):
        finished, state, text, _ = self.send(pose_stamped(float("nan"), 0.0, 0.0), 10.0)
        self.assertTrue(finished)
        self.assertEqual(state, GoalStatus.ABORTED)
        self.assertIn("NaN", text)

    def test_4_reaches_a_goal_ahead_and_to_the_side_of_home(self):
        x0, y0 = self.truth_in_home()
        self.assertLess(math.hypot(x0, y0), 0.1, "the robot is not at Home before the drive")
        # 4 m ahead, 1 m to the left of Home, given in base_link (= map at Home): the goal is transformed
        finished, state, text, took = self.send(pose_stamped(4.0, 1.0, 0.0, frame="base_link"), 150.0)
        self.assertTrue(finished, "move_base did not finish within 150 s")
        self.assertEqual(state, GoalStatus.SUCCEEDED, text)
        rospy.sleep(0.5)
        x, y = self.truth_in_home()
        err = math.hypot(x - 4.0, y - 1.0)
        rospy.loginfo("check_move_base: reached (%.3f, %.3f) in Home frame, error %.3f m, %.1f s wall",
                      x, y, err, took)
        self.assertLessEqual(err, 0.2, f"ground truth ({x:.3f}, {y:.3f}) is {err:.3f} m from the goal")


if __name__ == "__main__":
    rospy.init_node("check_move_base")
    rostest.rosrun("cottonsim_experiments", "move_base_check", MoveBaseTest)
