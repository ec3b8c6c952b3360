"""Shared by the rostest check nodes: drive the robot on /cmd_vel until the ground truth moved or turned enough."""
import math
import time

import rospy
from geometry_msgs.msg import Twist

from cottonsim_common.angles import wrap_angle_scalar
from cottonsim_common.ros.conversions import yaw_from_quaternion_msg


def drive_until(cmd, truth, v, w, distance_m=None, angle_rad=None, timeout_s=120.0, period_s=0.05) -> None:
    """Publish (v [m/s], w [rad/s]) on ``cmd`` until the robot moved ``distance_m`` or turned ``angle_rad``
    (summed |yaw change|) by the ground truth, or ``timeout_s`` of wall time passed; then publish a stop.

    truth: called for the newest nav_msgs/Odometry of the ground truth; period_s: sim time between commands.
    """
    p0 = truth().pose.pose
    yaw_prev, turned = yaw_from_quaternion_msg(p0.orientation), 0.0
    msg = Twist()
    msg.linear.x, msg.angular.z = v, w
    end = time.monotonic() + timeout_s
    while time.monotonic() < end and not rospy.is_shutdown():
        p = truth().pose.pose
        yaw = yaw_from_quaternion_msg(p.orientation)
        turned += abs(wrap_angle_scalar(yaw - yaw_prev))
        yaw_prev = yaw
        if distance_m is not None and math.hypot(p.position.x - p0.position.x,
                                                 p.position.y - p0.position.y) >= distance_m:
            break
        if angle_rad is not None and turned >= angle_rad:
            break
        cmd.publish(msg)
        rospy.sleep(period_s)
    cmd.publish(Twist())
