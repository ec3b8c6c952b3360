"""Harvest recorder: keeps the harvest node's status and targets and the bolls' truth of a run in harvest.json.

The record itself is :mod:`cottonsim_experiments.harvest_run.record` (no ROS); this node feeds it and
writes ``~output_file`` atomically after every change (at most every ``~min_write_period_s`` of wall
time; a change within that is written at the next message or timer tick) and once more on shutdown,
so the file holds the last state whichever way the run ends.

Subscriptions
  /harvest/status (std_msgs/String, JSON), /harvest/targets (cottonsim_msgs/BollTargetArray), /sim/bolls
  (cottonsim_msgs/BollArray, world), /ground_truth/odom (nav_msgs/Odometry, world): with TF (targets' frame
  -> ~robot_frame) the pose of the targets' frame in the world, so each target gets position_world, as of the
  message in which its position last changed (the odom frame drifts from the world over a run).
Parameters
  ~output_file (str, required): where harvest.json goes (its folder is created)
  ~robot_frame (str, base_link): the robot's frame, the child of /ground_truth/odom
  ~min_write_period_s (float, 2.0 s wall): least time between two writes while the run goes on (a farm's
      harvest.json is ~1 MB: writing it costs ~50 ms of CPU)
"""
from __future__ import annotations

import threading
import time

import numpy as np
import rospy
import tf2_ros
from cottonsim_msgs.msg import BollArray, BollTargetArray
from nav_msgs.msg import Odometry
from std_msgs.msg import String

from cottonsim_common.ros.conversions import transform_matrix
from cottonsim_common.transforms import invert, pose_matrix
from cottonsim_experiments.harvest_run.record import HarvestRecord, write_json_atomic


class HarvestRecorderStartError(RuntimeError):
    """A bad parameter; the node exits non-zero."""


class HarvestRecorderNode:
    """Records the harvest of a run into ~output_file (module docstring)."""

    def __init__(self) -> None:
        self.output_file = str(rospy.get_param("~output_file", ""))
        if not self.output_file:
            raise HarvestRecorderStartError("~output_file must name the harvest.json to write")
        self.robot_frame = str(rospy.get_param("~robot_frame", "base_link"))
        self.min_write_period_s = float(rospy.get_param("~min_write_period_s", 2.0))
        if not self.min_write_period_s >= 0.0:
            raise HarvestRecorderStartError(f"~min_write_period_s must be >= 0, got {self.min_write_period_s}")
        self.record = HarvestRecord()
        self.lock = threading.Lock()
        self.dirty = False
        self.last_write_wall_s = 0.0
        self.world_T_base = None          # (stamp, 4x4) from /ground_truth/odom
        self.world_of_target = {}         # target id -> (position in the targets' frame, in the world) when estimated
        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        rospy.Subscriber("/ground_truth/odom", Odometry, self._on_truth_pose, queue_size=5)
        rospy.Subscriber("/harvest/status", String, self._on_status, queue_size=20)
        rospy.Subscriber("/harvest/targets", BollTargetArray, self._on_targets, queue_size=5)
        rospy.Subscriber("/sim/bolls", BollArray, self._on_bolls, queue_size=2)
        rospy.Timer(rospy.Duration(1.0), lambda _: self._write(force=False))
        rospy.on_shutdown(lambda: self._write(force=True))
        rospy.loginfo(f"harvest_recorder: writing {self.output_file}")

    def _on_truth_pose(self, msg: Odometry) -> None:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        self.world_T_base = (msg.header.stamp, pose_matrix((p.x, p.y, p.z), (q.x, q.y, q.z, q.w)))

    def _world_T_frame(self, frame: str):
        """The targets' frame in the world at the newest true pose, or None (no pose yet, no TF)."""
        truth = self.world_T_base
        if truth is None or not frame:
            return None
        stamp, world_T_base = truth
        try:
            tf = self.tf_buffer.lookup_transform(frame, self.robot_frame, stamp, rospy.Duration(0.2))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException):
            return None
        return world_T_base @ invert(transform_matrix(tf))

    def _on_status(self, msg: String) -> None:
        try:
            with self.lock:
                self.dirty |= self.record.on_status(msg.data, rospy.get_time())
        except ValueError as exc:
            rospy.logwarn_throttle(10.0, f"harvest_recorder: {exc}")
            return
        self._write(force=False)

    def _on_targets(self, msg: BollTargetArray) -> None:
        world_T_frame = self._world_T_frame(msg.header.frame_id)
        targets = []
        for t in msg.targets:
            position = [t.position.x, t.position.y, t.position.z]
            # a target's world position as of its last estimate: the odom frame drifts from the world
            # (by decimetres over a long run), and a target not seen since keeps where it was believed then
            known = self.world_of_target.get(t.id)
            if known is not None and known[0] == position:
                world = known[1]
            else:
                world = None if world_T_frame is None else (world_T_frame @ np.array(position + [1.0]))[:3].tolist()
                if world is not None:
                    self.world_of_target[t.id] = (position, world)
            targets.append({"id": t.id, "position": position, "position_world": world, "sigma_m": t.sigma_m,
                            "observations": t.observations, "state": t.state, "attempts": t.attempts,
                            "last_result": t.last_result, "first_seen_s": t.first_seen.to_sec(),
                            "last_seen_s": t.last_seen.to_sec()})
        try:
            with self.lock:
                self.dirty |= self.record.on_targets(msg.header.frame_id, msg.header.stamp.to_sec(), targets)
        except ValueError as exc:
            rospy.logwarn_throttle(10.0, f"harvest_recorder: {exc}")
            return
        self._write(force=False)

    def _on_bolls(self, msg: BollArray) -> None:
        bolls = [{"id": b.id, "plant": b.plant_id, "position": [b.position.x, b.position.y, b.position.z],
                  "state": b.state} for b in msg.bolls]
        try:
            with self.lock:
                self.dirty |= self.record.on_bolls(msg.header.stamp.to_sec(), bolls)
        except ValueError as exc:
            rospy.logwarn_throttle(10.0, f"harvest_recorder: {exc}")
            return
        self._write(force=False)

    def _write(self, force: bool) -> None:
        with self.lock:
            now = time.monotonic()
            if not force and (not self.dirty or now - self.last_write_wall_s < self.min_write_period_s):
                return
            data = self.record.to_dict()
            self.dirty = False
            self.last_write_wall_s = now
            try:
                write_json_atomic(self.output_file, data)
            except OSError as exc:
                rospy.logerr(f"harvest_recorder: cannot write {self.output_file}: {exc}")
