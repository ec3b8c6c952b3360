"""Broadcasting a planar transform (e.g. map -> odom) once per stamp.

tf2 warns TF_REPEATED_DATA and drops a transform sent again with the same
stamp, which happens whenever sim time stands still between two timer ticks;
:class:`PlanarTransformBroadcaster` skips a stamp that is not newer than the
last one it sent.
"""
from __future__ import annotations

from typing import Optional

import rospy
import tf2_ros

from cottonsim_common.pose import Pose2D
from cottonsim_common.ros.conversions import transform_msg
from cottonsim_common.transforms import yaw_to_quaternion


class PlanarTransformBroadcaster:
    """Sends ``parent -> child`` as a Pose2D (z = 0), each stamp at most once and only forward in time."""

    def __init__(self, parent_frame: str, child_frame: str, broadcaster: Optional[tf2_ros.TransformBroadcaster] = None):
        self.parent_frame = parent_frame
        self.child_frame = child_frame
        self.broadcaster = broadcaster or tf2_ros.TransformBroadcaster()
        self.last_stamp: Optional[rospy.Time] = None

    def send(self, pose: Pose2D, stamp: rospy.Time) -> bool:
        """Broadcast ``pose`` at ``stamp``; False (nothing sent) when the stamp is not newer than the last."""
        if self.last_stamp is not None and stamp <= self.last_stamp:
            return False
        self.last_stamp = stamp
        self.broadcaster.sendTransform(transform_msg(self.parent_frame, self.child_frame, (pose.x_m, pose.y_m, 0.0),
                                                     yaw_to_quaternion(pose.yaw_rad), stamp))
        return True
