"""ROS layer of move_base: the action server around the pure state machine.

The decisions live in ``cottonsim_navigation.move_base.state_machine.MoveBase``;
the costmaps are fed by ``move_base_costmaps.MoveBaseCostmaps``; this module
looks up TF and runs the control loop at ~controller_frequency inside the action server's
execute callback. See :class:`MoveBaseNode` for the ROS API.
"""
from __future__ import annotations

import math
import threading
from typing import Optional, Tuple

import actionlib
import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseActionGoal, MoveBaseFeedback, MoveBaseResult
from nav_msgs.msg import Odometry, Path
from nav_msgs.srv import GetPlan, GetPlanResponse
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Empty, EmptyResponse

from cottonsim_common.ros import conversions as conv
from cottonsim_common.ros.params import config_from_params, typed_param
from cottonsim_common.transforms import pose_matrix
from cottonsim_common.pose import Pose2D, compose
from cottonsim_common.transforms import yaw_to_quaternion
from cottonsim_navigation.move_base.config import MoveBaseConfig, VisionBiasConfig
from cottonsim_navigation.move_base.recovery import RotateRecoveryConfig
from cottonsim_navigation.move_base.state_machine import MoveBase, Outcome
from cottonsim_navigation.planning.base import make_global_planner, make_local_planner
from cottonsim_navigation.planning.global_planners.navfn import NavfnConfig
from cottonsim_navigation.planning.local_planners.dwa import DWAConfig
from cottonsim_navigation.ros.move_base_costmaps import MoveBaseCostmaps
from cottonsim_navigation.ros.move_base_messages import path_msg, pose_msg_is_valid, transform_to_pose2d



# ----------------------------------------------------------------- the node
class MoveBaseNode:
    """move_base: navfn + DWA + recoveries behind move_base's action interface.

    Action server
      move_base                 move_base_msgs/MoveBaseAction. Goals in any TF frame (transformed to
                                the global frame); feedback = robot pose in the global frame;
                                aborted with a text reason (goal invalid / in or next to an obstacle /
                                no plan or no valid trajectory after N recovery behaviours / oscillating);
                                a new goal preempts the running one.
    Subscriptions
      move_base_simple/goal     geometry_msgs/PoseStamped   forwarded to the action server
      ~map_topic (/map)         nav_msgs/OccupancyGrid      static layer of the global costmap (latched)
      ~local_costmap/obstacle_layer/point_cloud_topic (/passthrough/output)
                                sensor_msgs/PointCloud2     obstacles of the local costmap, and of the
                                                            global one when its plugins have an
                                                            obstacle_layer (any frame; moved with TF)
      ~odom_topic (/odometry/filtered) nav_msgs/Odometry    current velocity for the dynamic window
      ~vision_topic (husky/cv/coords) std_msgs/Float64MultiArray [linear_x, angular_z], only when
                                                            ~vision_bias is true
    Publications
      cmd_vel                   geometry_msgs/Twist         the base command (remap as needed)
      ~NavfnROS/plan            nav_msgs/Path               global plan (global frame)
      ~DWAPlannerROS/local_plan nav_msgs/Path               predicted trajectory of the command (local frame)
      ~global_costmap/costmap   nav_msgs/OccupancyGrid      latched, re-sent when it changes
      ~local_costmap/costmap    nav_msgs/OccupancyGrid      at ~local_costmap/publish_frequency (3 Hz)
      ~current_goal             geometry_msgs/PoseStamped   the goal in the global frame
      ~vision_correction        std_msgs/Float64            the row-centring angular_z [rad/s] added to the
                                                            command (before the +/- ~max_vision_rate clip),
                                                            in each control cycle where it changed the command
      move_base/goal            move_base_msgs/MoveBaseActionGoal (from move_base_simple/goal)
      move_base/status, /result, /feedback                  from actionlib
    Services
      ~make_plan                nav_msgs/GetPlan   plan on the global costmap (empty path if none; start
                                                   with an empty frame_id = the robot's pose;
                                                   tolerance <= 0 = NavfnROS/default_tolerance)
      ~clear_costmaps           std_srvs/Empty     forget every obstacle-layer cell
    Parameters (defaults = config/*.yaml = the original's values; see those files)
      ~controller_frequency 5.0 Hz, ~planner_frequency 0.0 Hz, ~planner_patience 5.0 s,
      ~controller_patience 15.0 s, ~max_planning_retries -1, ~oscillation_timeout 20.0 s,
      ~oscillation_distance 0.5 m, ~recovery_behavior_enabled true, ~clearing_rotation_allowed true,
      ~recovery_behaviours [conservative_reset, rotate_recovery, aggressive_reset, rotate_recovery],
      ~conservative_reset_dist 3.0 m, ~abort_on_blocked_goal true,
      ~base_global_planner navfn/NavfnROS, ~base_local_planner dwa_local_planner/DWAPlannerROS,
      ~NavfnROS/* (navfn.yaml), ~DWAPlannerROS/* (dwa.yaml; controller_frequency is move_base's),
      ~global_costmap/* and ~local_costmap/* (costmap_common.yaml + global/local_costmap.yaml:
      frames, size, resolution, footprint, plugins [static_layer, obstacle_layer, inflation_layer]
      and each layer's parameters; an obstacle_layer in ~global_costmap/plugins is updated at
      ~global_costmap/update_frequency over a window around the robot, see move_base_costmaps.py),
      ~rotate_recovery/* (RotateRecoveryConfig),
      ~use_static_map (true): wait for and use the map; false = the global costmap has its own
      configured geometry (width, height, origin_x/y) and no static layer,
      ~vision_bias (false), ~max_vision_rate (0.0873 rad/s = 5 deg/s), ~vision_max_age (0.5 s),
      ~vision_row_reach (1.0 m): the row-centring correction (see below).
    TF
      needs global_frame -> robot_base_frame (map -> base_link), local_frame -> robot_base_frame
      (odom -> base_link) and local_frame -> the cloud's frame.

    Vision correction: with ~vision_bias true, a row-centring estimate younger than
    ~vision_max_age is added to the local planner's angular velocity, clipped to
    +/- ~max_vision_rate, only while the global costmap shows obstacles within
    ~vision_row_reach on both sides of the robot (inside a crop row). move_base stays the only
    publisher of cmd_vel, so the correction and the planner never fight.

    Messages with NaN (clouds' points, odometry, vision estimates) are warned about and ignored.
    """

    def __init__(self):
        self.lock = threading.RLock()
        self.config = config_from_params(MoveBaseConfig, "~")
        self.use_static_map = typed_param("~use_static_map", True)
        vision = config_from_params(VisionBiasConfig, "~", overrides={
            "enabled": typed_param("~vision_bias", False),
            "max_vision_rate": typed_param("~max_vision_rate", VisionBiasConfig().max_vision_rate, minimum=0.0),
            "max_age_s": typed_param("~vision_max_age", VisionBiasConfig().max_age_s, minimum=0.0),
            "row_reach_m": typed_param("~vision_row_reach", VisionBiasConfig().row_reach_m, minimum=0.0)})
        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(10.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.costmaps = MoveBaseCostmaps(self.lock, self.tf_buffer, self.use_static_map, self._pose_in)
        self.global_costmap = self.costmaps.global_costmap
        self.local_costmap = self.costmaps.local_costmap
        self.global_frame = self.costmaps.global_frame
        self.local_frame = self.costmaps.local_frame
        self.base_frame = self.costmaps.base_frame
        navfn = config_from_params(NavfnConfig, "~NavfnROS/")
        dwa = config_from_params(DWAConfig, "~DWAPlannerROS/",
                                 overrides={"controller_frequency": self.config.controller_frequency})
        rotate = config_from_params(RotateRecoveryConfig, "~rotate_recovery/", overrides={
            "max_rotational_vel": dwa.max_rot_vel, "min_in_place_rotational_vel": dwa.min_rot_vel,
            "acc_lim_th": dwa.acc_lim_theta})
        self.core = MoveBase(self.config, self.global_costmap, self.local_costmap,
                             make_global_planner(self.config.base_global_planner, navfn),
                             make_local_planner(self.config.base_local_planner, dwa),
                             vision=vision, rotate=rotate)
        self._velocity = (0.0, 0.0)
        self._vision: Optional[Tuple[float, float]] = None      # (angular_z, receive time s)

        self.cmd_pub = rospy.Publisher("cmd_vel", Twist, queue_size=1)
        self.plan_pub = rospy.Publisher("~NavfnROS/plan", Path, queue_size=1, latch=True)
        self.local_plan_pub = rospy.Publisher("~DWAPlannerROS/local_plan", Path, queue_size=1)
        self.goal_pub = rospy.Publisher("~current_goal", PoseStamped, queue_size=1, latch=True)
        self.vision_pub = rospy.Publisher("~vision_correction", Float64, queue_size=5)
        self.action_goal_pub = rospy.Publisher("move_base/goal", MoveBaseActionGoal, queue_size=1)

        self.costmaps.start()
        rospy.Subscriber(typed_param("~odom_topic", "/odometry/filtered"), Odometry, self._on_odom, queue_size=1)
        if vision.enabled:
            rospy.Subscriber(typed_param("~vision_topic", "husky/cv/coords"), Float64MultiArray,
                             self._on_vision, queue_size=1)
        rospy.Subscriber("move_base_simple/goal", PoseStamped, self._on_simple_goal, queue_size=1)
        rospy.Service("~make_plan", GetPlan, self._on_make_plan)
        rospy.Service("~clear_costmaps", Empty, self._on_clear_costmaps)

        self.server = actionlib.SimpleActionServer("move_base", MoveBaseAction, execute_cb=self._execute,
                                                   auto_start=False)
        self.server.start()
        rospy.loginfo("move_base: %s + %s, global frame %s, local frame %s, controller %.1f Hz, %d recoveries",
                      self.config.base_global_planner, self.config.base_local_planner, self.global_frame,
                      self.local_frame, self.config.controller_frequency, len(self.core.recoveries))

    # ------------------------------------------------------------- callbacks
    def _on_odom(self, msg: Odometry) -> None:
        v, w = msg.twist.twist.linear.x, msg.twist.twist.angular.z
        if not (math.isfinite(v) and math.isfinite(w)):
            rospy.logwarn_throttle(5.0, "move_base: odometry twist has NaN, ignored")
            return
        self._velocity = (v, w)

    def _on_vision(self, msg: Float64MultiArray) -> None:
        if len(msg.data) < 2 or not math.isfinite(msg.data[1]):
            rospy.logwarn_throttle(5.0, f"move_base: vision estimate {list(msg.data)} ignored "
                                        "(need finite [linear_x, angular_z])")
            return
        self._vision = (float(msg.data[1]), rospy.Time.now().to_sec())

    def _on_simple_goal(self, msg: PoseStamped) -> None:
        goal = MoveBaseActionGoal()
        goal.header.stamp = rospy.Time.now()
        goal.goal.target_pose = msg
        self.action_goal_pub.publish(goal)

    # ------------------------------------------------------------- TF
    def _pose_in(self, frame: str) -> Optional[Pose2D]:
        try:
            t = self.tf_buffer.lookup_transform(frame, self.base_frame, rospy.Time(0), rospy.Duration(0.1))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            rospy.logwarn_throttle(5.0, f"move_base: no robot pose in {frame}: {exc}")
            return None
        return transform_to_pose2d(t.transform)

    def _to_global(self, ps: PoseStamped) -> Tuple[Optional[Pose2D], str]:
        """A PoseStamped in any frame -> Pose2D in the global frame, or (None, reason)."""
        ok, reason = pose_msg_is_valid(ps.pose)
        if not ok:
            return None, reason
        frame = ps.header.frame_id.lstrip("/") or self.global_frame
        pose = Pose2D(ps.pose.position.x, ps.pose.position.y, conv.yaw_from_quaternion_msg(ps.pose.orientation))
        if frame == self.global_frame:
            return pose, ""
        try:
            t = self.tf_buffer.lookup_transform(self.global_frame, frame, rospy.Time(0), rospy.Duration(0.5))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            return None, f"cannot transform the goal from {frame} to {self.global_frame}: {exc}"
        return compose(transform_to_pose2d(t.transform), pose), ""

    # ------------------------------------------------------------- services
    def _on_make_plan(self, req) -> GetPlanResponse:
        resp = GetPlanResponse()
        resp.plan.header = conv.header(rospy.Time.now(), self.global_frame)
        if req.start.header.frame_id == "":
            start, reason = self._pose_in(self.global_frame), "no robot pose"
        else:
            start, reason = self._to_global(req.start)
        goal, greason = self._to_global(req.goal)
        if start is None or goal is None:
            rospy.logwarn(f"move_base: make_plan refused: {reason if start is None else greason}")
            return resp
        tol = float(req.tolerance) if math.isfinite(req.tolerance) and req.tolerance > 0 else None
        with self.lock:
            plan = self.core.make_plan(start, goal, tol)
        if not plan.ok:
            rospy.logwarn(f"move_base: make_plan found no path: {plan.reason}")
            return resp
        resp.plan = path_msg(plan.poses, self.global_frame, rospy.Time.now())
        return resp

    def _on_clear_costmaps(self, _req) -> EmptyResponse:
        with self.lock:
            self.core.clear_costmaps(None, None)
        rospy.loginfo("move_base: costmaps cleared")
        return EmptyResponse()

    # ------------------------------------------------------------- the action
    def _stop(self) -> None:
        self.cmd_pub.publish(Twist())

    def _start_goal(self, goal_msg) -> Optional[str]:
        """Hand a new action goal to the core; returns a reason when it is refused."""
        goal, reason = self._to_global(goal_msg.target_pose)
        if goal is None:
            return reason
        if not self.costmaps.map_received:
            return f"no map received on the map topic yet (use_static_map is true)"
        with self.lock:
            self.core.set_goal(goal, rospy.Time.now().to_sec())
        ps = PoseStamped()
        ps.header = conv.header(rospy.Time.now(), self.global_frame)
        ps.pose.position.x, ps.pose.position.y = goal.x_m, goal.y_m
        ps.pose.orientation = conv.quaternion_msg(yaw_to_quaternion(goal.yaw_rad))
        self.goal_pub.publish(ps)
        rospy.loginfo("move_base: new goal (%.2f, %.2f, %.2f rad) in %s", goal.x_m, goal.y_m, goal.yaw_rad,
                      self.global_frame)
        return None

    def _execute(self, goal_msg) -> None:
        refused = self._start_goal(goal_msg)
        if refused:
            rospy.logwarn(f"move_base: goal aborted: {refused}")
            self.server.set_aborted(MoveBaseResult(), text=refused)
            return
        rate = rospy.Rate(self.config.controller_frequency)
        try:
            while not rospy.is_shutdown():
                if self.server.is_preempt_requested():
                    if self.server.is_new_goal_available():
                        refused = self._start_goal(self.server.accept_new_goal())
                        if refused:
                            self._finish_aborted(refused)
                            return
                    else:
                        with self.lock:
                            self.core.cancel()
                        self._stop()
                        self.server.set_preempted(MoveBaseResult(), text="goal cancelled")
                        return
                if not self._cycle():
                    return
                rate.sleep()
        except rospy.ROSInterruptException:
            pass
        except rospy.ROSTimeMovedBackwardsException:
            self._finish_aborted("sim time moved backwards")
            return
        if self.server.is_active():
            self._finish_aborted("move_base is shutting down")

    def _finish_aborted(self, reason: str) -> None:
        with self.lock:
            self.core.cancel()
        self._stop()
        rospy.logwarn(f"move_base: goal aborted: {reason}")
        self.server.set_aborted(MoveBaseResult(), text=reason)

    def _cycle(self) -> bool:
        """One control cycle; False once the goal has ended."""
        gpose = self._pose_in(self.global_frame)
        lpose = self._pose_in(self.local_frame)
        if gpose is None or lpose is None:
            self._stop()
            return True
        now = rospy.Time.now()
        vision_w = vision_age = None
        if self._vision is not None:
            vision_w, vision_age = self._vision[0], now.to_sec() - self._vision[1]
        with self.lock:
            r = self.core.step(now.to_sec(), gpose, lpose, self._velocity, vision_w, vision_age)
        if r.new_plan is not None:
            self.plan_pub.publish(path_msg(r.new_plan.poses, self.global_frame, now))
        if r.outcome == Outcome.SUCCEEDED:
            self._stop()
            self.server.set_succeeded(MoveBaseResult(), text="goal reached")
            rospy.loginfo("move_base: goal reached")
            return False
        if r.outcome in (Outcome.ABORTED, Outcome.IDLE):
            self._finish_aborted(r.reason or "goal dropped")
            return False
        cmd = Twist()
        cmd.linear.x, cmd.angular.z = r.v_mps, r.w_radps
        self.cmd_pub.publish(cmd)
        if r.vision_applied:
            self.vision_pub.publish(Float64(data=vision_w))
        self.local_plan_pub.publish(path_msg(r.local_path, self.local_frame, now))
        fb = MoveBaseFeedback()
        fb.base_position.header = conv.header(now, self.global_frame)
        fb.base_position.pose.position.x, fb.base_position.pose.position.y = gpose.x_m, gpose.y_m
        fb.base_position.pose.orientation = conv.quaternion_msg(yaw_to_quaternion(gpose.yaw_rad))
        self.server.publish_feedback(fb)
        return True
