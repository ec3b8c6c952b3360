"""slam_gmapping: build the occupancy map of the farm while driving (the ROS slam_gmapping node).

The mapper is ``cottonsim_navigation.mapping.slam.RbpfSlam`` (a gmapping-style
Rao-Blackwellised particle filter); this node converts scans and TF to its
types and publishes the map and the map -> odom correction.
"""
from __future__ import annotations

import bisect
import math
import threading
import time
from collections import deque
from typing import Optional

import numpy as np
import rospy
import tf2_ros
from nav_msgs.msg import MapMetaData, OccupancyGrid, Odometry
from nav_msgs.srv import GetMap, GetMapResponse
from sensor_msgs.msg import Imu, LaserScan
from std_msgs.msg import Float64

from cottonsim_common.pose import Pose2D, compose
from cottonsim_common.ros.conversions import occupancy_grid_msg
from cottonsim_common.ros.conversions import yaw_from_quaternion_msg
from cottonsim_common.ros.params import config_from_params, typed_param
from cottonsim_common.ros.tf import PlanarTransformBroadcaster
from cottonsim_common.transforms import quaternion_to_matrix, yaw_to_quaternion
from cottonsim_navigation.mapping.scan_matcher import ScanMatcherConfig
from cottonsim_navigation.mapping.slam import RbpfSlam, SlamConfig
from cottonsim_navigation.ros.amcl_node import TfPoseReader, scan_and_odom


def base_yaw_from_imu(q_world_imu, r_base_imu: np.ndarray) -> Optional[float]:
    """Yaw [rad] of base_link from an IMU orientation (x, y, z, w) of the IMU frame and the mount rotation
    base_link <- imu frame; None for an unusable (zero or non-finite) quaternion."""
    q = np.asarray(q_world_imu, dtype=float)
    n = float(np.linalg.norm(q))
    if not (np.all(np.isfinite(q)) and n > 1e-6):
        return None
    r = quaternion_to_matrix(q / n) @ r_base_imu.T
    return math.atan2(r[1, 0], r[0, 0])


class SlamNode:
    """Maps with the laser and publishes the map and TF map -> odom.

    Subscriptions
      ~scan_topic (default /scan_360)  sensor_msgs/LaserScan  the full-circle slice of the VLP-16 (the
          original's +/-45 deg /scan gives maps of IoU 0.25-0.33 against ground truth, 360 deg 0.45-0.50)
      ~imu_topic (default /imu/data; '' = none)  sensor_msgs/Imu  its orientation's yaw holds the particles'
          heading (mapping.heading_fusion; the yaw of the sample nearest each scan's stamp); samples whose
          orientation_covariance[0] is -1 (no orientation) are ignored
      ~odom_topic (default /odometry/filtered; '' = none)  nav_msgs/Odometry  republished as ~map_odometry
    Publications
      map            nav_msgs/OccupancyGrid  latched, every ~map_update_interval once something changed
      map_metadata   nav_msgs/MapMetaData    latched
      ~entropy       std_msgs/Float64        entropy of the particle weights [nats] after each processed scan
      ~map_odometry  nav_msgs/Odometry       (not in gmapping) each ~odom_topic message carried into the map
          frame with the current map -> odom correction (frame map, child base_link; twist unchanged): the
          robot's SLAM pose at the odometry's rate, for a driver that steers on it (mapping.launch)
    Services
      dynamic_map    nav_msgs/GetMap         the current map
    TF
      publishes ~map_frame -> ~odom_frame every ~transform_publish_period, post-dated by that period;
      uses ~odom_frame -> ~base_frame at each scan's stamp and ~base_frame -> the scan's frame (static).
      The map frame is the odometry frame at the first scan (map -> odom starts as identity).
    Parameters (private; config/slam.yaml documents each with unit and the original's value)
      SlamConfig fields under their names (~particles, ~max_urange_m, ~max_range_m, ~linear_update_m,
      ~angular_update_rad, ~temporal_update_s, ~resample_threshold, ~delta_m, ~xmin_m.., ~srr, ~srt,
      ~str_, ~stt, ~lsigma_m, ~ogain, ~lskip, ~match_max_beams, ~logodds_*, ~occupied_prob,
      ~heading_tau_s, ~heading_track_rate, ~heading_sigma_rad); ScanMatcherConfig fields under ~matcher/ (e.g. ~matcher/sigma_m);
      ~scan_topic (/scan_360), ~map_update_interval (0.5 s), ~transform_publish_period (0.05 s),
      ~map_frame (map), ~odom_frame (odom), ~base_frame (base_link), ~seed (-1 = random),
      ~tf_start_delay_s (1.0): map -> odom is first published this long (sim time) after the first map, so
      that nodes which start on TF (the waypoint navigators) find move_base holding a map [s];
      ~publish_full_extent (false): publish the whole xmin_m..ymax_m extent (unknown where unobserved)
      instead of only the observed tiles; with an extent around the farm this lets move_base accept
      goals in areas not yet seen (mapping.launch).
    Scans with non-finite angles are ignored with a warning; NaN ranges are invalid beams.
    """

    def __init__(self):
        matcher = config_from_params(ScanMatcherConfig, "~matcher/")
        self.config = config_from_params(SlamConfig, overrides={"matcher": matcher})
        self.scan_topic = typed_param("~scan_topic", "/scan_360")
        self.imu_topic = typed_param("~imu_topic", "/imu/data")
        self._imu = deque(maxlen=100)         # (stamp_s, base yaw) of recent IMU samples
        self._imu_mount: Optional[np.ndarray] = None
        self.map_update_interval_s = typed_param("~map_update_interval", 0.5, minimum=0.01)
        self.tf_period_s = typed_param("~transform_publish_period", 0.05, minimum=0.001)
        self.map_frame = typed_param("~map_frame", "map")
        self.odom_frame = typed_param("~odom_frame", "odom")
        self.base_frame = typed_param("~base_frame", "base_link")
        seed = typed_param("~seed", -1)
        self.full_extent = typed_param("~publish_full_extent", False)
        self.tf_start_delay_s = typed_param("~tf_start_delay_s", 1.0, minimum=0.0)
        self._tf_start: Optional[rospy.Time] = None
        self.slam = RbpfSlam(self.config, np.random.default_rng(None if seed < 0 else seed))
        self._lock = threading.Lock()
        self._map_dirty = False
        self._started = False
        self._map_msg: Optional[OccupancyGrid] = None
        self.updates = 0
        self.update_wall_s = 0.0

        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.map_to_odom_tf = PlanarTransformBroadcaster(self.map_frame, self.odom_frame)
        self.poses = TfPoseReader(self.tf_buffer, "slam_gmapping")
        self.map_pub = rospy.Publisher("map", OccupancyGrid, queue_size=1, latch=True)
        self.meta_pub = rospy.Publisher("map_metadata", MapMetaData, queue_size=1, latch=True)
        self.entropy_pub = rospy.Publisher("~entropy", Float64, queue_size=5)
        self.service = rospy.Service("dynamic_map", GetMap, self._on_dynamic_map)
        rospy.Subscriber(self.scan_topic, LaserScan, self._on_scan, queue_size=1, buff_size=2 ** 22)
        if self.imu_topic:
            rospy.Subscriber(self.imu_topic, Imu, self._on_imu, queue_size=50)
        self.odom_topic = typed_param("~odom_topic", "/odometry/filtered")
        self.map_odom_pub = rospy.Publisher("~map_odometry", Odometry, queue_size=5)
        if self.odom_topic:
            rospy.Subscriber(self.odom_topic, Odometry, self._on_odom, queue_size=5)
        self.map_timer = rospy.Timer(rospy.Duration(self.map_update_interval_s), self._on_map_timer)
        self.tf_timer = rospy.Timer(rospy.Duration(self.tf_period_s), self._on_tf_timer)
        rospy.loginfo("slam_gmapping: scans from %s, %d particles", self.scan_topic, self.config.particles)

    def _on_odom(self, msg: Odometry):
        if not self._started:
            return
        p = msg.pose.pose
        m = compose(self.slam.map_to_odom, Pose2D(p.position.x, p.position.y, yaw_from_quaternion_msg(p.orientation)))
        out = Odometry()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = self.map_frame
        out.child_frame_id = msg.child_frame_id or self.base_frame
        out.pose.pose.position.x, out.pose.pose.position.y = m.x_m, m.y_m
        q = yaw_to_quaternion(m.yaw_rad)
        o = out.pose.pose.orientation
        o.x, o.y, o.z, o.w = q
        out.pose.covariance = msg.pose.covariance
        out.twist = msg.twist
        self.map_odom_pub.publish(out)

    def _on_imu(self, msg: Imu):
        if msg.orientation_covariance[0] < 0:
            return
        if self._imu_mount is None:
            try:
                t = self.tf_buffer.lookup_transform(self.base_frame, msg.header.frame_id, rospy.Time(0))
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException):
                rospy.logwarn_throttle(5.0, f"slam_gmapping: no TF {self.base_frame} -> {msg.header.frame_id} yet")
                return
            r = t.transform.rotation
            self._imu_mount = quaternion_to_matrix((r.x, r.y, r.z, r.w))
        o = msg.orientation
        yaw = base_yaw_from_imu((o.x, o.y, o.z, o.w), self._imu_mount)
        if yaw is None:
            rospy.logwarn_throttle(5.0, "slam_gmapping: IMU sample with an unusable orientation ignored")
            return
        self._imu.append((msg.header.stamp.to_sec(), yaw))

    def _imu_yaw_at(self, stamp_s: float, max_gap_s: float = 0.1) -> Optional[float]:
        """Yaw of the IMU sample nearest ``stamp_s`` (None if none within max_gap_s)."""
        samples = list(self._imu)
        if not samples:
            return None
        i = bisect.bisect_left([t for t, _ in samples], stamp_s)
        best = min((samples[j] for j in (i - 1, i) if 0 <= j < len(samples)), key=lambda s_: abs(s_[0] - stamp_s))
        return best[1] if abs(best[0] - stamp_s) <= max_gap_s else None

    def _on_scan(self, msg: LaserScan):
        read = scan_and_odom(self.poses, msg, self.base_frame, self.odom_frame, "slam_gmapping")
        if read is None:
            return
        scan, odom = read
        t0 = time.perf_counter()
        with self._lock:
            result = self.slam.update(odom, scan, msg.header.stamp.to_sec(),
                                      self._imu_yaw_at(msg.header.stamp.to_sec()) if self.imu_topic else None)
            first = not self._started
            self._started = True
        if result.updated:
            self.updates += 1
            self.update_wall_s += time.perf_counter() - t0
            self._map_dirty = True
            if first:      # the map goes out with the first TF: clients that wait for TF find a map too
                self._on_map_timer(None)
            self.entropy_pub.publish(Float64(data=result.entropy))
            if self.updates % 50 == 0:
                rospy.loginfo("slam_gmapping: %d updates, %.0f ms each on average, N_eff %.1f", self.updates,
                              1000.0 * self.update_wall_s / self.updates, result.neff)

    def _build_map_msg(self) -> Optional[OccupancyGrid]:
        with self._lock:
            if not self._started:
                return None
            grid, spec = self.slam.occupancy(crop=not self.full_extent)
        return occupancy_grid_msg(grid, spec.resolution_m, (spec.origin_x_m, spec.origin_y_m, 0.0), self.map_frame,
                                  rospy.Time.now())

    def _on_map_timer(self, _event):
        if not self._map_dirty:
            return
        self._map_dirty = False
        msg = self._build_map_msg()
        if msg is None:
            return
        self._map_msg = msg
        self.meta_pub.publish(msg.info)
        self.map_pub.publish(msg)
        if self._tf_start is None:
            self._tf_start = rospy.Time.now() + rospy.Duration(self.tf_start_delay_s)

    def _on_dynamic_map(self, _req):
        msg = self._build_map_msg()
        if msg is None:
            raise rospy.ServiceException("no map yet: no scan has been processed")
        return GetMapResponse(map=msg)

    def _on_tf_timer(self, _event):
        if not self._started or self._tf_start is None or rospy.Time.now() < self._tf_start:
            return
        self.map_to_odom_tf.send(self.slam.map_to_odom, rospy.Time.now() + rospy.Duration(self.tf_period_s))
