"""GPS waypoint navigator: the paper's GPS-based route, one move_base goal per "lat lon" waypoint.

Replaces the original's GPS node, which listened on the wrong topic, sent the
robot's own position as goal and took the goal yaw from the y coordinate.
Here each waypoint is converted into the map frame (ENU at the GPS datum,
the frame the GPS localisation publishes map -> odom in) with the same
geodesy as navsat_transform, and faces the next waypoint.
"""
from __future__ import annotations

import math
import threading
from typing import List, Optional

import rospy
from sensor_msgs.msg import NavSatFix, NavSatStatus

from cottonsim_navigation.geodesy.navsat import NavsatConfig, NavsatTransform
from cottonsim_navigation.ros.waypoint_navigator import NavigatorStartError, WaypointNavigatorBase
from cottonsim_navigation.waypoints.files import MapWaypoint, WaypointFileError, load_gps_lanes, load_gps_waypoints
from cottonsim_navigation.waypoints.goals import gps_goals_in_map, gps_lanes_in_map


class GpsWaypointNavigatorNode(WaypointNavigatorBase):
    """Follows a GPS route ("lat lon" lines or YAML) through move_base.

    Everything of :class:`~cottonsim_navigation.ros.waypoint_navigator.WaypointNavigatorBase`
    (move_base action client, /battery/state, ~state, ~on_failure, ~return_home_percentage, ...), plus:

    Subscriptions
      /navsat_transform/datum (sensor_msgs/NavSatFix, latched, ~datum_topic): lat/lon of the map
        origin, published by navsat_transform when it takes its datum. The route starts only once
        it is known (and TF map -> base_link exists).
      /navsat/fix (sensor_msgs/NavSatFix, ~fix_topic): used only when ~datum_topic is "": the first
        good fix (status >= STATUS_FIX, finite) after TF map -> base_link exists pins lat/lon to the
        robot's map pose. NaN fixes are ignored.
    The map frame is ENU (x east, y true north) at the datum, as navsat_transform builds it; the
    waypoints are converted with the same core (geodesy.navsat.NavsatTransform, the tangent plane at
    the datum). A datum outside 80 S .. 84 N or a waypoint over 100 km from it ends the route with
    the reason in ~state.
    GPS lost: ~localized_topic defaults to /gps_localization/localized, false once gps_localization has had
    no usable fix for longer than its ~dead_reckoning_limit_s (20 s); the route then pauses (the goal is
    cancelled and held, the robot stops; ~state "paused", reason "GPS lost ...") and goes on with the same
    goal when the fix is back. Shorter outages are driven through on the odometry.
    Parameters (private)
      ~datum (list [lat deg, lon deg], unset): lat/lon of the map origin (0, 0); when set, neither
        topic is needed
      ~datum_topic (str, "/navsat_transform/datum"), ~fix_topic (str, "/navsat/fix")
      ~lanes_file (str, ""): lane centre lines, 'lat lon lat lon' per lane (config/waypoints/
        farm_lanes_gps.txt is the default farm's); when set, every waypoint within ~lane_snap_max_m
        (float, 0.5 m) sideways of a lane, between ~lane_snap_margin_m (float, 5.0 m) before its start
        and after its end, is moved onto the lane's centre line before the route starts
        (waypoints.goals.snap_to_lanes); "" = the waypoints as they are
    Home = the robot's map pose when the route starts (the first fix, i.e. the datum, at map ~(0, 0),
    with the start heading).
    """

    NAME = "gps_waypoint_navigator"
    DEFAULT_LOCALIZED_TOPIC = "/gps_localization/localized"
    LOST_REASON = "GPS lost: no usable fix for longer than the dead-reckoning limit"
    LOST_HINT = "it goes on once gps_localization has a usable fix again (/gps_localization/status)"

    def __init__(self):
        self.fix_topic = str(rospy.get_param("~fix_topic", "/navsat/fix"))
        self.datum_topic = str(rospy.get_param("~datum_topic", "/navsat_transform/datum"))
        datum = rospy.get_param("~datum", None)
        self.lanes_file = str(rospy.get_param("~lanes_file", ""))
        self.lane_snap_max_m = float(rospy.get_param("~lane_snap_max_m", 0.5))
        self.lane_snap_margin_m = float(rospy.get_param("~lane_snap_margin_m", 5.0))
        for name in ("lane_snap_max_m", "lane_snap_margin_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise NavigatorStartError(f"~{name} must be finite and >= 0, got {v}")
        self.lanes = None
        if self.lanes_file:
            try:
                self.lanes = load_gps_lanes(self.lanes_file)
            except WaypointFileError as exc:
                raise NavigatorStartError(f"bad lanes file {exc}") from None
        # ENU map: the transform's rotation must be zero, so no IMU yaw offset is applied here
        self.navsat = NavsatTransform(NavsatConfig(yaw_offset=0.0, magnetic_declination_radians=0.0))
        self._fix_lock = threading.Lock()
        self._fix: Optional[tuple] = None
        if datum not in (None, "", []):
            try:
                lat, lon = float(datum[0]), float(datum[1])
                self.navsat.set_datum(lat, lon, 0.0, 0.0, 0.0, 0.0)
            except (TypeError, ValueError, IndexError) as exc:
                raise NavigatorStartError(f"~datum must be [lat deg, lon deg], got {datum!r} ({exc})") from None
        super().__init__()
        if not self.navsat.has_datum:
            if self.datum_topic:
                rospy.Subscriber(self.datum_topic, NavSatFix, self._on_datum, queue_size=2)
            else:
                rospy.Subscriber(self.fix_topic, NavSatFix, self._on_fix, queue_size=5)

    def load_route(self, path: str) -> list:
        return load_gps_waypoints(path)

    @staticmethod
    def _latlon(msg: NavSatFix, what: str) -> Optional[tuple]:
        if not (math.isfinite(msg.latitude) and math.isfinite(msg.longitude)):
            rospy.logwarn_throttle(10.0, f"gps_waypoint_navigator: {what} with NaN latitude/longitude ignored")
            return None
        if not (-90.0 <= msg.latitude <= 90.0 and -180.0 <= msg.longitude <= 180.0):
            rospy.logwarn_throttle(10.0, f"gps_waypoint_navigator: {what} outside lat/lon range ignored")
            return None
        return (msg.latitude, msg.longitude)

    def _on_fix(self, msg: NavSatFix):
        if msg.status.status < NavSatStatus.STATUS_FIX:
            return
        latlon = self._latlon(msg, "GPS fix")
        if latlon is not None:
            with self._fix_lock:
                self._fix = latlon

    def _on_datum(self, msg: NavSatFix):
        latlon = self._latlon(msg, "datum")
        if latlon is None:
            return
        with self._fix_lock:
            if not self.navsat.has_datum:
                try:
                    self.navsat.set_datum(latlon[0], latlon[1], 0.0, 0.0, 0.0, 0.0)    # ENU map, origin at the datum
                except ValueError as exc:
                    rospy.logerr_throttle(10.0, f"{self.NAME}: datum not usable: {exc}")
                    return
                rospy.loginfo("%s: datum lat %.9f lon %.9f = map (0, 0)", self.NAME, latlon[0], latlon[1])

    def localization_ready(self) -> bool:
        pose = self.robot_pose()
        if pose is None:
            return False
        with self._fix_lock:
            if self.navsat.has_datum:
                return True
            fix = self._fix
        if fix is None:
            return False
        # the fix is where the robot is now: that pins lat/lon onto the (ENU) map
        try:
            self.navsat.set_datum(fix[0], fix[1], imu_yaw_rad=pose.yaw_rad, robot_x_m=pose.x_m, robot_y_m=pose.y_m,
                                  robot_yaw_rad=pose.yaw_rad)
        except ValueError as exc:
            rospy.logerr_throttle(10.0, f"{self.NAME}: the GPS fix cannot be the datum: {exc}")
            return False
        rospy.loginfo("%s: datum lat %.9f lon %.9f at map (%.3f, %.3f)", self.NAME, fix[0], fix[1], pose.x_m,
                      pose.y_m)
        return True

    def make_goals(self, waypoints: list) -> List[MapWaypoint]:
        if self.lanes is None:
            return gps_goals_in_map(waypoints, self.navsat)
        lanes_m = gps_lanes_in_map(self.lanes, self.navsat)
        raw = gps_goals_in_map(waypoints, self.navsat)
        goals = gps_goals_in_map(waypoints, self.navsat, lanes_m=lanes_m, lane_snap_max_m=self.lane_snap_max_m,
                                 lane_snap_margin_m=self.lane_snap_margin_m)
        moved = [math.hypot(g.x_m - r.x_m, g.y_m - r.y_m) for g, r in zip(goals, raw)]
        rospy.loginfo("%s: %d of %d waypoints moved onto the lane centres of %s (by up to %.2f m)", self.NAME,
                      sum(m > 1e-6 for m in moved), len(goals), self.lanes_file, max(moved))
        return goals
