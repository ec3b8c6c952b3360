"""The harvest node: boll targets from the side cameras' detections, stops, picks with the arm's ROS API.

The decisions are harvest.harvester.Harvester's (targets, when to stop, pick
cycles, figures); this layer feeds it and carries out its commands.

Subscriptions
  ~detection_topics (cottonsim_msgs/BollDetections, default /boll_detection_left/detections and
      /boll_detection_right/detections; ~target_source 'detections'): the localised boll centres, moved into
      ~frame with TF at their stamps and fused into targets.
  /sim/bolls (cottonsim_msgs/BollArray) and /ground_truth/odom (nav_msgs/Odometry), only with
      ~target_source 'ground_truth' (a study option): the simulator's open bolls within ~truth_range_m of
      the robot are the detections, every loop cycle.
  /joint_states (sensor_msgs/JointState): the arm's joints (~joint_prefix + the UR5e joint names; ros.arm_client).
  ~odom_topic (nav_msgs/Odometry, /odometry/filtered): the robot stands when its speeds are small.
  /arm_controller/vacuum/holding (std_msgs/Bool): the nozzle holds a boll (confirms a capture).
Publications
  ~targets (cottonsim_msgs/BollTargetArray, latched): every target in ~frame, after a change, at most every
      ~targets_period_s (a farm's targets are thousands: each message carries them all).
  ~markers (visualization_msgs/MarkerArray, latched): the targets as 4 cm spheres for rviz, grey tentative,
      yellow confirmed, green picked, red abandoned.
  ~status (std_msgs/String, latched): JSON {"state": idle|parking|picking, "auto": bool, "phase": the pick
      cycle's phase or null, "target": id or null, "route_held": bool, "targets": {state: count},
      "in_reach": ids of the targets a stop would pick now (recently seen, in the arm's workspace, not
      failed to plan from about here), the nearest first,
      "results": {reason: count}, "picked", "attempted", "stops", "cycle_time_median_s",
      "cycle_time_p95_s", "cycle_times_s": [...]}, every ~status_period_s, after each pick result and when
      the state, phase or target changes.
  ~hold_topic (std_msgs/Bool, /harvest/hold_route): true every loop cycle while the route must stand
      (a stop), false once when it may go on (the navigator's route hold).
Action client / service client (ros.arm_client)
  /arm_controller/follow_joint_trajectory (cottonsim_msgs/FollowJointTrajectory), /arm_controller/vacuum
      (std_srvs/SetBool).
Action server
  ~pick (cottonsim_msgs/PickBoll): pick one target (by id) or a point; refused (reason 'rejected') while a
      pick runs or for a bad goal; cancel stops the arm where it is (reason 'cancelled').
Service
  ~enable (std_srvs/SetBool): automatic picking on / off (~auto_harvest at the start).
Parameters: config/harvest.yaml (each key with its unit and default).
Before a pick the arm goes to its ready pose (the bin pose, PickCycleConfig.bin_joints_rad) when it is
elsewhere. The obstacles of a plan are the robot's own body (from /robot_description) and the stems the
harvester estimates (~stem_obstacles); the robot does not perceive the plants themselves.
"""
from __future__ import annotations

import collections
import json
import math
import threading

import actionlib
import numpy as np
import rospy
import tf2_ros
from cottonsim_msgs.msg import (BollDetections, BollTarget, BollTargetArray, PickBollAction, PickBollFeedback,
                                PickBollResult)
from nav_msgs.msg import Odometry
from std_msgs.msg import Bool, ColorRGBA, String
from std_srvs.srv import SetBool, SetBoolResponse
from visualization_msgs.msg import Marker, MarkerArray

from cottonsim_common.kinematics.ur5e import JOINT_NAMES
from cottonsim_common.ros.conversions import transform_matrix
from cottonsim_common.ros.params import config_from_params, typed_param
from cottonsim_common.transforms import transform_points
from cottonsim_manipulation.harvest.harvester import HarvestConfig, Harvester
from cottonsim_manipulation.harvest.pick_cycle import (APPROACH, DELIVER, CancelTrajectory, CaptureConfirmed, HaltRoute,
                                                       PickCycleConfig, ResumeRoute, RobotStopped, SendTrajectory,
                                                       SetVacuum, TrajectoryFailed)
from cottonsim_manipulation.harvest.pick_order import PickOrderConfig
from cottonsim_manipulation.harvest.targets import TargetFusion, TargetFusionConfig
from cottonsim_manipulation.planning.approach import ApproachConfig, plan_approach
from cottonsim_common.kinematics.arm_capsules import ArmCollisionConfig
from cottonsim_manipulation.planning.collision import ArmCollisionModel
from cottonsim_manipulation.planning.robot_body import body_boxes_from_urdf
from cottonsim_manipulation.planning.trajectory import TrajectoryConfig, plan_trajectory
from cottonsim_manipulation.ros.arm_client import ArmClient
from cottonsim_manipulation.ros.truth_targets import TruthTargets

TARGET_SOURCES = ("detections", "ground_truth")
_TARGET_STATES = {"tentative": BollTarget.TENTATIVE, "confirmed": BollTarget.CONFIRMED,
                  "picked": BollTarget.PICKED, "abandoned": BollTarget.ABANDONED}
_MARKER_RGB = {"tentative": (0.6, 0.6, 0.6), "confirmed": (1.0, 0.8, 0.0), "picked": (0.1, 0.8, 0.1),
               "abandoned": (0.9, 0.1, 0.1)}
READY_TOLERANCE_RAD = 0.02                      # the arm is at its ready pose this close [rad]
WAKE_POLL_S = 0.005                             # between loop ticks, the loop looks this often (wall time) whether an
                                                # arm motion ended or the nozzle caught its boll, and then runs at
                                                # once: each of a pick's five phase changes waited half a loop
                                                # period (25 ms at 20 Hz) on average [s]
HOLD_PERIOD_S = 0.2                             # the route hold is sent this often, from a timer of its own
                                                # (a stop's planning holds the loop for longer than the
                                                # navigator's hold lasts: the robot drove off mid-stop) [s]


class HarvestNode:
    """See the module docstring."""

    def __init__(self):
        self.target_source = typed_param("~target_source", "detections")
        if self.target_source not in TARGET_SOURCES:
            raise ValueError(f"parameter ~target_source: must be one of {TARGET_SOURCES}, got {self.target_source!r}")
        self.frame = typed_param("~frame", "odom")
        self.robot_frame = typed_param("~robot_frame", "base_link")
        self.arm_base_frame = typed_param("~arm_base_frame", "ur5e_base")
        joint_names = [typed_param("~joint_prefix", "ur5e_") + j for j in JOINT_NAMES]
        self.loop_hz = typed_param("~loop_hz", 20.0, minimum=1.0)
        self.status_period_s = typed_param("~status_period_s", 1.0, minimum=0.05)
        self.targets_period_s = typed_param("~targets_period_s", 1.0, minimum=0.0)
        self.truth_range_m = typed_param("~truth_range_m", 1.5, minimum=0.1)
        self.odom_max_age_s = typed_param("~odom_max_age_s", 0.5, minimum=0.01)
        self.auto = typed_param("~auto_harvest", True)
        self.config = config_from_params(HarvestConfig, "~")
        fusion = TargetFusion(config_from_params(TargetFusionConfig, "~fusion/"))
        cycle = config_from_params(PickCycleConfig, "~cycle/")
        approach = config_from_params(ApproachConfig, "~approach/")
        self.trajectory_config = config_from_params(TrajectoryConfig, "~trajectory/")
        urdf = rospy.get_param("/robot_description", "")
        if not urdf:
            raise ValueError("no /robot_description: the arm's collision model needs the robot's body")
        model = ArmCollisionModel(config_from_params(ArmCollisionConfig, "~collision/"),
                                  body=body_boxes_from_urdf(urdf, arm_base_frame=self.arm_base_frame))
        self.harvester = Harvester(
            lambda p, n, q, stems: plan_approach(p, n, q, model, stems, approach, self.trajectory_config),
            self.config, fusion, cycle, config_from_params(PickOrderConfig, "~order/"), approach_config=approach,
            trajectory_config=self.trajectory_config, clock=rospy.get_time)
        self.ready_rad = np.asarray(cycle.bin_joints_rad, dtype=float)

        self._lock = threading.Lock()
        self._wake = threading.Event()           # set by the callbacks the pick cycle waits for
        self._detections = collections.deque()   # (points in ~frame (N, 3), stamp [s])
        self._requests = collections.deque()     # pick action requests (dicts)
        self._odom = None                        # (stamp [s], speed [m/s], yaw rate [rad/s])
        self._holding = False
        self._parking = False
        self._park_deadline_s = 0.0
        self._route_held = False
        self._request = None                     # the pick request being served
        self._cancel_request = False
        self._next_status_s = 0.0
        self._next_targets_s = 0.0
        self._targets_dirty = False
        self._published_activity = None          # (parking, picking, phase, target) of the last status
        self._logged = 0                         # pick results logged

        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.targets_pub = rospy.Publisher("~targets", BollTargetArray, queue_size=2, latch=True)
        self.markers_pub = rospy.Publisher("~markers", MarkerArray, queue_size=2, latch=True)
        self.status_pub = rospy.Publisher("~status", String, queue_size=2, latch=True)
        self.hold_pub = rospy.Publisher(typed_param("~hold_topic", "/harvest/hold_route"), Bool, queue_size=2)
        self._hold_timer = rospy.Timer(rospy.Duration(HOLD_PERIOD_S), self._publish_hold)
        self.arm = ArmClient(joint_names, self.trajectory_config, on_event=self._wake.set)
        rospy.Subscriber(typed_param("~odom_topic", "/odometry/filtered"), Odometry, self._on_odom, queue_size=5)
        rospy.Subscriber("/arm_controller/vacuum/holding", Bool, self._on_holding, queue_size=5)
        if self.target_source == "detections":
            topics = typed_param("~detection_topics", ("/boll_detection_left/detections",
                                                       "/boll_detection_right/detections"))
            for topic in topics:
                rospy.Subscriber(str(topic), BollDetections, self._on_detections, queue_size=5)
        else:
            rospy.logwarn("harvest: ground-truth targets from /sim/bolls (a study option, not the robot's view)")
            self.truth = TruthTargets(self.tf_buffer, self.frame, self.robot_frame, self.truth_range_m)
        self.server = actionlib.SimpleActionServer("~pick", PickBollAction, execute_cb=self._execute_pick,
                                                   auto_start=False)
        self.server.start()
        rospy.Service("~enable", SetBool, self._on_enable)

    # ------------------------------------------------------------------ callbacks (ROS threads)
    def _on_odom(self, msg: Odometry):
        v, w = msg.twist.twist.linear, msg.twist.twist.angular
        with self._lock:
            self._odom = (rospy.get_time(), math.hypot(v.x, v.y), abs(w.z))

    def _on_holding(self, msg: Bool):
        with self._lock:
            caught = bool(msg.data) and not self._holding
            self._holding = bool(msg.data)
        if caught:
            self._wake.set()

    def _on_detections(self, msg: BollDetections):
        points = [(d.position.x, d.position.y, d.position.z) for d in msg.detections if d.has_position]
        if not points:
            return
        try:
            tf = self.tf_buffer.lookup_transform(self.frame, msg.header.frame_id, msg.header.stamp,
                                                 rospy.Duration(0.2))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            rospy.logwarn_throttle(10.0, f"harvest: detections of {msg.camera} dropped: no TF {self.frame} <- "
                                         f"{msg.header.frame_id}: {exc}")
            return
        pts = transform_points(transform_matrix(tf), np.array(points, dtype=float))
        if np.all(np.isfinite(pts)):
            with self._lock:
                self._detections.append((pts, msg.header.stamp.to_sec()))

    def _publish_hold(self, _event) -> None:
        if self._route_held:
            self.hold_pub.publish(Bool(True))

    def _on_enable(self, req):
        with self._lock:
            self.auto = bool(req.data)
        return SetBoolResponse(True, f"automatic picking {'on' if req.data else 'off'}")

    def _execute_pick(self, goal):
        request = {"goal": goal, "done": threading.Event(), "result": None}
        with self._lock:
            self._requests.append(request)
        while not request["done"].wait(0.05):
            if rospy.is_shutdown():
                return
            if self.server.is_preempt_requested():
                with self._lock:
                    if self._request is request:
                        self._cancel_request = True
                    elif request in self._requests:
                        self._requests.remove(request)
                        request["result"] = PickBollResult(False, "cancelled", "cancelled before it started", 0.0)
                        request["done"].set()
        result = request["result"]
        if result.success:
            self.server.set_succeeded(result, result.message)
        elif result.reason == "cancelled":
            self.server.set_preempted(result, result.message)
        else:
            self.server.set_aborted(result, result.message)

    # ------------------------------------------------------------------ the loop
    def spin(self) -> None:
        while not rospy.is_shutdown() and not self.arm.wait_for_server(1.0):
            rospy.logwarn_throttle(10.0, "harvest: waiting for /arm_controller/follow_joint_trajectory")
        period_s = 1.0 / self.loop_hz
        next_s = rospy.get_time()
        while not rospy.is_shutdown():
            self._step()
            now = rospy.get_time()
            next_s = min(max(next_s + period_s, now), now + period_s)   # behind: at once; clock reset: a period
            self._sleep_until(next_s)

    def _sleep_until(self, tick_s: float) -> None:
        """Wait until the sim time tick_s, or less when an arm motion ends or the nozzle catches its boll."""
        while not rospy.is_shutdown() and rospy.get_time() < tick_s:
            if self._wake.wait(WAKE_POLL_S):
                break
        self._wake.clear()

    def _pose(self) -> bool:
        try:
            arm_T_frame = transform_matrix(self.tf_buffer.lookup_transform(self.arm_base_frame, self.frame, rospy.Time(0)))
            arm_T_base = transform_matrix(self.tf_buffer.lookup_transform(self.arm_base_frame, self.robot_frame,
                                                                 rospy.Time(0)))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException):
            rospy.logwarn_throttle(10.0, f"harvest: waiting for TF {self.arm_base_frame} <- {self.frame}")
            return False
        self.harvester.update_pose(arm_T_frame, arm_T_base)
        return True

    def _step(self) -> None:
        now = rospy.get_time()
        with self._lock:
            detections = list(self._detections)
            self._detections.clear()
            holding, odom, cancel = self._holding, self._odom, self._cancel_request
            self._cancel_request = False
        q, events = self.arm.joints(), self.arm.pop_events()
        if not self._pose():
            return
        changed = self._fuse(detections, now)
        stopped = odom is not None and 0.0 <= now - odom[0] <= self.odom_max_age_s and \
            odom[1] <= self.config.stopped_speed_m_s and odom[2] <= self.config.stopped_yaw_rate_rad_s
        h = self.harvester
        if self._parking:
            for event in events:
                self._parking = False
                if isinstance(event, TrajectoryFailed):
                    rospy.logwarn("harvest: the move to the ready pose failed: %s", event.detail)
            if self._parking and now > self._park_deadline_s:
                rospy.logwarn("harvest: the move to the ready pose took too long; cancelled")
                self._carry_out([CancelTrajectory()])
                self._parking = False
        elif h.busy:
            if q is not None:
                h.update_joints(q)
            commands = []
            if cancel:
                commands += h.cancel(now, "the pick goal was cancelled")
            for event in events:
                commands += h.on_event(event, now)
            if h.busy and h.cycle.phase == "halt" and stopped:
                commands += h.on_event(RobotStopped(), now)
            if h.busy and h.cycle.phase == "capture" and holding:
                commands += h.on_event(CaptureConfirmed(), now)
            commands += h.tick(now)
            self._carry_out(commands)
            if h.busy and h.cycle.phase in (APPROACH, DELIVER) and not commands:
                h.plan_next()                          # the next target's plan, while the arm moves
            for result in h.history[self._logged:]:
                rospy.loginfo("harvest: target %d: %s (%s), %.2f s", result.target_id, result.reason, result.detail,
                              result.cycle_time_s)
            changed |= len(h.history) > self._logged       # a result changes its target (picked, attempts)
            self._logged = len(h.history)
            if not h.busy:
                self._finish_request(now)
        elif q is not None:
            self._maybe_start(q, stopped, now)
        self.arm.send_waiting()
        self._targets_dirty |= changed
        if self._targets_dirty and now >= self._next_targets_s:
            self._publish_targets(now)
        activity = (self._parking, h.busy, h.cycle.phase if h.busy else None,
                    h.cycle.current_target_id if h.busy else None)
        if changed or activity != self._published_activity or now >= self._next_status_s:
            self._published_activity = activity
            self._publish_status(now)

    def _fuse(self, detections, now: float) -> bool:
        if self.target_source == "ground_truth":
            points = self.truth.points()
            detections = [(points, now)] if points is not None and len(points) else []
            sigma = self.harvester.fusion.config.min_sigma_m
        else:
            sigma = None
        before = [(t.target_id, t.state) for t in self.harvester.fusion.targets()]
        for points, stamp in detections:
            self.harvester.add_detections(points, stamp, sigma)
        return before != [(t.target_id, t.state) for t in self.harvester.fusion.targets()]

    def _maybe_start(self, q: np.ndarray, stopped: bool, now: float) -> None:
        """Serve a pick request, or start a stop; the arm first goes to its ready pose."""
        h = self.harvester
        with self._lock:
            request = self._requests.popleft() if self._requests else None
            auto = self.auto
        if request is None and not (auto and h.want_stop(stopped, now)):
            if self._route_held:                     # parked for a stop that is no longer wanted
                self._route_held = False
                self.hold_pub.publish(Bool(False))
            return
        if np.abs(q - self.ready_rad).max() > READY_TOLERANCE_RAD:
            if request is not None:
                with self._lock:
                    self._requests.appendleft(request)
            self._route_held = request is None
            self._publish_hold(None)
            self._parking = True
            park = plan_trajectory(np.stack([q, self.ready_rad]), self.trajectory_config)
            self._park_deadline_s = now + park.duration_s + h.cycle_config.motion_margin_s
            self.arm.send(park)
            return
        if request is None:
            count = min(len(h.pickable(now)), self.config.max_targets_per_stop)
            not_seen_lately = len(h.in_reach()) - len(h.in_reach(now))
            self._carry_out(h.start_stop(q, now))
            rospy.loginfo("harvest: stop %d: halting for %d targets in reach (%d more in reach not seen in the last "
                          "%.1f s)", h.figures.stops, count, not_seen_lately, h.config.max_target_age_s)
            return
        goal = request["goal"]
        try:
            if goal.target_id >= 0:
                commands = h.start_pick(q, now, target_id=goal.target_id)
            else:
                tf = self.tf_buffer.lookup_transform(self.frame, goal.point.header.frame_id or self.frame,
                                                     rospy.Time(0))
                p = goal.point.point
                commands = h.start_pick(q, now, point_frame_m=transform_points(transform_matrix(tf), [[p.x, p.y, p.z]])[0])
        except (ValueError, RuntimeError, tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException) as exc:
            request["result"] = PickBollResult(False, "rejected", str(exc), 0.0)
            request["done"].set()
            return
        self._request = request
        self._pick_start_s = now
        self._carry_out(commands)
        if not h.busy:
            self._finish_request(now)

    def _finish_request(self, now: float) -> None:
        request, self._request = self._request, None
        if request is None:
            return
        result = self.harvester.cycle.results[-1]
        request["result"] = PickBollResult(result.ok, result.reason, result.detail, now - self._pick_start_s)
        request["done"].set()

    def _carry_out(self, commands) -> None:
        for command in commands:
            if isinstance(command, HaltRoute):
                self._route_held = True
                self._publish_hold(None)
            elif isinstance(command, ResumeRoute):
                self._route_held = False
                self.hold_pub.publish(Bool(False))
            elif isinstance(command, SendTrajectory):
                self.arm.send(command.trajectory)
            elif isinstance(command, CancelTrajectory):
                self.arm.cancel()
            elif isinstance(command, SetVacuum):
                self.arm.set_vacuum(command.on)
        if self._request is not None and self.harvester.busy:
            self.server.publish_feedback(PickBollFeedback(phase=self.harvester.cycle.phase or ""))

    # ------------------------------------------------------------------ outputs
    def _publish_targets(self, now: float) -> None:
        self._targets_dirty = False
        self._next_targets_s = now + self.targets_period_s
        msg = BollTargetArray()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self.frame
        for t in self.harvester.fusion.targets():
            last = self.harvester.last_result.get(t.target_id)
            item = BollTarget(id=t.target_id, sigma_m=t.sigma_m, observations=t.observations,
                              state=_TARGET_STATES[t.state], attempts=t.attempts,
                              last_result=last.reason if last else "",
                              first_seen=rospy.Time.from_sec(max(t.first_seen_s, 0.0)),
                              last_seen=rospy.Time.from_sec(max(t.last_seen_s, 0.0)))
            item.position.x, item.position.y, item.position.z = (float(v) for v in t.position_m)
            msg.targets.append(item)
        self.targets_pub.publish(msg)
        spheres = Marker(header=msg.header, ns="harvest_targets", id=0, type=Marker.SPHERE_LIST, action=Marker.ADD)
        spheres.pose.orientation.w = 1.0
        spheres.scale.x = spheres.scale.y = spheres.scale.z = 0.04
        for t, item in zip(self.harvester.fusion.targets(), msg.targets):
            spheres.points.append(item.position)
            r, g, b = _MARKER_RGB[t.state]
            spheres.colors.append(ColorRGBA(r, g, b, 1.0))
        self.markers_pub.publish(MarkerArray(markers=[spheres]))

    def _publish_status(self, now: float) -> None:
        self._next_status_s = now + self.status_period_s
        h = self.harvester
        counts = {state: 0 for state in _TARGET_STATES}
        for t in h.fusion.targets():
            counts[t.state] += 1
        status = {"state": "parking" if self._parking else "picking" if h.busy else "idle", "auto": self.auto,
                  "phase": h.cycle.phase if h.busy else None, "target": h.cycle.current_target_id if h.busy else None,
                  "route_held": self._route_held, "targets": counts,
                  "in_reach": [t.target_id for t in h.pickable(now)]}
        status.update(h.figures.as_dict())
        self.status_pub.publish(String(data=json.dumps(status)))
