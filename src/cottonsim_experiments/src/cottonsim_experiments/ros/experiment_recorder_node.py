"""Experiment recorder: measures a waypoint run against ground truth and writes its report.

The robot never sees ground truth; this node does, only to score the run
the way the paper does (Eq. 4-7: E per waypoint, AE, RMSE, CR) plus plant
contacts (crop damage), in-row cross-track error and durations. The work is
done by the ROS-free :mod:`cottonsim_experiments.recording.experiment`; the
offline evaluator (ros/bag_evaluation.py, `rosrun cottonsim_experiments evaluate_bag`) calls the same code on a bag.
"""
from __future__ import annotations

import collections
import datetime
import json
import math
import os
import threading
import time

import numpy as np
import rospy
from cottonsim_msgs.msg import ArmContacts, GpsLocalizationStatus, PlantContacts
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import NavSatFix, NavSatStatus
from std_msgs.msg import Bool, Float64, Float64MultiArray, String

from cottonsim_experiments.recording.experiment import (MODES, TrajectoryLog, TrajectoryLogConfig,
                                                        planned_world_from_gps, planned_world_from_map,
                                                        sim_world_from_settings, summary_line, write_experiment)
from cottonsim_navigation.evaluation.gps_outages import (GpsOutageConfig, estimates_in_world, fix_outages,
                                                         gps_outage_report, paused_intervals, position_errors)
from cottonsim_common.pose import Pose2D
from cottonsim_common.ros.conversions import yaw_from_quaternion_msg
from cottonsim_navigation.evaluation.localization_error import localization_errors, localization_summary
from cottonsim_navigation.evaluation.vision_outputs import VisionCounts, vision_report
from cottonsim_navigation.geodesy.navsat import NavsatConfig, NavsatTransform
from cottonsim_navigation.waypoints.files import WaypointFileError, load_gps_waypoints, load_map_waypoints


class RecorderStartError(RuntimeError):
    """Bad parameters or an unreadable route file; the node exits non-zero."""


class ExperimentRecorderNode:
    """Records ground truth during a waypoint run and writes results/<run>/ when the navigator is done.

    Subscriptions
      /ground_truth/odom (nav_msgs/Odometry, world frame): the true pose, kept every ~record_period_s
      /ground_truth/plant_contacts (cottonsim_msgs/PlantContacts): total_contact_events (counted from
        the first message received)
      /ground_truth/arm_contacts (cottonsim_msgs/ArmContacts): the arm's stem and leaf contact events, counted
        the same way (report: arm_stem_contacts, arm_leaf_contacts; 0 when the simulator publishes none), and
        the arm-stem events by plant part (stem, branch) and arm link (arm_stem_contacts_by_part, _by_link)
      ~state_topic (std_msgs/String, default /gps_waypoint_navigator/state): the navigator's JSON state;
        the run's durations go from its first "navigating" to "finished", which triggers the report
      ~localization_topic (geometry_msgs/PoseWithCovarianceStamped, default '' = none; map runs: /amcl_pose):
        the robot's own pose estimate in the map (= Home) frame; the report gets its error against ground
        truth over the route (localization_error_mean_m / _max_m / _rmse_m, localization_samples)
      ~fix_topic (sensor_msgs/NavSatFix, gps mode default /navsat/fix, '' = none): the receiver's fixes; gaps
        between usable ones (status >= FIX, finite) longer than ~gps_outage_min_gap_s are the run's GPS
        outages (report: gps_outages, gps_outage_total_s, gps_outage_max_s, gps_outage_max_position_error_m,
        gps_outage_list, navigator_pauses, navigator_paused_s; evaluation.gps_outages)
      ~gps_status_topic (cottonsim_msgs/GpsLocalizationStatus, default '' = none; GPS runs:
        /gps_localization/status): the robot's map pose, brought into the world through ~datum_topic's datum
        (sensor_msgs/NavSatFix, latched, default /navsat_transform/datum); its error against ground truth
        during outages, and over the route (localization_error_* as above)
    Parameters (private)
      ~mode (str, "gps"): "gps" (waypoints are "lat lon") or "map" (x, y, yaw in the map = Home frame)
      ~waypoints_file (str, required): the planned route, the file the navigator drives
      ~run_name (str, "run_<date>_<time>"), ~results_dir (str, "results"): output folder results_dir/run_name
      ~sim_settings_param (str, "/sim_bridge/sim"): parameter holding the simulator's settings (farm,
        geodesy reference), to rebuild the plants, lanes and Home
      ~home (list [x m, y m, yaw rad], world; default: the farm's spawn): the map frame of map routes
      ~record_period_s (float, 0.05): sim-time spacing of the kept poses [s]
      ~plot (bool, true): write trajectory.png
      ~shutdown_when_done (bool, true): end the node (and, as a required node, the launch) after writing
      ~gps_outage_min_gap_s (float, 1.0): a gap between usable fixes longer than this [s] is an outage
      ~vision (bool, false): count Cotton-Eye's outputs along the route (/row_centring/status, /husky/cv/coords,
        /move_base/vision_correction, /cotton_eye/bolls_in_reach); the report gets the vision_* keys of
        evaluation.vision_outputs (rates per sim second, the fraction of "no estimate" frames)
    Files: report.json, trajectory.csv, trajectory.png (see evaluation.experiment). On shutdown before
    the navigator finished, the same files are written with "complete": false.
    """

    def __init__(self):
        self.mode = str(rospy.get_param("~mode", "gps"))
        self.waypoints_file = str(rospy.get_param("~waypoints_file", ""))
        stamp = datetime.datetime.now().strftime("%Y%m%d_%H%M%S")
        self.run_name = str(rospy.get_param("~run_name", "") or f"run_{stamp}")
        self.results_dir = str(rospy.get_param("~results_dir", "results"))
        self.state_topic = str(rospy.get_param("~state_topic", "/gps_waypoint_navigator/state"))
        settings_param = str(rospy.get_param("~sim_settings_param", "/sim_bridge/sim"))
        home = rospy.get_param("~home", None)
        period = float(rospy.get_param("~record_period_s", 0.05))
        self.plot = bool(rospy.get_param("~plot", True))
        self.shutdown_when_done = bool(rospy.get_param("~shutdown_when_done", True))
        if self.mode not in MODES:
            raise RecorderStartError(f"~mode must be one of {MODES}, got {self.mode!r}")
        if not self.waypoints_file:
            raise RecorderStartError("~waypoints_file is not set")
        if os.sep in self.run_name or self.run_name in (".", ".."):
            raise RecorderStartError(f"~run_name must be a plain folder name, got {self.run_name!r}")
        try:
            self.log = TrajectoryLog(TrajectoryLogConfig(min_period_s=period))
        except ValueError as exc:
            raise RecorderStartError(f"~record_period_s: {exc}") from None
        try:
            self.world = sim_world_from_settings(rospy.get_param(settings_param, {}) or {})
        except ValueError as exc:
            raise RecorderStartError(f"simulator settings in {settings_param}: {exc}") from None
        self.home = self.world.home
        if home not in (None, "", []):
            try:
                self.home = Pose2D(float(home[0]), float(home[1]), float(home[2]))
            except (TypeError, ValueError, IndexError):
                raise RecorderStartError(f"~home must be [x m, y m, yaw rad], got {home!r}") from None
        try:
            if self.mode == "gps":
                self.route = load_gps_waypoints(self.waypoints_file)
                self.planned_latlon = np.array([[w.lat, w.lon] for w in self.route], dtype=float)
                self.planned_world = planned_world_from_gps(self.route, self.world.geodesy)
            else:
                self.route = load_map_waypoints(self.waypoints_file)
                self.planned_latlon = None
                self.planned_world = planned_world_from_map(self.route, self.home)
        except WaypointFileError as exc:
            raise RecorderStartError(f"bad waypoint file {exc}") from None
        self.out_dir = os.path.join(self.results_dir, self.run_name)

        self._lock = threading.Lock()
        self._contacts_first = None
        self._contacts_last = None
        self._arm_contacts_first = None     # (stem, leaf) totals of the first / last ArmContacts
        self._arm_contacts_last = None
        self._arm_stem_parts = collections.Counter()   # the arm-stem contact events by plant part and arm link
        self._arm_stem_links = collections.Counter()
        self._start = None            # (sim s, wall s) of the route start
        self._end = None
        self._first_seen = None       # (sim s, wall s) of the first ground truth, fallback start
        self._navigator = {}
        self._estimates = []          # (t s, x m, y m) of the localisation estimates, map frame
        self._states = []             # (sim s, navigator state name) in arrival order
        self._fix_stamps = []         # stamps [s] of the usable GPS fixes
        self._gps_estimates = []      # (t s, x m, y m) of gps_localization's map pose
        self._datum = None            # (lat, lon) of the map origin (navsat_transform's datum)
        self._done = threading.Event()
        self._written = False
        rospy.Subscriber("/ground_truth/odom", Odometry, self._on_truth, queue_size=50)
        rospy.Subscriber("/ground_truth/plant_contacts", PlantContacts, self._on_contacts, queue_size=10)
        rospy.Subscriber("/ground_truth/arm_contacts", ArmContacts, self._on_arm_contacts, queue_size=10)
        rospy.Subscriber(self.state_topic, String, self._on_state, queue_size=10)
        self.localization_topic = str(rospy.get_param("~localization_topic", ""))
        if self.localization_topic:
            rospy.Subscriber(self.localization_topic, PoseWithCovarianceStamped, self._on_estimate, queue_size=20)
        self.fix_topic = str(rospy.get_param("~fix_topic", "/navsat/fix" if self.mode == "gps" else ""))
        self.gps_status_topic = str(rospy.get_param("~gps_status_topic", ""))
        try:
            self.outage_config = GpsOutageConfig(float(rospy.get_param("~gps_outage_min_gap_s", 1.0)))
        except ValueError as exc:
            raise RecorderStartError(f"~gps_outage_min_gap_s: {exc}") from None
        if self.fix_topic:
            rospy.Subscriber(self.fix_topic, NavSatFix, self._on_fix, queue_size=50)
        if self.gps_status_topic:
            rospy.Subscriber(self.gps_status_topic, GpsLocalizationStatus, self._on_gps_status, queue_size=20)
            rospy.Subscriber(str(rospy.get_param("~datum_topic", "/navsat_transform/datum")), NavSatFix,
                             self._on_datum, queue_size=2)
        self.vision = bool(rospy.get_param("~vision", False))
        self._vision_counts = VisionCounts()
        if self.vision:
            for topic, msg_type, update in (
                    ("/row_centring/status", String, lambda m: lambda c: c.add_status(m.data)),
                    ("/husky/cv/coords", Float64MultiArray, lambda m: VisionCounts.add_command),
                    ("/move_base/vision_correction", Float64, lambda m: VisionCounts.add_correction),
                    ("/cotton_eye/bolls_in_reach", Bool, lambda m: lambda c: c.add_verdict(m.data))):
                rospy.Subscriber(topic, msg_type, lambda m, u=update: self._count_vision(u(m)), queue_size=50)
        rospy.on_shutdown(self._on_shutdown)
        if self.plot:
            # import matplotlib now, in the background: at the end (possibly during a shutdown, when
            # roslaunch allows only seconds) the figure then takes well under a second
            threading.Thread(target=_warm_up_matplotlib, daemon=True).start()
        rospy.loginfo("experiment_recorder: %s route of %d waypoints from %s -> %s", self.mode, len(self.route),
                      self.waypoints_file, self.out_dir)

    # ------------------------------------------------------------------ inputs
    def _on_truth(self, msg: Odometry):
        p = msg.pose.pose
        t = msg.header.stamp.to_sec()
        yaw = yaw_from_quaternion_msg(p.orientation)
        with self._lock:
            if not self.log.add(t, p.position.x, p.position.y, yaw):
                if not all(math.isfinite(v) for v in (t, p.position.x, p.position.y, yaw)):
                    rospy.logwarn_throttle(10.0, "experiment_recorder: ground truth with NaN ignored")
            if self._first_seen is None:
                self._first_seen = (t, time.monotonic())

    def _on_estimate(self, msg: PoseWithCovarianceStamped):
        p = msg.pose.pose.position
        with self._lock:
            if self._start is not None and self._end is None:      # along the route only
                self._estimates.append((msg.header.stamp.to_sec(), p.x, p.y))

    def _on_fix(self, msg: NavSatFix):
        if msg.status.status < NavSatStatus.STATUS_FIX or not (math.isfinite(msg.latitude)
                                                              and math.isfinite(msg.longitude)):
            return
        with self._lock:
            self._fix_stamps.append(msg.header.stamp.to_sec())

    def _on_gps_status(self, msg: GpsLocalizationStatus):
        with self._lock:
            if self._start is not None and self._end is None and math.isfinite(msg.pose.x):
                self._gps_estimates.append((msg.header.stamp.to_sec(), msg.pose.x, msg.pose.y))

    def _on_datum(self, msg: NavSatFix):
        if math.isfinite(msg.latitude) and math.isfinite(msg.longitude):
            with self._lock:
                self._datum = (msg.latitude, msg.longitude)

    def _count_vision(self, update):
        """Apply update(VisionCounts) to the counts, along the route only."""
        with self._lock:
            if self._start is not None and self._end is None:
                update(self._vision_counts)

    def _on_contacts(self, msg: PlantContacts):
        with self._lock:
            if self._contacts_first is None:
                self._contacts_first = int(msg.total_contact_events)
            self._contacts_last = int(msg.total_contact_events)

    def _on_arm_contacts(self, msg: ArmContacts):
        totals = (int(msg.total_stem_contact_events), int(msg.total_leaf_contact_events))
        with self._lock:
            if self._arm_contacts_first is None:
                self._arm_contacts_first = totals
            self._arm_contacts_last = totals
            for contact in msg.contacts:
                if contact.kind == "stem":
                    self._arm_stem_parts[contact.part] += 1
                    self._arm_stem_links[contact.arm_link] += 1

    def _on_state(self, msg: String):
        try:
            state = json.loads(msg.data)
            name = state["state"]
        except (ValueError, KeyError, TypeError):
            rospy.logwarn_throttle(10.0, f"experiment_recorder: unreadable navigator state {msg.data[:80]!r}")
            return
        now = (rospy.get_time(), time.monotonic())
        with self._lock:
            self._navigator = state
            self._states.append((now[0], name))
            if name in ("navigating", "returning_home") and self._start is None:
                self._start = now
            if name == "finished" and self._end is None:
                self._end = now
                self._done.set()

    # ------------------------------------------------------------------ output
    def write(self, complete: bool, reason: str = "") -> dict:
        with self._lock:
            if self._written:
                return {}
            self._written = True
            traj = self.log.array
            start = self._start or self._first_seen or (rospy.get_time(), time.monotonic())
            end = self._end or (traj[-1, 0] if len(traj) else start[0], time.monotonic())
            contacts = 0 if self._contacts_first is None else self._contacts_last - self._contacts_first
            arm_first, arm_last = self._arm_contacts_first or (0, 0), self._arm_contacts_last or (0, 0)
            stem_parts, stem_links = dict(self._arm_stem_parts), dict(self._arm_stem_links)
            navigator = dict(self._navigator)
            estimates = list(self._estimates)
            states, fixes = list(self._states), list(self._fix_stamps)
            gps_estimates, datum = list(self._gps_estimates), self._datum
            counts = VisionCounts(**vars(self._vision_counts))
        extra = {"vision": self.vision, "halts": navigator.get("halts", 0),
                 "halt_time_s": navigator.get("halt_time_s", 0.0),
                 "arm_stem_contacts": arm_last[0] - arm_first[0], "arm_leaf_contacts": arm_last[1] - arm_first[1],
                 "arm_stem_contacts_by_part": stem_parts, "arm_stem_contacts_by_link": stem_links}
        if self.vision:
            extra.update(vision_report(counts, max(0.0, end[0] - start[0])))
        if self.localization_topic:
            extra = {**extra, "localization_topic": self.localization_topic,
                     **localization_summary(localization_errors(np.array(estimates).reshape(-1, 3), traj, self.home))}
        if self.fix_topic:
            extra.update(self._outage_keys(start[0], end[0], traj, states, fixes, gps_estimates, datum))
        report = write_experiment(
            self.out_dir, self.mode, self.planned_world, traj, max(0.0, end[0] - start[0]),
            max(0.0, end[1] - start[1]), contacts, lanes=self.world.lanes, plant_xy=self.world.plant_xy,
            geodesy=self.world.geodesy, planned_latlon=self.planned_latlon, complete=complete,
            incomplete_reason=reason, run_name=self.run_name, waypoints_file=self.waypoints_file,
            navigator=navigator, plot=self.plot, extra=extra)
        rospy.loginfo("experiment_recorder: %s", summary_line(report))
        rospy.loginfo("experiment_recorder: wrote %s", self.out_dir)
        return report

    def _outage_keys(self, start_s: float, end_s: float, traj, states, fixes, gps_estimates, datum) -> dict:
        """The GPS outage keys of the report (and the GPS pose error over the route when it was recorded)."""
        errors = None
        keys = {}
        if self.gps_status_topic:
            if datum is None:
                rospy.logwarn("experiment_recorder: no datum on the datum topic; the pose errors are left out")
            else:
                navsat = NavsatTransform(NavsatConfig(yaw_offset=0.0, magnetic_declination_radians=0.0))
                navsat.set_datum(datum[0], datum[1], 0.0, 0.0, 0.0, 0.0)       # ENU map, origin at the datum
                world = estimates_in_world(np.array(gps_estimates).reshape(-1, 3), navsat.map_to_latlon,
                                           self.world.geodesy)
                errors = position_errors(world, traj)
                keys = {"localization_topic": self.gps_status_topic, **localization_summary(errors[:, 1])}
        outages = fix_outages(fixes, start_s, end_s, self.outage_config)
        keys.update(gps_outage_report(outages, errors, paused_intervals(states, end_s)))
        return keys

    def _on_shutdown(self):
        if not self._written:
            try:
                self.write(False, "shut down before the navigator finished")
            except (OSError, ValueError) as exc:
                rospy.logerr(f"experiment_recorder: could not write the report: {exc}")

    def spin(self):
        while not rospy.is_shutdown():
            if self._done.wait(0.2):
                try:
                    rospy.sleep(0.5)           # let the last poses arrive
                except rospy.ROSInterruptException:
                    return                     # the shutdown hook writes the report
                try:
                    self.write(True)
                except (OSError, ValueError) as exc:
                    rospy.logerr(f"experiment_recorder: could not write the report: {exc}")
                if self.shutdown_when_done:
                    rospy.signal_shutdown("experiment recorded")
                    return
                self._done.clear()


def _warm_up_matplotlib():
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot  # noqa: F401
    except ImportError:
        pass                      # plot_trajectory reports it when the figure is due
