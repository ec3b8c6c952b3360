"""gps_localization: TF map -> odom from the GPS position and the IMU heading.

Stands in for robot_localization's second (map-frame) EKF of the original GPS
mode. The filter is ``cottonsim_navigation.localization.gps_localization.
GpsLocalizer``; this node pairs each measurement with the odometry pose
(TF odom -> base_link) at the measurement's own stamp and publishes the result,
and says when the GPS is lost (``~localized``, ``~status``) so that the
navigator can pause.
"""
from __future__ import annotations

import collections
import math
import threading
from typing import Deque, Optional, Tuple

import rospy
import tf2_ros
from cottonsim_msgs.msg import GpsLocalizationStatus
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu
from std_msgs.msg import Bool

from cottonsim_common.pose import Pose2D
from cottonsim_common.transforms import yaw_to_quaternion
from cottonsim_navigation.localization.gps_localization import (REJECTED_JUMP, REJECTED_VARIANCE,
                                                                STATE_DEAD_RECKONING, STATE_GPS, STATE_GPS_LOST,
                                                                STATE_WAITING, GpsLocalizationConfig, GpsLocalizer,
                                                                enu_yaw)
from cottonsim_common.ros.conversions import finite_or_none, yaw_from_quaternion_msg
from cottonsim_common.ros.params import config_from_params, typed_param
from cottonsim_common.ros.tf import PlanarTransformBroadcaster
from cottonsim_navigation.ros.navsat_transform_node import ImuYawReader

_TF_ERRORS = (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException)


class GpsLocalizationNode:

    """Publishes TF map -> odom so that map -> base_link follows the GPS and the IMU heading.

    Subscriptions
      /odometry/gps   nav_msgs/Odometry   GPS position of base_link in the map (navsat_transform, which drops
                                          NO_FIX fixes) with its covariance: x/y variance gates and weights it
      /imu/data       sensor_msgs/Imu     absolute heading (IMU yaw + ~yaw_offset + declination = ENU)
    Publications
      ~pose           nav_msgs/Odometry   the robot's map pose after each GPS update (for logging)
      ~localized      std_msgs/Bool       latched, on change: false while no usable fix for longer than
                                          ~dead_reckoning_limit_s (gps_lost), true otherwise once the first fix
                                          is used; the GPS navigator pauses on false (its ~localized_topic)
      ~status         cottonsim_msgs/GpsLocalizationStatus  at ~status_frequency: state (waiting, gps,
                                          dead_reckoning, gps_lost), time since the last fix used, the map pose
                                          (latest odometry), fixes used / refused
    TF
      publishes ~map_frame -> ~odom_frame at ~frequency, post-dated by ~transform_tolerance_s,
      only after the first GPS position (nothing before);
      uses ~odom_frame -> ~base_link_frame (odometry, looked up at each measurement's stamp)
      and base_link <- imu frame (static).
    Parameters (private)
      ~frequency (float, 30): TF rate [Hz]
      ~position_time_constant_s (float, 0.5): GPS blending time constant [s] (0 = follow each fix)
      ~yaw_time_constant_s (float, 1.0): IMU heading blending time constant [s]
      ~yaw_offset (float, 1.570796327): [rad], as navsat_transform's
      ~magnetic_declination_radians (float, 0): [rad]
      ~max_dt_s (float, 1.0): longest gap used for a blending weight [s]
      ~transform_tolerance_s (float, 0.1): post-dating of the published transform [s]
      ~reference_fix_variance_m2 (float, 0.0025): fixes up to this variance [m^2] use the time constant
          as it is, noisier ones one scaled by variance / this
      ~max_fix_variance_m2 (float, 0.25): fixes with a larger variance [m^2] are refused (degraded fix)
      ~jump_gate_m (float, 1.0), ~jump_gate_timeout_s (float, 5.0): a fix farther than the gate + 3 sigma
          from the estimate is refused (multipath), unless no fix was used for the time-out [s]
      ~dead_reckoning_limit_s (float, 20.0): without a used fix for longer than this [s], gps_lost
      ~status_frequency (float, 5.0): ~status rate [Hz]
      ~map_frame (map), ~odom_frame (odom), ~base_link_frame (base_link)
    Messages with NaN (or a negative variance) are ignored with a warning. Between fixes (an outage, refused
    fixes) map -> odom is held, so map -> base_link follows the odometry (wheels + IMU): dead reckoning.
    """

    _IMU_MAX_WAIT_S = 0.2       # how long an IMU heading may wait for its odometry TF [s, sim time]

    def __init__(self):
        self.config = config_from_params(GpsLocalizationConfig)
        self.map_frame = typed_param("~map_frame", "map")
        self.odom_frame = typed_param("~odom_frame", "odom")
        self.base_frame = typed_param("~base_link_frame", "base_link")
        self.filter = GpsLocalizer(self.config)
        self._lock = threading.Lock()
        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.map_to_odom_tf = PlanarTransformBroadcaster(self.map_frame, self.odom_frame)
        self.imu = ImuYawReader(self.tf_buffer, self.base_frame, "gps_localization")
        self.pose_pub = rospy.Publisher("~pose", Odometry, queue_size=10)
        self.localized_pub = rospy.Publisher("~localized", Bool, queue_size=2, latch=True)
        self.status_pub = rospy.Publisher("~status", GpsLocalizationStatus, queue_size=5)
        self._state: Optional[str] = None
        self._localized: Optional[bool] = None
        self._last_fix_s = 0.0          # when dead reckoning began: the last fix used before it [s]
        self._last_status_s = -math.inf
        self._imu_queue: Deque[Tuple[rospy.Time, float]] = collections.deque(maxlen=64)
        rospy.Subscriber("/odometry/gps", Odometry, self._on_gps, queue_size=20)
        rospy.Subscriber("/imu/data", Imu, self._on_imu, queue_size=20)
        self.timer = rospy.Timer(rospy.Duration(1.0 / self.config.frequency), self._on_timer)

    def _odom_pose(self, stamp: rospy.Time) -> Optional[Pose2D]:
        """odom -> base_link at ``stamp`` (waits briefly for the odometry to catch up)."""
        try:
            t = self.tf_buffer.lookup_transform(self.odom_frame, self.base_frame, stamp, rospy.Duration(0.2))
        except _TF_ERRORS as exc:
            rospy.logwarn_throttle(5.0, f"gps_localization: no TF {self.odom_frame} -> {self.base_frame} "
                                        f"at {stamp.to_sec():.3f}: {exc}")
            return None
        tr = t.transform
        return Pose2D(tr.translation.x, tr.translation.y, yaw_from_quaternion_msg(tr.rotation))

    def _on_imu(self, msg: Imu):
        """Queue the heading; use every queued one whose odometry pose exists by now.

        The IMU (50 Hz) often arrives just before the odometry TF of the same
        stamp. Waiting for it in the callback (as for GPS fixes) polls the sim
        clock and was this node's largest CPU cost; instead a heading waits in
        a short queue (up to ~0.2 s, ``_IMU_MAX_WAIT_S``) and is used, in stamp
        order, by a later IMU callback once the TF has arrived.
        """
        yaw = self.imu.robot_yaw(msg)
        if yaw is None:
            return
        heading = enu_yaw(yaw, self.config.yaw_offset, self.config.magnetic_declination_radians)
        self._imu_queue.append((msg.header.stamp, heading))
        newest = msg.header.stamp.to_sec()
        while self._imu_queue:
            stamp, h = self._imu_queue[0]
            odom = self._odom_pose_now(stamp)
            if odom is None:
                if newest - stamp.to_sec() <= self._IMU_MAX_WAIT_S:
                    return                                  # its odometry is not here yet: later
                self._imu_queue.popleft()                   # too old: give up on it
                rospy.logwarn_throttle(5.0, f"gps_localization: no TF {self.odom_frame} -> {self.base_frame} "
                                            f"for an IMU heading after {self._IMU_MAX_WAIT_S} s; dropped")
                continue
            self._imu_queue.popleft()
            with self._lock:
                self.filter.update_heading(stamp.to_sec(), odom, h)

    def _odom_pose_now(self, stamp: rospy.Time) -> Optional[Pose2D]:
        """odom -> base_link at ``stamp`` if TF has it already (no waiting), else None."""
        try:
            t = self.tf_buffer.lookup_transform(self.odom_frame, self.base_frame, stamp)
        except _TF_ERRORS:
            return None
        tr = t.transform
        return Pose2D(tr.translation.x, tr.translation.y, yaw_from_quaternion_msg(tr.rotation))

    def _on_gps(self, msg: Odometry):
        p = msg.pose.pose.position
        if not finite_or_none(p.x, p.y):
            rospy.logwarn_throttle(5.0, "gps_localization: /odometry/gps with NaN ignored")
            return
        if msg.header.frame_id and msg.header.frame_id.lstrip("/") != self.map_frame:
            rospy.logwarn_throttle(5.0, f"gps_localization: /odometry/gps in frame '{msg.header.frame_id}', "
                                        f"expected '{self.map_frame}'; ignored")
            return
        cov = msg.pose.covariance
        variance = max(cov[0], cov[7])
        if not (math.isfinite(variance) and variance >= 0.0):
            rospy.logwarn_throttle(5.0, f"gps_localization: /odometry/gps with variance {variance} ignored")
            return
        odom = self._odom_pose(msg.header.stamp)
        if odom is None:
            return
        with self._lock:
            first = not self.filter.ready
            used = self.filter.update_gps(msg.header.stamp.to_sec(), odom, p.x, p.y, variance)
            pose = self.filter.map_pose(odom)
            why = self.filter.last_rejection
        if not used:
            if why == REJECTED_VARIANCE:
                rospy.logwarn_throttle(5.0, f"gps_localization: degraded fix (variance {variance:.3g} m^2 > "
                                            f"{self.config.max_fix_variance_m2} m^2) not used")
            elif why == REJECTED_JUMP:
                rospy.logwarn_throttle(5.0, "gps_localization: fix too far from the pose (a jump?) not used")
            else:
                rospy.logwarn_throttle(5.0, "gps_localization: waiting for an IMU heading before the first fix")
            return
        if first:
            rospy.loginfo("gps_localization: first fix, robot at map (%.3f, %.3f, %.3f rad)",
                          pose.x_m, pose.y_m, pose.yaw_rad)
        out = Odometry()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = self.map_frame
        out.child_frame_id = self.base_frame
        out.pose.pose.position.x, out.pose.pose.position.y = pose.x_m, pose.y_m
        q = yaw_to_quaternion(pose.yaw_rad)
        o = out.pose.pose.orientation
        o.x, o.y, o.z, o.w = q
        self.pose_pub.publish(out)

    def _on_timer(self, _event):
        now = rospy.Time.now()
        now_s = now.to_sec()
        with self._lock:
            t = self.filter.map_to_odom
            state = self.filter.state(now_s)
            localized = self.filter.localized(now_s)
            since_fix = self.filter.seconds_since_fix(now_s)
        self._follow_state(state, localized, since_fix, now_s)
        if now_s - self._last_status_s >= 1.0 / self.config.status_frequency or now_s < self._last_status_s:
            self._last_status_s = now_s
            self._publish_status(state, localized, since_fix)
        if t is None:
            return
        self.map_to_odom_tf.send(t, now + rospy.Duration(self.config.transform_tolerance_s))


    def _follow_state(self, state: str, localized: bool, since_fix_s: float, now_s: float):
        """Log state changes; publish ~localized when it changes (latched)."""
        if state != self._state:
            previous, self._state = self._state, state
            if state == STATE_DEAD_RECKONING:
                self._last_fix_s = now_s - since_fix_s
                rospy.logwarn("gps_localization: no usable GPS fix for %.1f s: dead reckoning on the odometry "
                              "(limit %.1f s)", since_fix_s, self.config.dead_reckoning_limit_s)
            elif state == STATE_GPS_LOST:
                rospy.logwarn("gps_localization: GPS LOST: no usable fix for %.1f s (limit %.1f s); "
                              "not localised until a fix is back", since_fix_s, self.config.dead_reckoning_limit_s)
            elif state == STATE_GPS and previous in (STATE_DEAD_RECKONING, STATE_GPS_LOST):
                rospy.loginfo("gps_localization: GPS fix back after %.1f s without one", now_s - self._last_fix_s)
        if state != STATE_WAITING and localized != self._localized:
            self._localized = localized
            self.localized_pub.publish(Bool(data=localized))

    def _publish_status(self, state: str, localized: bool, since_fix_s: float):
        msg = GpsLocalizationStatus(state=state, localized=localized, seconds_since_fix=since_fix_s)
        with self._lock:
            msg.fixes_used = self.filter.gps_updates
            msg.fixes_rejected_variance = self.filter.rejected[REJECTED_VARIANCE]
            msg.fixes_rejected_jump = self.filter.rejected[REJECTED_JUMP]
        msg.header.frame_id = self.map_frame
        if self.filter.ready:
            try:
                tf = self.tf_buffer.lookup_transform(self.odom_frame, self.base_frame, rospy.Time(0))
            except _TF_ERRORS:
                tf = None
            if tf is not None:
                tr = tf.transform
                odom = Pose2D(tr.translation.x, tr.translation.y, yaw_from_quaternion_msg(tr.rotation))
                with self._lock:
                    pose = self.filter.map_pose(odom)
                msg.header.stamp = tf.header.stamp
                msg.pose.x, msg.pose.y, msg.pose.theta = pose.x_m, pose.y_m, pose.yaw_rad
        if msg.header.stamp.is_zero():
            msg.header.stamp = rospy.Time.now()
            msg.pose.x = msg.pose.y = msg.pose.theta = math.nan
        self.status_pub.publish(msg)
