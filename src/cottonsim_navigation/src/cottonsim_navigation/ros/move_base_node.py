"""ROS layer of move_base: the action server around the pure state machine.

The decisions live in ``cottonsim_navigation.navigation.move_base.MoveBase``;
this module converts messages, looks up TF, keeps the two costmaps fed and
runs the control loop at ~controller_frequency inside the action server's
execute callback. See :class:`MoveBaseNode` for the ROS API.
"""
from __future__ import annotations

import math
import threading
from typing import Optional, Tuple

import actionlib
import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseActionGoal, MoveBaseFeedback, MoveBaseResult
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from nav_msgs.srv import GetPlan, GetPlanResponse
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Empty, EmptyResponse

from cottonsim_navigation.core import geometry as geo
from cottonsim_navigation.core.grid import GridSpec
from cottonsim_navigation.navigation.move_base import MoveBase, MoveBaseConfig, Outcome, VisionBiasConfig
from cottonsim_navigation.navigation.recovery import RotateRecoveryConfig
from cottonsim_navigation.planning.base import make_global_planner, make_local_planner
from cottonsim_navigation.planning.costmap import (Costmap2D, CostmapConfig, InflationLayer, InflationLayerConfig,
                                                   ObstacleLayer, ObstacleLayerConfig, StaticLayer,
                                                   StaticLayerConfig)
from cottonsim_navigation.planning.global_planners.navfn import NavfnConfig
from cottonsim_navigation.planning.local_planners.dwa import DWAConfig
from cottonsim_navigation.ros.params import config_from_params, typed_param
from cottonsim_world.ros import conversions as conv

_LAYER_CONFIGS = {"static_layer": StaticLayerConfig, "obstacle_layer": ObstacleLayerConfig,
                  "inflation_layer": InflationLayerConfig}


# ----------------------------------------------------------------- conversions
def transform_to_pose2d(t) -> geo.Pose2D:
    """geometry_msgs/Transform (planar part) -> Pose2D."""
    return geo.Pose2D(t.translation.x, t.translation.y, conv.yaw_from_quaternion_msg(t.rotation))


def transform_matrix(t) -> np.ndarray:
    """geometry_msgs/Transform -> 4 x 4 homogeneous matrix."""
    q = t.rotation
    x, y, z, w = q.x, q.y, q.z, q.w
    n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    m = np.eye(4)
    m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    m[:3, 3] = (t.translation.x, t.translation.y, t.translation.z)
    return m


def pose_msg_is_valid(pose) -> Tuple[bool, str]:
    """A goal pose must be finite with a non-zero quaternion."""
    p, q = pose.position, pose.orientation
    values = (p.x, p.y, p.z, q.x, q.y, q.z, q.w)
    if not all(math.isfinite(v) for v in values):
        return False, f"goal has a non-finite (NaN/inf) value: position ({p.x}, {p.y}, {p.z}), " \
                      f"orientation ({q.x}, {q.y}, {q.z}, {q.w})"
    if q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w < 1e-6:
        return False, "goal has a zero-length quaternion"
    return True, ""


def path_msg(poses: np.ndarray, frame_id: str, stamp) -> Path:
    msg = Path()
    msg.header = conv.header(stamp, frame_id)
    for x, y, yaw in np.asarray(poses, dtype=float).reshape(-1, 3):
        ps = PoseStamped()
        ps.header = msg.header
        ps.pose.position.x, ps.pose.position.y = float(x), float(y)
        ps.pose.orientation = conv.quaternion_msg(geo.yaw_to_quaternion(float(yaw)))
        msg.poses.append(ps)
    return msg


def costmap_msg(costmap: Costmap2D, frame_id: str, stamp) -> OccupancyGrid:
    spec = costmap.spec
    msg = OccupancyGrid()
    msg.header = conv.header(stamp, frame_id)
    msg.info.map_load_time = stamp
    msg.info.resolution = spec.resolution_m
    msg.info.width, msg.info.height = spec.width, spec.height
    msg.info.origin.position.x, msg.info.origin.position.y = spec.origin_x_m, spec.origin_y_m
    msg.info.origin.orientation.w = 1.0
    msg.data = costmap.to_occupancy().ravel().tolist()
    return msg


def occupancy_from_msg(msg: OccupancyGrid) -> Tuple[np.ndarray, GridSpec]:
    """nav_msgs/OccupancyGrid -> ((height, width) int16 values, GridSpec); ValueError on a bad map."""
    info = msg.info
    if info.width < 1 or info.height < 1 or len(msg.data) != info.width * info.height:
        raise ValueError(f"map is {info.width} x {info.height} cells but carries {len(msg.data)} values")
    o = info.origin.position
    spec = GridSpec(float(info.resolution), int(info.width), int(info.height), float(o.x), float(o.y))
    occ = np.asarray(msg.data, dtype=np.int16).reshape(info.height, info.width)
    return occ, spec


# ----------------------------------------------------------------- the node
class MoveBaseNode:
    """move_base: navfn + DWA + recoveries behind move_base's action interface.

    Action server
      move_base                 move_base_msgs/MoveBaseAction. Goals in any TF frame (transformed to
                                the global frame); feedback = robot pose in the global frame;
                                aborted with a text reason (goal invalid / in an obstacle / no plan or
                                no valid trajectory after N recovery behaviours / oscillating);
                                a new goal preempts the running one.
    Subscriptions
      move_base_simple/goal     geometry_msgs/PoseStamped   forwarded to the action server
      ~map_topic (/map)         nav_msgs/OccupancyGrid      static layer of the global costmap (latched)
      ~local_costmap/obstacle_layer/point_cloud_topic (/passthrough/output)
                                sensor_msgs/PointCloud2     obstacles of the local costmap (any frame;
                                                            transformed to the local frame with TF)
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
      ~controller_patience 15.0 s, ~max_planning_retries -1, ~oscillation_timeout 0.0 s,
      ~oscillation_distance 0.5 m, ~recovery_behavior_enabled true, ~clearing_rotation_allowed true,
      ~recovery_behaviours [conservative_reset, rotate_recovery, aggressive_reset, rotate_recovery],
      ~conservative_reset_dist 3.0 m, ~abort_on_blocked_goal true,
      ~base_global_planner navfn/NavfnROS, ~base_local_planner dwa_local_planner/DWAPlannerROS,
      ~NavfnROS/* (navfn.yaml), ~DWAPlannerROS/* (dwa.yaml; controller_frequency is move_base's),
      ~global_costmap/* and ~local_costmap/* (costmap_common.yaml + global/local_costmap.yaml:
      frames, size, resolution, footprint, plugins [static_layer, obstacle_layer, inflation_layer]
      and each layer's parameters), ~rotate_recovery/* (RotateRecoveryConfig),
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
        self.global_costmap = self._make_costmap("global_costmap", default_layers=("static_layer", "inflation_layer"))
        self.local_costmap = self._make_costmap("local_costmap", default_layers=("obstacle_layer", "inflation_layer"))
        self.global_frame = self.global_costmap.config.global_frame
        self.local_frame = self.local_costmap.config.global_frame
        self.base_frame = self.local_costmap.config.robot_base_frame
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
        self.map_received = not self.use_static_map
        self._cloud: Optional[Tuple[np.ndarray, np.ndarray]] = None
        self._velocity = (0.0, 0.0)
        self._vision: Optional[Tuple[float, float]] = None      # (angular_z, receive time s)
        self._global_dirty = True

        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(10.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.cmd_pub = rospy.Publisher("cmd_vel", Twist, queue_size=1)
        self.plan_pub = rospy.Publisher("~NavfnROS/plan", Path, queue_size=1, latch=True)
        self.local_plan_pub = rospy.Publisher("~DWAPlannerROS/local_plan", Path, queue_size=1)
        self.global_cm_pub = rospy.Publisher("~global_costmap/costmap", OccupancyGrid, queue_size=1, latch=True)
        self.local_cm_pub = rospy.Publisher("~local_costmap/costmap", OccupancyGrid, queue_size=1)
        self.goal_pub = rospy.Publisher("~current_goal", PoseStamped, queue_size=1, latch=True)
        self.vision_pub = rospy.Publisher("~vision_correction", Float64, queue_size=5)
        self.action_goal_pub = rospy.Publisher("move_base/goal", MoveBaseActionGoal, queue_size=1)

        if self.use_static_map:
            rospy.Subscriber(typed_param("~map_topic", "/map"), OccupancyGrid, self._on_map, queue_size=1)
        if self.local_costmap.obstacle_layer is not None:
            topic = typed_param("~local_costmap/obstacle_layer/point_cloud_topic", "/passthrough/output")
            rospy.Subscriber(topic, PointCloud2, self._on_cloud, queue_size=1, buff_size=2 ** 24)
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
        lc = self.local_costmap.config
        rospy.Timer(rospy.Duration(1.0 / max(lc.update_frequency, 0.1)), self._update_local_costmap)
        rospy.Timer(rospy.Duration(1.0 / max(lc.publish_frequency, 0.1)), self._publish_costmaps)
        rospy.loginfo("move_base: %s + %s, global frame %s, local frame %s, controller %.1f Hz, %d recoveries",
                      self.config.base_global_planner, self.config.base_local_planner, self.global_frame,
                      self.local_frame, self.config.controller_frequency, len(self.core.recoveries))

    # ------------------------------------------------------------- setup helpers
    def _make_costmap(self, ns: str, default_layers) -> Costmap2D:
        config = config_from_params(CostmapConfig, f"~{ns}/")
        plugins = typed_param(f"~{ns}/plugins", tuple(default_layers))
        layers = []
        for name in plugins:
            if name not in _LAYER_CONFIGS:
                raise ValueError(f"parameter ~{ns}/plugins: unknown layer {name!r}; known: "
                                 f"{', '.join(_LAYER_CONFIGS)}")
            if name == "static_layer" and not self.use_static_map:
                continue
            layer_config = config_from_params(_LAYER_CONFIGS[name], f"~{ns}/{name}/")
            layers.append({"static_layer": StaticLayer, "obstacle_layer": ObstacleLayer,
                           "inflation_layer": InflationLayer}[name](layer_config))
        return Costmap2D(config, layers)

    # ------------------------------------------------------------- callbacks
    def _on_map(self, msg: OccupancyGrid) -> None:
        try:
            occ, spec = occupancy_from_msg(msg)
        except ValueError as exc:
            rospy.logwarn("move_base: ignoring map: %s", exc)
            return
        if msg.header.frame_id and msg.header.frame_id.lstrip("/") != self.global_frame:
            rospy.logwarn("move_base: map is in frame %s, the global costmap in %s; using it as %s",
                          msg.header.frame_id, self.global_frame, self.global_frame)
        with self.lock:
            cm = self.global_costmap
            if not cm.config.rolling_window:
                cm.resize(spec)
            cm.static_layer.set_map(occ, spec, track_unknown_space=cm.config.track_unknown_space)
            cm.update_map(geo.Pose2D(*spec.map_to_world(0, 0), 0.0))
            self.map_received = True
            self._global_dirty = True
        rospy.loginfo("move_base: static map %d x %d cells at %.3f m", spec.width, spec.height, spec.resolution_m)

    def _on_cloud(self, msg: PointCloud2) -> None:
        try:
            xyz = conv.cloud_to_xyz(msg, skip_nans=True)
            t = self.tf_buffer.lookup_transform(self.local_frame, msg.header.frame_id, msg.header.stamp,
                                                rospy.Duration(0.2)).transform
        except ValueError as exc:
            rospy.logwarn_throttle(5.0, f"move_base: ignoring cloud: {exc}")
            return
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            rospy.logwarn_throttle(5.0, f"move_base: no TF for the cloud: {exc}")
            return
        m = transform_matrix(t)
        pts = xyz.astype(float) @ m[:3, :3].T + m[:3, 3]
        with self.lock:
            self._cloud = (pts, m[:3, 3].copy())

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
    def _pose_in(self, frame: str) -> Optional[geo.Pose2D]:
        try:
            t = self.tf_buffer.lookup_transform(frame, self.base_frame, rospy.Time(0), rospy.Duration(0.1))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            rospy.logwarn_throttle(5.0, f"move_base: no robot pose in {frame}: {exc}")
            return None
        return transform_to_pose2d(t.transform)

    def _to_global(self, ps: PoseStamped) -> Tuple[Optional[geo.Pose2D], str]:
        """A PoseStamped in any frame -> Pose2D in the global frame, or (None, reason)."""
        ok, reason = pose_msg_is_valid(ps.pose)
        if not ok:
            return None, reason
        frame = ps.header.frame_id.lstrip("/") or self.global_frame
        pose = geo.Pose2D(ps.pose.position.x, ps.pose.position.y, conv.yaw_from_quaternion_msg(ps.pose.orientation))
        if frame == self.global_frame:
            return pose, ""
        try:
            t = self.tf_buffer.lookup_transform(self.global_frame, frame, rospy.Time(0), rospy.Duration(0.5))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            return None, f"cannot transform the goal from {frame} to {self.global_frame}: {exc}"
        return geo.compose(transform_to_pose2d(t.transform), pose), ""

    # ------------------------------------------------------------- costmaps
    def _update_local_costmap(self, _event=None) -> None:
        pose = self._pose_in(self.local_frame)
        if pose is None:
            return
        with self.lock:
            if self._cloud is not None and self.local_costmap.obstacle_layer is not None:
                self.local_costmap.obstacle_layer.add_observation(*self._cloud)
                self._cloud = None
            self.local_costmap.update_map(pose)
            if self.global_costmap.obstacle_layer is not None:
                gpose = self._pose_in(self.global_frame)
                if gpose is not None:
                    self.global_costmap.update_map(gpose)
                    self._global_dirty = True

    def _publish_costmaps(self, _event=None) -> None:
        stamp = rospy.Time.now()
        with self.lock:
            if self._global_dirty and self.map_received:
                self.global_cm_pub.publish(costmap_msg(self.global_costmap, self.global_frame, stamp))
                self._global_dirty = False
            if self.local_cm_pub.get_num_connections() > 0:
                self.local_cm_pub.publish(costmap_msg(self.local_costmap, self.local_frame, stamp))

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
        if not self.map_received:
            return f"no map received on the map topic yet (use_static_map is true)"
        with self.lock:
            self.core.set_goal(goal, rospy.Time.now().to_sec())
        ps = PoseStamped()
        ps.header = conv.header(rospy.Time.now(), self.global_frame)
        ps.pose.position.x, ps.pose.position.y = goal.x_m, goal.y_m
        ps.pose.orientation = conv.quaternion_msg(geo.yaw_to_quaternion(goal.yaw_rad))
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
        fb.base_position.pose.orientation = conv.quaternion_msg(geo.yaw_to_quaternion(gpose.yaw_rad))
        self.server.publish_feedback(fb)
        return True


def main():
    rospy.init_node("move_base")
    try:
        MoveBaseNode()
    except ValueError as exc:
        rospy.logfatal(f"move_base: {exc}")
        raise SystemExit(2)
    rospy.spin()
