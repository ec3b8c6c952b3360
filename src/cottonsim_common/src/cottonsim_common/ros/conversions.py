"""Explicit conversions between the cores' numpy data and ROS messages, for every package.

Every message our nodes publish is built here, so the cores never see a
message type and the node modules stay short. Other packages' ROS layers reuse
the PointCloud2 and pose helpers (``cloud_to_xyz``, ``yaw_from_quaternion_msg``).

All stamps are ``rospy.Time`` in sim time; all arrays are numpy.
"""
from __future__ import annotations

import math
from typing import Iterable, Optional, Sequence

import numpy as np
import rospy
from geometry_msgs.msg import Quaternion, TransformStamped
from nav_msgs.msg import OccupancyGrid, Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import (CameraInfo, Image, Imu, JointState, LaserScan, NavSatFix, NavSatStatus,
                             PointCloud2, PointField)
from std_msgs.msg import Header

from cottonsim_common.transforms import pose_matrix, quaternion_to_yaw, yaw_to_quaternion

# PointField datatypes (sensor_msgs/PointField constants) keyed by numpy dtype.
_POINTFIELD_OF_DTYPE = {
    np.dtype(np.float32): PointField.FLOAT32,
    np.dtype(np.float64): PointField.FLOAT64,
    np.dtype(np.uint16): PointField.UINT16,
    np.dtype(np.uint32): PointField.UINT32,
    np.dtype(np.uint8): PointField.UINT8,
    np.dtype(np.int32): PointField.INT32,
}
_DTYPE_OF_POINTFIELD = {v: k for k, v in _POINTFIELD_OF_DTYPE.items()}


def header(stamp: rospy.Time, frame_id: str) -> Header:
    return Header(stamp=stamp, frame_id=frame_id)


def to_time(seconds: float) -> rospy.Time:
    """Sim time in seconds -> rospy.Time (exact nanoseconds, no float drift)."""
    return rospy.Time(nsecs=int(round(seconds * 1e9)))


def clock_msg(seconds: float) -> Clock:
    return Clock(clock=to_time(seconds))


def quaternion_msg(q_xyzw: Sequence[float]) -> Quaternion:
    return Quaternion(x=float(q_xyzw[0]), y=float(q_xyzw[1]), z=float(q_xyzw[2]), w=float(q_xyzw[3]))


def yaw_from_quaternion_msg(q: Quaternion) -> float:
    """Yaw [rad] of a quaternion message (rotation about z, REP-103)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def image_msg(pixels: np.ndarray, stamp: rospy.Time, frame_id: str) -> Image:
    """(H, W, 3) uint8 -> rgb8 Image; (H, W) uint8 -> mono8 Image."""
    if pixels.dtype != np.uint8:
        raise ValueError(f"image must be uint8, got {pixels.dtype}")
    pixels = np.ascontiguousarray(pixels)
    if pixels.ndim == 3 and pixels.shape[2] == 3:
        encoding, step = "rgb8", pixels.shape[1] * 3
    elif pixels.ndim == 2:
        encoding, step = "mono8", pixels.shape[1]
    else:
        raise ValueError(f"image must be (H, W, 3) or (H, W), got shape {pixels.shape}")
    return Image(header=header(stamp, frame_id), height=pixels.shape[0], width=pixels.shape[1],
                 encoding=encoding, is_bigendian=0, step=step, data=pixels.tobytes())


def image_to_array(msg: Image) -> np.ndarray:
    """Image message -> numpy array (rgb8/bgr8 -> (H, W, 3) RGB; mono8 -> (H, W)).

    Raises ValueError naming the encoding for anything else, and for a data
    buffer that does not match height x step (a truncated or empty frame).
    """
    if msg.height == 0 or msg.width == 0:
        raise ValueError("empty image (height or width is 0)")
    channels = {"rgb8": 3, "bgr8": 3, "mono8": 1}.get(msg.encoding)
    if channels is None:
        raise ValueError(f"unsupported image encoding '{msg.encoding}' (expected rgb8, bgr8 or mono8)")
    if len(msg.data) < msg.height * msg.step or msg.step < msg.width * channels:
        raise ValueError(f"image data has {len(msg.data)} bytes, expected {msg.height} x {msg.step}")
    buf = np.frombuffer(msg.data, dtype=np.uint8, count=msg.height * msg.step).reshape(msg.height, msg.step)
    buf = buf[:, : msg.width * channels]
    if channels == 1:
        return buf.reshape(msg.height, msg.width).copy()
    img = buf.reshape(msg.height, msg.width, 3)
    return img[:, :, ::-1].copy() if msg.encoding == "bgr8" else img.copy()


def camera_info_msg(width: int, height: int, k: np.ndarray, p: np.ndarray, stamp: rospy.Time,
                    frame_id: str) -> CameraInfo:
    """Pinhole camera without distortion ('plumb_bob' with zero coefficients)."""
    info = CameraInfo(header=header(stamp, frame_id), width=int(width), height=int(height))
    info.distortion_model = "plumb_bob"
    info.D = [0.0, 0.0, 0.0, 0.0, 0.0]
    info.K = [float(v) for v in np.asarray(k, dtype=float).reshape(9)]
    info.R = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    info.P = [float(v) for v in np.asarray(p, dtype=float).reshape(12)]
    return info


def cloud_msg(fields: "dict[str, np.ndarray]", stamp: rospy.Time, frame_id: str) -> PointCloud2:
    """Unorganised PointCloud2 from named per-point columns (same length each).

    Example: ``cloud_msg({'x': x, 'y': y, 'z': z, 'intensity': i, 'ring': r}, ...)``.
    Column dtypes decide the PointField types; packing is one numpy copy.
    """
    names = list(fields)
    n = len(next(iter(fields.values()))) if fields else 0
    dtype = np.dtype([(name, np.asarray(fields[name]).dtype) for name in names])
    packed = np.empty(n, dtype=dtype)
    point_fields = []
    for name in names:
        column = np.asarray(fields[name])
        if len(column) != n:
            raise ValueError(f"cloud column '{name}' has {len(column)} values, expected {n}")
        if column.dtype not in _POINTFIELD_OF_DTYPE:
            raise ValueError(f"cloud column '{name}' has unsupported dtype {column.dtype}")
        packed[name] = column
        point_fields.append(PointField(name=name, offset=dtype.fields[name][1],
                                       datatype=_POINTFIELD_OF_DTYPE[column.dtype], count=1))
    return PointCloud2(header=header(stamp, frame_id), height=1, width=n, fields=point_fields,
                       is_bigendian=False, point_step=dtype.itemsize, row_step=dtype.itemsize * n,
                       data=packed.tobytes(), is_dense=True)


def pack_rgb(rgb: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 -> (N,) float32 holding 0x00RRGGBB, as PCL's 'rgb' field."""
    rgb = np.asarray(rgb, dtype=np.uint32)
    packed = (rgb[:, 0] << 16) | (rgb[:, 1] << 8) | rgb[:, 2]
    return packed.astype(np.uint32).view(np.float32)


def xyzrgb_cloud_msg(xyz: np.ndarray, rgb: np.ndarray, stamp: rospy.Time, frame_id: str) -> PointCloud2:
    xyz = np.asarray(xyz, dtype=np.float32).reshape(-1, 3)
    return cloud_msg({"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "rgb": pack_rgb(rgb)}, stamp, frame_id)


def cloud_to_xyz(msg: PointCloud2, skip_nans: bool = True) -> np.ndarray:
    """PointCloud2 -> (N, 3) float32 x, y, z; NaN/inf points dropped by default."""
    offsets = {}
    for field in msg.fields:
        if field.name in ("x", "y", "z"):
            if field.datatype not in _DTYPE_OF_POINTFIELD:
                raise ValueError(f"field '{field.name}' has unsupported datatype {field.datatype}")
            offsets[field.name] = (field.offset, _DTYPE_OF_POINTFIELD[field.datatype])
    if len(offsets) != 3:
        raise ValueError(f"cloud lacks x/y/z fields (has {[f.name for f in msg.fields]})")
    n = msg.width * msg.height
    if n == 0:
        return np.zeros((0, 3), dtype=np.float32)
    if len(msg.data) < n * msg.point_step:
        raise ValueError(f"cloud data has {len(msg.data)} bytes, expected {n * msg.point_step}")
    dtype = np.dtype({"names": ["x", "y", "z"], "formats": [offsets[k][1] for k in "xyz"],
                      "offsets": [offsets[k][0] for k in "xyz"], "itemsize": msg.point_step})
    rec = np.frombuffer(msg.data, dtype=dtype, count=n)
    xyz = np.stack([rec["x"], rec["y"], rec["z"]], axis=1).astype(np.float32)
    if skip_nans:
        xyz = xyz[np.isfinite(xyz).all(axis=1)]
    return xyz


def laserscan_msg(ranges: np.ndarray, angle_min: float, angle_max: float, angle_increment: float,
                  range_min: float, range_max: float, scan_time: float, stamp: rospy.Time,
                  frame_id: str) -> LaserScan:
    return LaserScan(header=header(stamp, frame_id), angle_min=angle_min, angle_max=angle_max,
                     angle_increment=angle_increment, time_increment=0.0, scan_time=scan_time,
                     range_min=range_min, range_max=range_max,
                     ranges=np.asarray(ranges, dtype=np.float32).tolist(), intensities=[])


def imu_msg(orientation_xyzw, angular_velocity, linear_acceleration, orientation_var: float,
            angular_velocity_var: float, linear_acceleration_var: float, stamp: rospy.Time,
            frame_id: str) -> Imu:
    msg = Imu(header=header(stamp, frame_id))
    msg.orientation = quaternion_msg(orientation_xyzw)
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = map(float, angular_velocity)
    msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = map(
        float, linear_acceleration)
    msg.orientation_covariance = _diag3(orientation_var)
    msg.angular_velocity_covariance = _diag3(angular_velocity_var)
    msg.linear_acceleration_covariance = _diag3(linear_acceleration_var)
    return msg


def navsatfix_msg(lat_deg: float, lon_deg: float, alt_m: float, position_var_m2: float,
                  stamp: rospy.Time, frame_id: str, status: int = NavSatStatus.STATUS_FIX) -> NavSatFix:
    """NavSatFix with a diagonal known covariance of ``position_var_m2`` [m^2] per axis.

    status: NavSatStatus value (-1 no fix, 0 fix, 1 SBAS, 2 GBAS). A variance that is not finite
    (a fix without a position) gives COVARIANCE_TYPE_UNKNOWN and a zero covariance.
    """
    msg = NavSatFix(header=header(stamp, frame_id), latitude=float(lat_deg), longitude=float(lon_deg),
                    altitude=float(alt_m))
    msg.status.status = int(status)
    msg.status.service = NavSatStatus.SERVICE_GPS
    if math.isfinite(position_var_m2):
        msg.position_covariance = _diag3(position_var_m2)
        msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    else:
        msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
    return msg


def odometry_msg(position, orientation_xyzw, linear_velocity_body, angular_velocity_body,
                 pose_covariance: Optional[Iterable[float]], twist_covariance: Optional[Iterable[float]],
                 stamp: rospy.Time, frame_id: str, child_frame_id: str) -> Odometry:
    """Odometry with the twist in the child (body) frame, as REP-105 / nav_msgs define it."""
    msg = Odometry(header=header(stamp, frame_id), child_frame_id=child_frame_id)
    p = msg.pose.pose.position
    p.x, p.y, p.z = map(float, position)
    msg.pose.pose.orientation = quaternion_msg(orientation_xyzw)
    t = msg.twist.twist
    t.linear.x, t.linear.y, t.linear.z = map(float, linear_velocity_body)
    t.angular.x, t.angular.y, t.angular.z = map(float, angular_velocity_body)
    if pose_covariance is not None:
        msg.pose.covariance = [float(v) for v in pose_covariance]
    if twist_covariance is not None:
        msg.twist.covariance = [float(v) for v in twist_covariance]
    return msg


def transform_msg(parent: str, child: str, translation, rotation_xyzw, stamp: rospy.Time) -> TransformStamped:
    msg = TransformStamped()
    msg.header = header(stamp, parent)
    msg.child_frame_id = child
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = map(
        float, translation)
    msg.transform.rotation = quaternion_msg(rotation_xyzw)
    return msg


def transform_matrix(msg: TransformStamped) -> np.ndarray:
    """The 4x4 matrix of a geometry_msgs/TransformStamped (child frame -> parent frame)."""
    t, r = msg.transform.translation, msg.transform.rotation
    return pose_matrix((t.x, t.y, t.z), (r.x, r.y, r.z, r.w))


def joint_state_msg(names: Sequence[str], positions, velocities, stamp: rospy.Time) -> JointState:
    return JointState(header=header(stamp, ""), name=list(names),
                      position=[float(v) for v in positions], velocity=[float(v) for v in velocities],
                      effort=[])


def occupancy_grid_msg(grid, resolution_m: float, origin, frame_id: str, stamp: rospy.Time) -> OccupancyGrid:
    """int8 grid [iy, ix] (row 0 = smallest y) + resolution + origin (x, y, yaw) -> OccupancyGrid."""
    msg = OccupancyGrid()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    info = msg.info
    info.map_load_time = stamp
    info.resolution = float(resolution_m)
    info.height, info.width = int(grid.shape[0]), int(grid.shape[1])
    info.origin.position.x, info.origin.position.y = float(origin[0]), float(origin[1])
    q = yaw_to_quaternion(float(origin[2]))
    info.origin.orientation.x, info.origin.orientation.y = q[0], q[1]
    info.origin.orientation.z, info.origin.orientation.w = q[2], q[3]
    msg.data = grid.reshape(-1).astype("int8").tolist()
    return msg


def occupancy_grid_to_array(msg: OccupancyGrid):
    """OccupancyGrid -> (grid int8 [height, width], resolution [m], origin (x, y, yaw)).

    Raises ValueError for a message whose data length does not match its size
    or whose geometry holds NaN.
    """
    w, h = int(msg.info.width), int(msg.info.height)
    if w <= 0 or h <= 0:
        raise ValueError(f"map has no cells ({w} x {h})")
    data = msg.data
    if isinstance(data, (bytes, bytearray)):
        grid = np.frombuffer(data, dtype=np.int8)
    else:
        grid = np.asarray(data, dtype=np.int16)
    if grid.size != w * h:
        raise ValueError(f"map data has {grid.size} cells, expected {w} x {h} = {w * h}")
    o = msg.info.origin
    q = o.orientation
    if q.x == q.y == q.z == q.w == 0.0:
        yaw = 0.0                                        # an unset quaternion: no rotation
    else:
        yaw = quaternion_to_yaw(q.x, q.y, q.z, q.w)
    origin = (float(o.position.x), float(o.position.y), float(yaw))
    return grid.reshape(h, w).astype(np.int8), float(msg.info.resolution), origin


def finite_or_none(*values: float) -> bool:
    """True when every value is a finite float (guards against NaN in incoming messages)."""
    return all(math.isfinite(v) for v in values)


def _diag3(variance: float):
    return [float(variance), 0.0, 0.0, 0.0, float(variance), 0.0, 0.0, 0.0, float(variance)]
