"""Message conversions of the move_base node: TF transforms, goal checks, paths and costmaps as ROS messages."""
from __future__ import annotations

import math
from typing import Tuple

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import OccupancyGrid, Path

from cottonsim_common.pose import Pose2D
from cottonsim_common.transforms import yaw_to_quaternion
from cottonsim_navigation.core.grid import GridSpec
from cottonsim_navigation.planning.costmap import Costmap2D
from cottonsim_common.ros import conversions as conv


def transform_to_pose2d(t) -> Pose2D:
    """geometry_msgs/Transform (planar part) -> Pose2D."""
    return Pose2D(t.translation.x, t.translation.y, conv.yaw_from_quaternion_msg(t.rotation))


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
        ps.pose.orientation = conv.quaternion_msg(yaw_to_quaternion(float(yaw)))
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
