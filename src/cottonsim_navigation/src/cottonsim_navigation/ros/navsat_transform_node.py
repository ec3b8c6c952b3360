"""navsat_transform: GPS fixes -> positions in the ENU map frame (robot_localization's node, planar).

The geodesy is ``cottonsim_navigation.geodesy.navsat.NavsatTransform``: the
map frame is the ENU tangent plane at the datum, x east, y *true* north, so
the datum fix is (0, 0) and the IMU's heading (true north) is the map's
heading as it is, at any datum (a UTM-grid map would be turned against it by
the meridian convergence; the geodesy module says why and by how much).
The IMU only tells the robot's ENU heading at the datum (published as the
datum yaw) and is converted with TF base_link <- imu_link, because the
simulated IMU is mounted rotated (paper Table 1: pitch -90, yaw 180 deg).
"""
from __future__ import annotations

import dataclasses
import math
import threading
from typing import Dict, Optional, Tuple

import rospy
import tf2_ros
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus

from cottonsim_common.pose import Pose2D, compose
from cottonsim_common.ros.conversions import finite_or_none, yaw_from_quaternion_msg
from cottonsim_common.ros.params import config_from_params, typed_param
from cottonsim_navigation.geodesy.navsat import NavsatConfig, NavsatTransform
from cottonsim_navigation.localization.gps_localization import enu_yaw, robot_yaw_from_imu


def _stamp_s(stamp) -> float:
    return stamp.to_sec()


class ImuYawReader:
    """The robot's (base_link's) yaw from IMU messages, using TF base_link <- <imu frame>.

    The rotation of each IMU frame is looked up once (it is static) and cached.
    ``robot_yaw(msg)`` returns None (and warns, throttled) while TF lacks the
    frame or when the message holds NaN / a zero quaternion.
    """

    def __init__(self, tf_buffer: tf2_ros.Buffer, base_frame: str, owner: str):
        self.tf_buffer = tf_buffer
        self.base_frame = base_frame
        self.owner = owner
        self._mount: Dict[str, Tuple[float, float, float, float]] = {}

    def mount(self, frame_id: str) -> Optional[Tuple[float, float, float, float]]:
        if not frame_id or frame_id == self.base_frame:
            return (0.0, 0.0, 0.0, 1.0)
        if frame_id not in self._mount:
            try:
                t = self.tf_buffer.lookup_transform(self.base_frame, frame_id, rospy.Time(0))
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
                rospy.logwarn_throttle(5.0, f"{self.owner}: no TF {self.base_frame} <- {frame_id} yet ({exc})")
                return None
            r = t.transform.rotation
            self._mount[frame_id] = (r.x, r.y, r.z, r.w)
        return self._mount[frame_id]

    def robot_yaw(self, msg: Imu) -> Optional[float]:
        q = msg.orientation
        if not finite_or_none(q.x, q.y, q.z, q.w) or (q.x == q.y == q.z == q.w == 0.0):
            rospy.logwarn_throttle(5.0, f"{self.owner}: IMU orientation with NaN or zero quaternion ignored")
            return None
        mount = self.mount(msg.header.frame_id)
        if mount is None:
            return None
        return robot_yaw_from_imu((q.x, q.y, q.z, q.w), mount)


class NavsatTransformNode:
    """GPS fix -> /odometry/gps in the ENU map frame at the datum.

    Subscriptions
      /navsat/fix            sensor_msgs/NavSatFix   GPS of base_link (fixes without a fix / with NaN ignored)
      /imu/data              sensor_msgs/Imu         heading at the datum (frame rotated by TF)
      /odometry/filtered     nav_msgs/Odometry       robot pose in odom (for /gps/filtered)
    Publications
      /odometry/gps          nav_msgs/Odometry       GPS position in ~map_frame (ENU, datum = origin),
                                                     child ~base_link_frame, orientation identity
                                                     (unknown, variance 1e6), at most ~frequency
      /gps/filtered          sensor_msgs/NavSatFix   robot pose (TF map <- odom + /odometry/filtered)
                                                     as lat/lon, only when ~publish_filtered_gps
      ~datum                 sensor_msgs/NavSatFix   latched: the datum position (lat, lon, alt)
    Parameters (private; robot_localization's names, defaults = the original's)
      ~frequency (float, 30): output rate [Hz]
      ~delay (float, 3.0): sim time to wait after the first fix before taking the datum [s]
      ~yaw_offset (float, 1.570796327): added to the IMU yaw so 0 means east [rad]
      ~magnetic_declination_radians (float, 0): [rad]
      ~zero_altitude (bool, true): z = 0; else z = altitude - datum altitude [m]
      ~wait_for_datum (bool, false) / ~datum ([lat deg, lon deg, yaw rad]): fixed datum instead of
          the first fix after the delay (yaw = the IMU heading there, like robot_localization's);
          a datum must lie in 80 S .. 84 N (UTM's range, robot_localization's too)
      ~publish_filtered_gps (bool, false)
      ~map_frame (str, map), ~odom_frame (str, odom), ~base_link_frame (str, base_link)
      ~datum_yaw (float, output): set once the datum is taken: the robot's ENU heading there [rad, 0 = east]
    TF used: base_link <- imu frame (static); map <- odom for /gps/filtered. Publishes none.
    """

    def __init__(self):
        config = config_from_params(NavsatConfig)
        self.config = config
        self.map_frame = typed_param("~map_frame", "map")
        self.odom_frame = typed_param("~odom_frame", "odom")
        self.base_frame = typed_param("~base_link_frame", "base_link")
        self.publish_filtered = typed_param("~publish_filtered_gps", False)
        # The geodesy core without a datum: this node sets it itself with map = ENU.
        self.transform = NavsatTransform(dataclasses.replace(config, datum=None, wait_for_datum=False))
        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.imu = ImuYawReader(self.tf_buffer, self.base_frame, "navsat_transform")
        self._lock = threading.Lock()
        self._imu_yaw: Optional[float] = None
        self._first_fix_s: Optional[float] = None
        self._latest_fix: Optional[NavSatFix] = None
        self._fix_is_new = False
        self._latest_odom: Optional[Odometry] = None
        self._datum_alt = 0.0
        self.odom_pub = rospy.Publisher("/odometry/gps", Odometry, queue_size=10)
        self.filtered_pub = rospy.Publisher("/gps/filtered", NavSatFix, queue_size=10) if self.publish_filtered else None
        self.datum_pub = rospy.Publisher("~datum", NavSatFix, queue_size=1, latch=True)
        rospy.Subscriber("/imu/data", Imu, self._on_imu, queue_size=10)
        rospy.Subscriber("/navsat/fix", NavSatFix, self._on_fix, queue_size=10)
        rospy.Subscriber("/odometry/filtered", Odometry, self._on_odom, queue_size=10)
        if config.datum is not None:
            lat, lon, yaw = config.datum
            self._set_datum(lat, lon, 0.0, yaw, rospy.Time.now())
        self.timer = rospy.Timer(rospy.Duration(1.0 / config.frequency), self._on_timer)

    # ------------------------------------------------------------------ inputs
    def _on_imu(self, msg: Imu):
        yaw = self.imu.robot_yaw(msg)
        if yaw is not None:
            with self._lock:
                self._imu_yaw = yaw

    def _on_fix(self, msg: NavSatFix):
        if msg.status.status == NavSatStatus.STATUS_NO_FIX:
            rospy.logwarn_throttle(5.0, "navsat_transform: fix with status NO_FIX ignored")
            return
        if not finite_or_none(msg.latitude, msg.longitude, msg.altitude):
            rospy.logwarn_throttle(5.0, "navsat_transform: fix with NaN latitude/longitude/altitude ignored")
            return
        if not (-90.0 <= msg.latitude <= 90.0 and -180.0 <= msg.longitude <= 180.0):
            rospy.logwarn_throttle(5.0, f"navsat_transform: fix out of range ({msg.latitude}, {msg.longitude}) ignored")
            return
        with self._lock:
            now_s = _stamp_s(msg.header.stamp)
            if self._first_fix_s is None or now_s < self._first_fix_s:
                self._first_fix_s = now_s                # (also restarts after a sim reset)
            self._latest_fix = msg
            self._fix_is_new = True
            if (not self.transform.has_datum and self._imu_yaw is not None
                    and now_s - self._first_fix_s >= self.config.delay):
                try:
                    self._set_datum(msg.latitude, msg.longitude, msg.altitude, self._imu_yaw, msg.header.stamp)
                except ValueError as exc:
                    rospy.logerr_throttle(5.0, f"navsat_transform: no datum taken at this fix: {exc}")

    def _on_odom(self, msg: Odometry):
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        if not finite_or_none(p.x, p.y, q.x, q.y, q.z, q.w):
            rospy.logwarn_throttle(5.0, "navsat_transform: odometry with NaN ignored")
            return
        with self._lock:
            self._latest_odom = msg

    # ------------------------------------------------------------------ datum
    def _set_datum(self, lat: float, lon: float, alt: float, imu_yaw_rad: float, stamp):
        """Anchor the map at (lat, lon): ENU axes, so the robot's map yaw there is its ENU heading."""
        c = self.config
        heading = imu_yaw_rad + c.magnetic_declination_radians + c.yaw_offset
        self.transform.set_datum(lat, lon, imu_yaw_rad, 0.0, 0.0, heading)
        self._datum_alt = float(alt)
        datum_yaw = enu_yaw(imu_yaw_rad, c.yaw_offset, c.magnetic_declination_radians)
        rospy.set_param("~datum_yaw", datum_yaw)
        msg = NavSatFix(latitude=float(lat), longitude=float(lon), altitude=float(alt))
        msg.header.stamp = stamp
        msg.header.frame_id = self.map_frame
        msg.status.status = NavSatStatus.STATUS_FIX
        msg.status.service = NavSatStatus.SERVICE_GPS
        self.datum_pub.publish(msg)
        rospy.loginfo("navsat_transform: datum lat %.8f lon %.8f, robot heading %.4f rad (ENU)", lat, lon, datum_yaw)

    # ------------------------------------------------------------------ outputs
    def _on_timer(self, _event):
        with self._lock:
            fix = self._latest_fix if self._fix_is_new else None
            self._fix_is_new = False
            odom = self._latest_odom
        if not self.transform.has_datum:
            return
        if fix is not None:
            self._publish_gps_odometry(fix)
        if self.filtered_pub is not None and odom is not None:
            self._publish_filtered(odom)

    def _publish_gps_odometry(self, fix: NavSatFix):
        try:
            x, y, z = self.transform.fix_to_map(fix.latitude, fix.longitude, fix.altitude)
        except ValueError as exc:
            rospy.logwarn_throttle(5.0, f"navsat_transform: fix not converted: {exc}")
            return
        if not self.config.zero_altitude:
            z = fix.altitude - self._datum_alt
        msg = Odometry()
        msg.header.stamp = fix.header.stamp
        msg.header.frame_id = self.map_frame
        msg.child_frame_id = self.base_frame
        msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = x, y, z
        msg.pose.pose.orientation.w = 1.0
        cov = [0.0] * 36
        fc = list(fix.position_covariance)
        for i in range(3):
            for j in range(3):
                cov[6 * i + j] = float(fc[3 * i + j]) if len(fc) == 9 and math.isfinite(fc[3 * i + j]) else 0.0
        for i in range(3, 6):
            cov[7 * i] = 1e6
        msg.pose.covariance = cov
        self.odom_pub.publish(msg)

    def _publish_filtered(self, odom: Odometry):
        try:
            t = self.tf_buffer.lookup_transform(self.map_frame, self.odom_frame, rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException):
            rospy.logwarn_throttle(10.0, f"navsat_transform: no TF {self.map_frame} <- {self.odom_frame} "
                                         "for /gps/filtered yet")
            return
        tr = t.transform
        map_odom = Pose2D(tr.translation.x, tr.translation.y, yaw_from_quaternion_msg(tr.rotation))
        p = odom.pose.pose
        robot = compose(map_odom, Pose2D(p.position.x, p.position.y, yaw_from_quaternion_msg(p.orientation)))
        lat, lon = self.transform.map_to_latlon(robot.x_m, robot.y_m)
        msg = NavSatFix(latitude=lat, longitude=lon, altitude=0.0 if self.config.zero_altitude else self._datum_alt)
        msg.header.stamp = odom.header.stamp
        msg.header.frame_id = self.base_frame
        msg.status.status = NavSatStatus.STATUS_FIX
        msg.status.service = NavSatStatus.SERVICE_GPS
        msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
        self.filtered_pub.publish(msg)
