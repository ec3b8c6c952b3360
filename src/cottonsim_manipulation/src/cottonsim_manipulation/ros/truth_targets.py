"""Ground-truth boll detections for the harvest node (``~target_source: ground_truth``, a study option).

The simulator's open bolls (/sim/bolls, world frame) within ``range_m`` of the robot's true position
(/ground_truth/odom) are given to the harvester as if detected, in the targets' fixed frame. The true
pose is paired with TF by stamp: the newest true pose no newer than the newest TF
``frame <- robot_frame``, and TF at its stamp (tf2 interpolates between its samples); TF comes up to
~0.2 s after the truth. With the newest of each, a driving robot's targets were off by its speed
times the two messages' age difference; with the nearest pose to the newest TF (up to 50 ms apart,
25 mm at 0.5 m/s) a boll's target could jump out of the fusion's gate and start a second target.
"""
from __future__ import annotations

import collections
import threading
from typing import Optional

import numpy as np
import rospy
import tf2_ros
from cottonsim_msgs.msg import Boll, BollArray
from nav_msgs.msg import Odometry

from cottonsim_common.ros.conversions import transform_matrix
from cottonsim_common.transforms import pose_matrix
from cottonsim_common.transforms import transform_points


class TruthTargets:
    """Subscribes to the simulator's truth; :meth:`points` gives the open bolls near the robot."""

    def __init__(self, tf_buffer: tf2_ros.Buffer, frame: str, robot_frame: str, range_m: float):
        self.tf_buffer, self.frame, self.robot_frame, self.range_m = tf_buffer, frame, robot_frame, range_m
        self._lock = threading.Lock()
        self._open_bolls: Optional[np.ndarray] = None                  # (N, 3) world [m]
        self._true_poses = collections.deque(maxlen=200)               # (stamp [s], 4x4 world_T_base)
        rospy.Subscriber("/sim/bolls", BollArray, self._on_bolls, queue_size=2)
        rospy.Subscriber("/ground_truth/odom", Odometry, self._on_pose, queue_size=5)

    def _on_bolls(self, msg: BollArray) -> None:
        bolls = np.array([(b.position.x, b.position.y, b.position.z) for b in msg.bolls
                          if b.state == Boll.ON_PLANT], dtype=float).reshape(-1, 3)
        with self._lock:
            self._open_bolls = bolls

    def _on_pose(self, msg: Odometry) -> None:
        p, r = msg.pose.pose.position, msg.pose.pose.orientation
        world_T_base = pose_matrix((p.x, p.y, p.z), (r.x, r.y, r.z, r.w))
        with self._lock:
            self._true_poses.append((msg.header.stamp.to_sec(), world_T_base))

    def points(self) -> Optional[np.ndarray]:
        """The open bolls within range_m of the robot, (N, 3) in ``frame``; None while the truth, the true
        pose or TF is missing."""
        with self._lock:
            bolls, poses = self._open_bolls, list(self._true_poses)
        if bolls is None or not poses:
            return self._missing("no /sim/bolls or /ground_truth/odom yet")
        try:
            newest = self.tf_buffer.lookup_transform(self.frame, self.robot_frame, rospy.Time(0))
            newest_s = newest.header.stamp.to_sec()
            known = [sp for sp in poses if sp[0] <= newest_s]        # TF lags the truth by up to ~0.2 s
            if not known:
                return self._missing(f"every true pose is newer than the newest TF {self.frame} <- "
                                     f"{self.robot_frame} ({newest_s:.3f} s)")
            pose_stamp_s, world_T_base = known[-1]
            tf_msg = self.tf_buffer.lookup_transform(self.frame, self.robot_frame, rospy.Time.from_sec(pose_stamp_s))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            return self._missing(f"no TF {self.frame} <- {self.robot_frame}: {exc}")
        near = bolls[np.linalg.norm(bolls[:, :2] - world_T_base[:2, 3], axis=1) <= self.range_m]
        return transform_points(transform_matrix(tf_msg) @ np.linalg.inv(world_T_base), near)

    @staticmethod
    def _missing(why: str) -> None:
        rospy.logwarn_throttle(10.0, f"harvest: no ground-truth targets now: {why}")
        return None
