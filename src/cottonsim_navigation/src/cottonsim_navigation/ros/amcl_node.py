"""amcl: adaptive Monte-Carlo localisation in a saved map (the ROS amcl node, for the map mode).

The filter is ``cottonsim_navigation.localization.amcl.Amcl``; the localised
signal, the kidnap handling and the stationary updates are
``cottonsim_navigation.localization.supervisor.LocalizationSupervisor``. This
node converts messages and TF to the cores' types and back. The laser scan helper
:func:`scan_from_msg` is shared with the SLAM node.
"""
from __future__ import annotations

import threading
from typing import Dict, Optional, Tuple

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import Pose, PoseArray, PoseWithCovarianceStamped
from nav_msgs.msg import OccupancyGrid
from nav_msgs.srv import GetMap
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Bool
from std_srvs.srv import Empty, EmptyResponse

from cottonsim_common.pose import Pose2D
from cottonsim_common.transforms import yaw_to_quaternion
from cottonsim_navigation.core.grid import GridSpec
from cottonsim_navigation.localization.amcl import Amcl, AmclConfig
from cottonsim_navigation.localization.free_space_model import FreeSpaceConfig
from cottonsim_navigation.localization.quality import LocalizationQualityConfig
from cottonsim_navigation.localization.sensor_models import Scan
from cottonsim_navigation.localization.supervisor import LocalizationSupervisor, SupervisorConfig
from cottonsim_navigation.ros.map_saver_node import occupancy_grid_to_array
from cottonsim_common.ros.params import config_from_params, typed_param
from cottonsim_common.ros.conversions import finite_or_none, transform_msg, yaw_from_quaternion_msg

TF_ERRORS = (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException)


def scan_from_msg(msg: LaserScan, laser_pose: Tuple[float, float, float]) -> Scan:
    """sensor_msgs/LaserScan + the laser's pose in base_link -> core Scan (NaN ranges = invalid beams).

    Raises ValueError for a scan whose angles or range limits are not finite.
    """
    if not finite_or_none(msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max):
        raise ValueError("scan with non-finite angle_min / angle_increment / range limits")
    return Scan.from_laserscan(np.asarray(msg.ranges, dtype=float), msg.angle_min, msg.angle_increment,
                               laser_pose, max(float(msg.range_min), 0.0), float(msg.range_max))


def grid_from_msg(msg: OccupancyGrid) -> Tuple[np.ndarray, GridSpec]:
    """OccupancyGrid (unrotated origin) -> (int8 [height, width] values, GridSpec)."""
    grid, resolution, origin = occupancy_grid_to_array(msg)
    if not finite_or_none(resolution, *origin) or resolution <= 0:
        raise ValueError(f"map with bad geometry: resolution {resolution}, origin {origin}")
    if abs(origin[2]) > 1e-6:
        raise ValueError(f"maps with a rotated origin are not supported (yaw {origin[2]:.4f} rad)")
    return grid, GridSpec(resolution, grid.shape[1], grid.shape[0], origin[0], origin[1])


class TfPoseReader:
    """Looks up 2-D poses in TF: odometry (odom -> base) at a stamp and static sensor mounts (cached)."""

    def __init__(self, buffer: tf2_ros.Buffer, name: str) -> None:
        self.buffer = buffer
        self.name = name
        self._mounts: Dict[Tuple[str, str], Tuple[float, float, float]] = {}

    def pose(self, parent: str, child: str, stamp: rospy.Time, timeout_s: float) -> Optional[Pose2D]:
        try:
            t = self.buffer.lookup_transform(parent, child, stamp, rospy.Duration(timeout_s))
        except TF_ERRORS as exc:
            rospy.logwarn_throttle(5.0, f"{self.name}: no TF {parent} -> {child} at {stamp.to_sec():.3f}: {exc}")
            return None
        tr = t.transform
        return Pose2D(tr.translation.x, tr.translation.y, yaw_from_quaternion_msg(tr.rotation))

    def mount(self, base: str, sensor: str) -> Optional[Tuple[float, float, float]]:
        key = (base, sensor)
        if key not in self._mounts:
            p = self.pose(base, sensor, rospy.Time(0), 1.0)
            if p is None:
                return None
            self._mounts[key] = (p.x_m, p.y_m, p.yaw_rad)
        return self._mounts[key]


def scan_and_odom(poses: "TfPoseReader", msg: LaserScan, base_frame: str, odom_frame: str, node: str):
    """The scan of ``msg`` (laser pose from TF) and the odometry pose at its stamp, or None when TF has
    neither yet or the scan is malformed (logged, throttled, naming ``node``)."""
    laser = poses.mount(base_frame, msg.header.frame_id)
    if laser is None:
        return None
    try:
        scan = scan_from_msg(msg, laser)
    except ValueError as exc:
        rospy.logwarn_throttle(5.0, f"{node}: scan ignored: {exc}")
        return None
    odom = poses.pose(odom_frame, base_frame, msg.header.stamp, 0.2)
    return None if odom is None else (scan, odom)


def pose_msg(x: float, y: float, yaw: float) -> Pose:
    p = Pose()
    p.position.x, p.position.y = float(x), float(y)
    q = yaw_to_quaternion(float(yaw))
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = q
    return p


class AmclNode:
    """Localises base_link in the map and publishes TF map -> odom.

    Subscriptions
      ~scan_topic (default /scan_360)  sensor_msgs/LaserScan   the full-circle slice of the VLP-16; the
          original's /scan (+/-45 deg) is too narrow along crop rows (AMCL stalls at ~0.26 m error)
      map               nav_msgs/OccupancyGrid  latched (when ~use_map_topic); else service static_map
      initialpose       geometry_msgs/PoseWithCovarianceStamped  re-initialise (rviz "2D Pose Estimate");
          covariance entries [0], [7], [35] (zero -> the configured initial covariance); the filter then
          updates without motion too (stationary policy) until localised, so a robot held by a paused
          navigator can be re-localised by hand
    Publications
      amcl_pose         geometry_msgs/PoseWithCovarianceStamped  after each filter update (frame map); while
          not localised its x-y / yaw covariance is (at least) that of the whole particle set, and while
          moreover the scan does not fit the map at the estimate at least the re-spread covariance
          (~localized_relocalize_std_*), so neither a re-spread filter nor one that agrees on an
          unverified pose reports a tight pose (localization/quality.py, reported_covariance)
      particlecloud     geometry_msgs/PoseArray  after each filter update
      ~localized        std_msgs/Bool (latched)  true while the particle set is tight and the scan fits the
          map at the estimate (see localization/quality.py); false after (re)initialisation, a kidnap, or
          while global localisation is still spread out. Navigators should wait while it is false.
    Services
      global_localization  std_srvs/Empty  spread the particles over the map's free space
    TF
      publishes ~global_frame_id -> ~odom_frame_id on every scan, post-dated by ~transform_tolerance;
      uses ~odom_frame_id -> ~base_frame_id at the scan's stamp and ~base_frame_id -> the scan's frame.
    Parameters (private; config/amcl.yaml documents each with unit and the original's value)
      AmclConfig fields under their names (~alpha1.., ~min_particles, ~max_particles, ~max_beams,
      ~laser_max_range_m, ~z_hit, ~z_rand, ~sigma_hit_m, ~likelihood_max_dist_m, ~update_min_d_m,
      ~update_min_a_rad, ~resample_interval, ~recovery_alpha_slow, ~recovery_alpha_fast, ...);
      ~initial_pose_x, ~initial_pose_y [m], ~initial_pose_a [rad] (0, 0, 0: the map frame is Home),
      ~initial_cov_xx, ~initial_cov_yy [m^2] (0.25), ~initial_cov_aa [rad^2] ((pi/12)^2);
      LocalizationQualityConfig fields with prefix ~localized_ (~localized_max_std_xy_m 0.15,
      ~localized_max_std_yaw_rad 0.1, ~localized_hit_distance_m 0.2, ~localized_min_hit_fraction 0.6,
      ~localized_switch_after 2, ~localized_relocalize_after 3 (0 = off), ~localized_relocalize_std_xy_m 2.0,
      ~localized_relocalize_std_yaw_rad 0.3, ~localized_relocalize_std_across_m 0 (= round),
      ~localized_relocalize_round_fraction 0 (share of the re-drawn particles with the round spread),
      ~localized_relocalize_particles 10000 (how many are re-drawn; 0 = max_particles): once AMCL has been
      localised since its (re)initialisation, after that many updates with a tight set but a poor scan fit
      (a kidnap) the particles are re-drawn around the estimate
      with that spread (std_xy along the estimate's heading, std_across across it); while such a kidnap is
      suspected the standing robot's scans keep being used;
      ~localized_max_crossed_m 0.5 (with the free-space check a beam crossing that much mapped obstacle is a
      miss of the scan fit); ~localized_stationary_update_period_s 0.5 (0 = off): filter updates without motion at most this often,
      while localised with a poor scan fit at the estimate (a standing robot's kidnap) and while re-localising
      after a kidnap, then with jitter ~localized_roughen_std_xy_m 0.03, ~localized_roughen_std_yaw_rad 0.01);
      ~free_space_mode ("relocalizing"): the free-space check of the beams (localization/free_space_model.py)
      "off", "relocalizing" (only while not localised) or "always" (SupervisorConfig); FreeSpaceConfig fields with prefix
      ~free_space_ (~free_space_tolerance_m 0.2, ~free_space_check_length_m 1.0,
      ~free_space_sample_spacing_m 0.1, ~free_space_far_sample_spacing_m 0.5, ~free_space_max_crossed_m 1.0,
      ~free_space_decay_length_m 1.0);
      ~scan_topic (/scan_360), ~use_map_topic (true), ~first_map_only (false), ~transform_tolerance (1.0 s),
      ~tf_broadcast (true), ~global_frame_id (map), ~odom_frame_id (odom), ~base_frame_id (base_link),
      ~seed (-1 = random).
    Scans or poses holding NaN are ignored with a warning. A filter update that comes late (the odometry
    moved more than ~odom_max_step_m / turned more than ~odom_max_step_rad since the previous one: the node
    falls behind a fast simulation or a busy machine) is warned about; its motion noise is sampled in parts.
    """

    def __init__(self):
        overrides = {}
        x = typed_param("~initial_pose_x", 0.0)
        y = typed_param("~initial_pose_y", 0.0)
        a = typed_param("~initial_pose_a", 0.0)
        overrides["initial_pose"] = (x, y, a)
        for ros_name, field in (("~initial_cov_xx", "initial_cov_xx_m2"), ("~initial_cov_yy", "initial_cov_yy_m2"),
                                ("~initial_cov_aa", "initial_cov_aa_rad2")):
            if rospy.has_param(ros_name):
                overrides[field] = typed_param(ros_name, 0.0)
        self.config = config_from_params(AmclConfig, overrides=overrides)
        self.quality_config = config_from_params(LocalizationQualityConfig, prefix="~localized_")
        free_space_mode = typed_param("~free_space_mode", SupervisorConfig.free_space_mode)
        try:
            supervisor_config = SupervisorConfig(free_space_mode, config_from_params(FreeSpaceConfig,
                                                                                     prefix="~free_space_"),
                                                 self.quality_config)
        except ValueError as exc:
            raise ValueError(f"parameter ~{exc}") from exc
        self.scan_topic = typed_param("~scan_topic", "/scan_360")
        self.use_map_topic = typed_param("~use_map_topic", True)
        self.first_map_only = typed_param("~first_map_only", False)
        self.transform_tolerance_s = typed_param("~transform_tolerance", 1.0, minimum=0.0)
        self.tf_broadcast = typed_param("~tf_broadcast", True)
        self.map_frame = typed_param("~global_frame_id", "map")
        self.odom_frame = typed_param("~odom_frame_id", "odom")
        self.base_frame = typed_param("~base_frame_id", "base_link")
        seed = typed_param("~seed", -1)
        rng = np.random.default_rng(None if seed < 0 else seed)

        self.amcl = Amcl(self.config, rng)
        self.supervisor = LocalizationSupervisor(self.amcl, supervisor_config)
        self._lock = threading.Lock()
        self._have_map = False
        self._last_tf_stamp: Optional[rospy.Time] = None
        self._map_to_odom: Optional[Pose2D] = None

        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.tf_pub = tf2_ros.TransformBroadcaster()
        self.poses = TfPoseReader(self.tf_buffer, "amcl")

        self.pose_pub = rospy.Publisher("amcl_pose", PoseWithCovarianceStamped, queue_size=2, latch=True)
        self.cloud_pub = rospy.Publisher("particlecloud", PoseArray, queue_size=2, latch=True)
        self.localized_pub = rospy.Publisher("~localized", Bool, queue_size=2, latch=True)
        self.localized_pub.publish(Bool(data=False))
        self.global_srv = rospy.Service("global_localization", Empty, self._on_global_localization)
        rospy.Subscriber("initialpose", PoseWithCovarianceStamped, self._on_initial_pose, queue_size=2)
        if self.use_map_topic:
            self.map_sub = rospy.Subscriber("map", OccupancyGrid, self._on_map, queue_size=1)
        else:
            threading.Thread(target=self._request_map, daemon=True).start()
        rospy.Subscriber(self.scan_topic, LaserScan, self._on_scan, queue_size=1, buff_size=2 ** 22)
        rospy.loginfo("amcl: scans from %s, %d-%d particles, recovery alphas (%.3g, %.3g)", self.scan_topic,
                      self.config.min_particles, self.config.max_particles, self.config.recovery_alpha_slow,
                      self.config.recovery_alpha_fast)

    # --- map ------------------------------------------------------------------------------
    def _request_map(self):
        rospy.wait_for_service("static_map")
        try:
            resp = rospy.ServiceProxy("static_map", GetMap)()
        except rospy.ServiceException as exc:
            rospy.logerr(f"amcl: static_map failed: {exc}")
            return
        self._on_map(resp.map)

    def _on_map(self, msg: OccupancyGrid):
        if self._have_map and self.first_map_only:
            return
        try:
            grid, spec = grid_from_msg(msg)
        except ValueError as exc:
            rospy.logwarn(f"amcl: map ignored: {exc}")
            return
        with self._lock:
            # a new map invalidates the particles: start again from the configured initial pose
            self.supervisor.set_map(grid, spec)
            self._have_map = True
        self.localized_pub.publish(Bool(data=False))
        rospy.loginfo("amcl: map %d x %d cells at %.3f m; initial pose (%.2f, %.2f, %.2f)", spec.width,
                      spec.height, spec.resolution_m, *self.config.initial_pose)

    # --- re-initialisation ---------------------------------------------------------------
    def _on_initial_pose(self, msg: PoseWithCovarianceStamped):
        p = msg.pose.pose
        q = p.orientation
        if not finite_or_none(p.position.x, p.position.y, q.x, q.y, q.z, q.w, *msg.pose.covariance):
            rospy.logwarn("amcl: initialpose with NaN ignored")
            return
        frame = msg.header.frame_id.lstrip("/")
        if frame and frame != self.map_frame:
            rospy.logwarn(f"amcl: initialpose in frame '{frame}', expected '{self.map_frame}'; ignored")
            return
        c = msg.pose.covariance
        cov = np.diag([c[0], c[7], c[35]])
        if not np.any(np.diag(cov) > 0):
            cov = None
        elif np.any(np.diag(cov) < 0):
            rospy.logwarn("amcl: initialpose with negative variance ignored")
            return
        pose = (p.position.x, p.position.y, yaw_from_quaternion_msg(q))
        with self._lock:
            if not self._have_map:
                rospy.logwarn("amcl: initialpose before a map; ignored")
                return
            self.supervisor.initialise(pose, cov)   # the robot may stand (a paused navigator): update anyway
        self.localized_pub.publish(Bool(data=False))
        rospy.loginfo("amcl: re-initialised at (%.2f, %.2f, %.2f)", *pose)

    def _on_global_localization(self, _req):
        with self._lock:
            if self._have_map:
                self.supervisor.global_localization()   # may be standing: update without motion too
                rospy.loginfo("amcl: global localisation, %d particles over the free space", self.amcl.filter.n)
            else:
                rospy.logwarn("amcl: global_localization before a map; nothing done")
        self.localized_pub.publish(Bool(data=False))
        return EmptyResponse()

    # --- the filter --------------------------------------------------------------------------
    def _on_scan(self, msg: LaserScan):
        if not self._have_map:
            return
        read = scan_and_odom(self.poses, msg, self.base_frame, self.odom_frame, "amcl")
        if read is None:
            return
        scan, odom = read
        with self._lock:
            step = self.supervisor.step(msg.header.stamp.to_sec(), (odom.x_m, odom.y_m, odom.yaw_rad), scan)
            self._map_to_odom = step.result.map_to_odom
        if step.updated:
            self._log_step(step)
            self._publish_pose(step.result, msg.header.stamp)
            self._publish_cloud(step.particles, msg.header.stamp)
            if step.changed:
                self.localized_pub.publish(Bool(data=step.localized))
        self._publish_tf(msg.header.stamp)

    def _log_step(self, step) -> None:
        result, q, c = step.result, self.quality_config, self.config
        if step.stationary_poor_fit is not None:
            rospy.loginfo_throttle(5.0, "amcl: the scan fits the map poorly at the estimate (%.2f < %.2f); "
                                        "updating although the robot stands" %
                                   (step.stationary_poor_fit, q.min_hit_fraction))
        if result.motion_parts > 1:
            rospy.logwarn_throttle(10.0, "amcl: late filter update (scans arrive faster than they are processed): "
                                         "its odometry increment was sampled in %d parts of <= %.2f m / %.2f rad" %
                                   (result.motion_parts, c.odom_max_step_m, c.odom_max_step_rad))
        rospy.loginfo_throttle(5.0, "amcl: pose (%.2f, %.2f, %.3f), %d particles, spread %.3f m %.3f rad, "
                                    "scan fit %.2f" % (result.pose.x_m, result.pose.y_m, result.pose.yaw_rad,
                                                       result.n_particles, step.std_xy_m, step.std_yaw_rad,
                                                       step.hit_fraction))
        if step.kidnapped:
            rospy.logwarn("amcl: the scan has not fitted the map for %d updates although the particles agree: "
                          "kidnapped? Re-spreading them around (%.2f, %.2f) (std %.1f m along, %.1f m across the "
                          "heading, %.2f rad)", q.relocalize_after, result.pose.x_m, result.pose.y_m,
                          q.relocalize_std_xy_m, q.relocalize_std_across_m or q.relocalize_std_xy_m,
                          q.relocalize_std_yaw_rad)
        if step.changed:
            rospy.loginfo("amcl: %s (spread %.3f m, %.3f rad, scan fit %.2f)",
                          "localised" if step.localized else "NOT localised", step.std_xy_m, step.std_yaw_rad,
                          step.hit_fraction)

    def _publish_pose(self, result, stamp):
        out = PoseWithCovarianceStamped()
        out.header.stamp = stamp
        out.header.frame_id = self.map_frame
        out.pose.pose = pose_msg(result.pose.x_m, result.pose.y_m, result.pose.yaw_rad)
        cov = [0.0] * 36
        c = result.covariance
        cov[0], cov[1], cov[6], cov[7] = c[0, 0], c[0, 1], c[1, 0], c[1, 1]
        cov[35] = c[2, 2]
        out.pose.covariance = [float(v) for v in cov]
        self.pose_pub.publish(out)

    def _publish_cloud(self, particles: np.ndarray, stamp):
        out = PoseArray()
        out.header.stamp = stamp
        out.header.frame_id = self.map_frame
        out.poses = [pose_msg(*p) for p in particles]
        self.cloud_pub.publish(out)

    def _publish_tf(self, scan_stamp: rospy.Time):
        if not self.tf_broadcast or self._map_to_odom is None:
            return
        stamp = scan_stamp + rospy.Duration(self.transform_tolerance_s)
        if self._last_tf_stamp is not None and stamp <= self._last_tf_stamp:
            return                                        # no duplicate / older stamps (TF_REPEATED_DATA)
        self._last_tf_stamp = stamp
        t = self._map_to_odom
        self.tf_pub.sendTransform(transform_msg(self.map_frame, self.odom_frame, (t.x_m, t.y_m, 0.0),
                                                yaw_to_quaternion(t.yaw_rad), stamp))
