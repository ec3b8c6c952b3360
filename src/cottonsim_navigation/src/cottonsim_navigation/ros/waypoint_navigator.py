"""The shared ROS machinery of the GPS and map waypoint navigators.

Both navigators do the same thing once their route is a list of map-frame
goal poses: wait for localisation, send the goals one by one to move_base,
react to aborts (skip or stop), go Home when the battery runs low, publish
their state and end with a summary. Only "how do waypoints become map
goals" and "when is localisation ready" differ; subclasses supply those
(:meth:`WaypointNavigatorBase.load_route`, :meth:`localization_ready`,
:meth:`make_goals`). The decision logic itself is the ROS-free
:class:`cottonsim_navigation.waypoints.follower.WaypointFollower`.

Goal tracking: every goal gets a sequence number; move_base's result is
accepted only for the goal it belongs to, so a late result of a cancelled
goal can never be taken for the current one (the original's stale-status
defect).

Lost localisation (``~localized_topic``, e.g. AMCL's ``/amcl/localized``): once
the localiser has reported "localised" and then reports "not localised" (a
kidnap), the active goal is cancelled (move_base stops the robot) and held,
not counted as aborted; when it reports "localised" again the same goal is
sent again. The route is never cut short by a lost localisation.

Halt at bolls (``~boll_halt/enabled``, the paper's stop for picking): while
Cotton-Eye's side cameras report a boll within the arm's reach
(``~bolls_in_reach_topic``), the active goal is cancelled (move_base stops
the robot) for ``~boll_halt/dwell_s`` of sim time, then the same goal is
sent again; the next halt needs the robot to have moved
``~boll_halt/rearm_distance_m`` (:mod:`cottonsim_navigation.waypoints.boll_halt`),
so a boll that stays in view never stalls the route.

Route hold (``~hold_topic``, e.g. /harvest/hold_route): while a fresh true is there the goal is cancelled
and the robot stands; released, the same goal is sent again (:mod:`cottonsim_navigation.waypoints.route_hold`).

State (std_msgs/String on ~state, latched): a JSON object
``{"state": waiting|navigating|returning_home|paused|halted|held|finished, "index": i (1-based goal), "total": N,
"label": ..., "goal": [x, y, yaw], "succeeded": n, "passed": n (of the succeeded, driven through),
"aborted": n, "aborted_waypoints": [{"index": i, "label": ..., "reason": move_base's status text}, ...],
"skipped": n, "returned_home": bool, "home_reached": bool|null, "holds": n (goals held
while localisation was lost), "halts": n (halts at bolls), "halt_time_s": s (their total sim time),
"route_holds": n, "route_hold_time_s": s (holds by ~hold_topic), "reason": ...}``.
"""
from __future__ import annotations

import json
import math
import threading
import time
from typing import List, Optional

import actionlib
import numpy as np
import rospy
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Bool, String

from cottonsim_common.transforms import yaw_to_quaternion
from cottonsim_navigation.ros.navigator_params import NavigatorStartError, read_navigator_params
from cottonsim_navigation.waypoints.boll_halt import BollHalt, BollVerdicts
from cottonsim_navigation.waypoints.route_hold import RouteHold
from cottonsim_navigation.waypoints.files import MapWaypoint, WaypointFileError
from cottonsim_navigation.waypoints.goals import pass_through_flags
from cottonsim_navigation.waypoints.follower import FollowerState, GoalResult, LocalisationGate, WaypointFollower
from cottonsim_common.ros.conversions import yaw_from_quaternion_msg

_STATUS_NAMES = {getattr(GoalStatus, n): n for n in ("PENDING", "ACTIVE", "PREEMPTED", "SUCCEEDED", "ABORTED",
                                                     "REJECTED", "PREEMPTING", "RECALLING", "RECALLED", "LOST")}


class WaypointNavigatorBase:
    """Sends a route of map-frame goals to move_base (ROS API shared by both navigators).

    Subscriptions
      /battery/state (sensor_msgs/BatteryState, ~battery_topic): percentage in [0, 1];
        at or below ~return_home_percentage the active goal is cancelled, Home is sent
        and the navigator stops once it is reached. NaN percentages are ignored.
      ~localized_topic (std_msgs/Bool, default per navigator, "" = none): the localiser's verdict;
        after it was true once, false pauses the route (the active goal is cancelled, the robot stops, the
        goal is held) until it is true again, then the same goal is sent again. The first true is not
        waited for: the route starts on the initial pose (AMCL reports localised only after some motion).
      ~bolls_in_reach_topic (std_msgs/Bool, default /cotton_eye/bolls_in_reach; only with ~boll_halt/enabled):
        each boll detection node's verdict per frame; the newest of every publisher (callerid) counts for
        ~boll_halt/max_age_s, and bolls are in reach while any of them is true.
      ~hold_topic (std_msgs/Bool, default "" = none): route hold requests, see the module docstring.
    Publications
      ~state (std_msgs/String, latched): JSON state, see the module docstring.
    Action client
      move_base (move_base_msgs/MoveBaseAction, ~move_base_action): one goal at a time, frame ~goal_frame.
    TF
      reads ~goal_frame -> ~robot_frame (map -> base_link): localisation is ready once it exists;
      the robot's pose there when the route starts is Home.
    Parameters (private)
      see :mod:`cottonsim_navigation.ros.navigator_params` (read once at start)
    """

    NAME = "waypoint_navigator"
    DEFAULT_LOCALIZED_TOPIC = ""
    LOST_REASON = "localisation lost"          # ~state's reason while paused for lost localisation
    LOST_HINT = ("if it cannot re-localise by itself, give it the robot's pose (/initialpose, rviz "
                 "'2D Pose Estimate')")

    # ------------------------------------------------------------------ hooks for subclasses
    def load_route(self, path: str) -> list:
        """Read the waypoint file; raise WaypointFileError (or ValueError) on any problem."""
        raise NotImplementedError

    def localization_ready(self) -> bool:
        """True once goals can be placed in the map (TF map -> base_link by default)."""
        return self.robot_pose() is not None

    def make_goals(self, waypoints: list) -> List[MapWaypoint]:
        """The route as map-frame goals; called once localisation is ready."""
        raise NotImplementedError

    # ------------------------------------------------------------------ setup
    def __init__(self):
        self.params = read_navigator_params(self.NAME, self.DEFAULT_LOCALIZED_TOPIC)
        self.route_hold = RouteHold(self.params.route_hold_config)
        try:
            self.waypoints = self.load_route(self.params.waypoints_file)
        except WaypointFileError as exc:
            raise NavigatorStartError(f"bad waypoint file {exc}") from None
        except ValueError as exc:
            raise NavigatorStartError(f"bad waypoint file {self.params.waypoints_file}: {exc}") from None
        rospy.loginfo("%s: %d waypoints from %s", self.NAME, len(self.waypoints), self.params.waypoints_file)

        self._lock = threading.Lock()
        self._goal_seq = 0              # sequence number of the goal in flight (0: none)
        self._result = None             # (seq, GoalStatus, status text) of a finished goal
        self._goal_sent_at = None
        self._battery_low = False
        self._gate = LocalisationGate()                # the localiser's verdicts
        self._paused_since: Optional[rospy.Time] = None
        self.boll_halt = BollHalt(self.params.halt_config)
        self._verdicts = BollVerdicts(self.params.halt_config.max_age_s)
        self.follower: Optional[WaypointFollower] = None
        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.state_pub = rospy.Publisher("~state", String, queue_size=10, latch=True)
        self.client = actionlib.ActionClient(self.params.action_ns, MoveBaseAction)
        self._goal_handle = None
        rospy.Subscriber(self.params.battery_topic, BatteryState, self._on_battery, queue_size=5)
        if self.params.localized_topic:
            rospy.Subscriber(self.params.localized_topic, Bool, self._on_localized, queue_size=5)
            rospy.loginfo("%s: pausing the route while %s reports not localised", self.NAME,
                          self.params.localized_topic)
        if self.params.halt_config.enabled:
            topic = self.params.bolls_in_reach_topic
            rospy.Subscriber(topic, Bool, self._on_bolls_in_reach, queue_size=10)
            rospy.loginfo("%s: halting %.1f s while %s reports bolls in reach", self.NAME,
                          self.params.halt_config.dwell_s, topic)
        hold_topic = self.params.hold_topic
        if hold_topic:
            rospy.Subscriber(hold_topic, Bool, self._on_hold, queue_size=10)
            rospy.loginfo("%s: standing while %s holds the route", self.NAME, hold_topic)

    # ------------------------------------------------------------------ inputs
    def _on_battery(self, msg: BatteryState):
        pct = float(msg.percentage)
        if not math.isfinite(pct):
            rospy.logwarn_throttle(10.0, f"{self.NAME}: battery percentage is NaN; ignored")
            return
        threshold = self.params.return_home_percentage
        if threshold > 0.0 and pct * 100.0 <= threshold and not self._battery_low:
            rospy.logwarn("%s: battery at %.1f %% (<= %.1f %%): returning Home", self.NAME, pct * 100.0,
                          self.params.return_home_percentage)
            self._battery_low = True

    def _on_localized(self, msg: Bool):
        with self._lock:
            self._gate.report(bool(msg.data))

    def _on_bolls_in_reach(self, msg: Bool):
        source = getattr(msg, "_connection_header", {}).get("callerid", "")
        with self._lock:
            self._verdicts.report(source, bool(msg.data), rospy.get_time())

    def _on_hold(self, msg: Bool):
        with self._lock:
            self.route_hold.report(bool(msg.data), rospy.get_time())

    def localization_lost(self) -> bool:
        """The localiser was localised once and now says it is not (kidnap, re-initialisation)."""
        with self._lock:
            return self._gate.lost

    def _on_transition(self, seq: int, gh):
        """actionlib transition callback, bound to the goal's sequence number when it was sent."""
        if gh.get_comm_state() != actionlib.CommState.DONE:
            return
        status = gh.get_goal_status()
        text = gh.get_goal_status_text()
        with self._lock:
            if seq == self._goal_seq:
                self._result = (seq, status, text)

    def robot_pose(self) -> Optional[MapWaypoint]:
        """The robot's pose in ~goal_frame from TF, or None when the transform is not there yet."""
        try:
            t = self.tf_buffer.lookup_transform(self.params.goal_frame, self.params.robot_frame, rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException):
            return None
        tr = t.transform.translation
        yaw = yaw_from_quaternion_msg(t.transform.rotation)
        if not all(math.isfinite(v) for v in (tr.x, tr.y, yaw)):
            return None
        return MapWaypoint(tr.x, tr.y, yaw, "Home")

    # ------------------------------------------------------------------ outputs
    def publish_state(self, state: str, reason: str = "", goal: Optional[MapWaypoint] = None):
        f = self.follower
        s = f.summary if f is not None else None
        msg = {"state": state,
               "index": (f.index + 1) if f is not None and not f.finished else None,
               "total": s.total if s else len(self.waypoints),
               "label": goal.label if goal is not None else "",
               "goal": [goal.x_m, goal.y_m, goal.yaw_rad] if goal is not None else None,
               "succeeded": s.succeeded if s else 0, "passed": s.passed if s else 0,
               "aborted": s.aborted if s else 0,
               "aborted_waypoints": [dict(a, label=getattr(f.goals[a["index"] - 1], "label", ""))
                                     for a in s.aborted_waypoints] if s else [],
               "skipped": s.skipped if s else 0, "returned_home": s.returned_home if s else False,
               "home_reached": s.home_reached if s else None, "holds": s.holds if s else 0,
               "halts": self.boll_halt.halts, "halt_time_s": round(self.boll_halt.halt_time_s, 3),
               "route_holds": self.route_hold.holds, "route_hold_time_s": round(self.route_hold.hold_time_s, 3),
               "reason": reason or (s.stopped_reason if s else "")}
        self.state_pub.publish(String(data=json.dumps(msg)))

    def _send(self, goal: MapWaypoint):
        mb = MoveBaseGoal()
        mb.target_pose.header.frame_id = self.params.goal_frame
        mb.target_pose.header.stamp = rospy.Time.now()
        mb.target_pose.pose.position.x = goal.x_m
        mb.target_pose.pose.position.y = goal.y_m
        q = yaw_to_quaternion(goal.yaw_rad)
        mb.target_pose.pose.orientation.x, mb.target_pose.pose.orientation.y = float(q[0]), float(q[1])
        mb.target_pose.pose.orientation.z, mb.target_pose.pose.orientation.w = float(q[2]), float(q[3])
        with self._lock:
            self._goal_seq += 1
            self._result = None
            seq = self._goal_seq
        self._goal_sent_at = rospy.Time.now()
        self._goal_handle = self.client.send_goal(mb, transition_cb=lambda gh, s=seq: self._on_transition(s, gh))
        home = self.follower.going_home
        rospy.loginfo("%s: goal %s%s (%.2f, %.2f, yaw %.2f) sent", self.NAME,
                      "Home" if home else f"{self.follower.index + 1}/{len(self.waypoints)} ",
                      "" if home else goal.label, goal.x_m, goal.y_m, goal.yaw_rad)
        self.publish_state("returning_home" if home else "navigating", goal=goal)

    def _cancel_active(self):
        with self._lock:
            self._goal_seq += 1          # any late result of the cancelled goal is now ignored
            self._result = None
        if self._goal_handle is not None:
            self._goal_handle.cancel()
            self._goal_handle = None

    # ------------------------------------------------------------------ main loop
    def _wait(self, what: str, ready) -> bool:
        """Poll ready() (wall-time sleeps, so a paused /clock cannot hang us unnoticed)."""
        start = time.monotonic()
        warned = False
        while not rospy.is_shutdown():
            if ready():
                return True
            if not warned and time.monotonic() - start > 5.0:
                rospy.loginfo("%s: waiting for %s", self.NAME, what)
                warned = True
            rospy.rostime.wallsleep(0.1)
        return False

    def run(self) -> int:
        """Drive the route; returns the process exit code (0 = ran to the end, even with skipped goals)."""
        self.publish_state("waiting", reason="waiting for move_base and localisation")
        wall_deadline = None if self.params.server_timeout_s == 0 else time.monotonic() + self.params.server_timeout_s
        while not rospy.is_shutdown():
            if self.client.wait_for_server(rospy.Duration(0.5)):
                break
            if wall_deadline is not None and time.monotonic() > wall_deadline:
                rospy.logfatal("%s: no move_base action server at '%s' after %.0f s", self.NAME, self.params.action_ns,
                               self.params.server_timeout_s)
                self.publish_state("finished", reason="no move_base action server")
                return 1
        if not self._wait(f"localisation (TF {self.params.goal_frame} -> {self.params.robot_frame})",
                          self.localization_ready):
            return 0
        home = self.robot_pose()
        try:
            goals = self.make_goals(self.waypoints)
        except ValueError as exc:
            rospy.logfatal("%s: cannot place the waypoints in the map: %s", self.NAME, exc)
            self.publish_state("finished", reason=str(exc))
            return 1
        flags = pass_through_flags(np.array([[g.x_m, g.y_m] for g in goals], dtype=float),
                                   self.params.pass_through_max_turn_rad)
        self.follower = WaypointFollower(goals, self.params.follower_config, home=home, pass_through=flags)
        if self.params.follower_config.pass_through_radius_m > 0:
            rospy.loginfo("%s: %d of %d waypoints are driven through (within %.2f m)", self.NAME, int(flags.sum()),
                          len(goals), self.params.follower_config.pass_through_radius_m)
        rospy.loginfo("%s: Home = (%.2f, %.2f, yaw %.2f) in %s; starting the route", self.NAME, home.x_m, home.y_m,
                      home.yaw_rad, self.params.goal_frame)
        rate = rospy.Rate(self.params.loop_hz)
        while not rospy.is_shutdown() and not self.follower.finished:
            self._step()
            if self.follower.finished:
                break
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                break
        if not self.follower.finished:
            self._cancel_active()
            self.publish_state("finished", reason="shut down before the route ended")
            return 0
        s = self.follower.summary
        self.publish_state("finished")
        rospy.loginfo("%s: finished (%s): %d/%d waypoints succeeded, %d aborted, %d skipped%s", self.NAME,
                      s.stopped_reason, s.succeeded, s.total, s.aborted, s.skipped,
                      (", Home reached" if s.home_reached else ", Home NOT reached") if s.returned_home else "")
        return 0

    def _passed_current(self) -> bool:
        """Ask the follower whether the robot's TF pose passes the active pass-through goal."""
        pose = self.robot_pose()
        goal = self.follower.current_goal
        if pose is None or goal is None:
            return False
        if not self.follower.passed(math.hypot(pose.x_m - goal.x_m, pose.y_m - goal.y_m)):
            return False
        with self._lock:
            self._goal_seq += 1          # the passed goal's late result (preempted by the next) is ignored
            self._result = None
        return True

    def _step(self):
        f = self.follower
        if self._battery_low and not f.going_home:
            if f.state is FollowerState.ACTIVE:
                self._cancel_active()
            f.battery_low()
        with self._lock:
            result, self._result = self._result, None
        lost = self.localization_lost()
        if result is not None and f.state is FollowerState.ACTIVE:
            status, text = result[1], result[2]
            ok = status == GoalStatus.SUCCEEDED
            reason = f"move_base {_STATUS_NAMES.get(status, status)}: {text}" if text else \
                f"move_base {_STATUS_NAMES.get(status, status)}"
            if not ok:
                rospy.logwarn("%s: goal %s ended: %s; %s", self.NAME, "Home" if f.going_home else f.index + 1,
                              reason, "going on with the route" if self.params.follower_config.on_failure == "skip"
                              else "stopping")
            f.report_result(GoalResult.SUCCEEDED if ok else GoalResult.ABORTED, reason)
        elif lost or self._paused_since is not None or self.boll_halt.halted or self.route_hold.held:
            pass                         # paused, halted or resuming: no pass-through or time-out of a held goal
        elif f.current_is_pass_through and self._passed_current():
            rospy.loginfo("%s: goal %d passed (within %.2f m); on to the next", self.NAME, f.index,
                          self.params.follower_config.pass_through_radius_m)
        elif (f.state is FollowerState.ACTIVE and self.params.goal_timeout_s > 0 and self._goal_sent_at is not None
              and (rospy.Time.now() - self._goal_sent_at).to_sec() > self.params.goal_timeout_s):
            rospy.logwarn("%s: goal %s timed out after %.0f s; cancelled", self.NAME, f.index + 1,
                          self.params.goal_timeout_s)
            self._cancel_active()
            f.report_result(GoalResult.ABORTED, f"timed out after {self.params.goal_timeout_s:.0f} s (goal_timeout_s)")
        if f.finished:
            return
        if lost:
            self._pause()
            return
        if self._paused_since is not None:
            rospy.loginfo("%s: localised again after %.1f s (sim): resuming %s", self.NAME,
                          (rospy.Time.now() - self._paused_since).to_sec(), self._describe_current())
            self._paused_since = None
        if self._held_by_request() or self._halt_at_bolls():
            return
        goal = f.next_goal(localization_ready=True)
        if goal is not None:
            self._send(goal)

    def _halt_at_bolls(self) -> bool:
        """The halt at bolls for this cycle; True while the robot stands (no goal may be sent)."""
        if not self.params.halt_config.enabled:
            return False
        f = self.follower
        now_s = rospy.get_time()
        if f.going_home:
            if self.boll_halt.cancel(now_s):
                rospy.loginfo("%s: halt at bolls ended early: returning Home", self.NAME)
            return False
        with self._lock:
            in_reach = self._verdicts.in_reach(now_s)
        pose = self.robot_pose()
        d = self.boll_halt.step(now_s, pose.x_m if pose else None, pose.y_m if pose else None,
                                in_reach and f.state is FollowerState.ACTIVE)
        if d.started:
            self._cancel_active()          # move_base stops the robot
            f.hold(count=False)
            rospy.loginfo("%s: bolls in reach: halt %d for %.1f s (%s held)", self.NAME, self.boll_halt.halts,
                          self.params.halt_config.dwell_s, self._describe_current())
            self.publish_state("halted", reason="bolls in reach", goal=f.current_goal)
        elif d.ended:
            rospy.loginfo("%s: halt %d done: resuming %s", self.NAME, self.boll_halt.halts, self._describe_current())
        return d.halted

    def _held_by_request(self) -> bool:
        """The route hold (~hold_topic) for this cycle; True while the robot stands (no goal may be sent)."""
        with self._lock:
            d = self.route_hold.step(rospy.get_time())
        if d.started:
            if self.follower.state is FollowerState.ACTIVE:
                self._cancel_active()          # move_base stops the robot
                self.follower.hold(count=False)
            self.publish_state("held", reason="held by request", goal=self.follower.current_goal)
        if d.started or d.ended:
            rospy.loginfo("%s: route %s: %s", self.NAME, "held" if d.halted else "released", self._describe_current())
        return d.halted

    def _describe_current(self) -> str:
        f = self.follower
        if f.index >= len(f.goals):
            return "the route"
        if f.going_home:
            return "the way Home"
        return f"goal {f.index + 1}/{len(self.waypoints)} {getattr(f.goals[f.index], 'label', '')}".rstrip()

    def _pause(self):
        """Localisation lost: cancel and hold the active goal (once), then wait (reminding every 30 s)."""
        if self._paused_since is not None:
            waited_s = (rospy.Time.now() - self._paused_since).to_sec()
            if waited_s >= 30.0:
                rospy.logwarn_throttle(30.0, "%s: still waiting for localisation (%.0f s, %s held); %s"
                                       % (self.NAME, waited_s, self._describe_current(), self.LOST_HINT))
            return
        self._paused_since = rospy.Time.now()
        f = self.follower
        held = f.state is FollowerState.ACTIVE
        if held:
            self._cancel_active()          # move_base stops the robot
            f.hold()
        goal = f.goals[f.index] if f.index < len(f.goals) else None
        rospy.logwarn("%s: %s (%s is false): %s %s, robot stopped; waiting to be localised again",
                      self.NAME, self.LOST_REASON, self.params.localized_topic, self._describe_current(),
                      "held" if held else "not sent yet")
        self.publish_state("paused", reason=self.LOST_REASON, goal=goal)


def run_route(node: "WaypointNavigatorBase") -> int:
    """Drive the route, let the latched final state reach its subscribers, shut down; the exit status."""
    code = node.run()
    rospy.rostime.wallsleep(1.0)
    rospy.signal_shutdown("waypoint route finished")   # actionlib threads would keep the process alive
    return code
