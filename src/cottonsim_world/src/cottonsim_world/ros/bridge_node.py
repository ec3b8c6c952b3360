"""ROS bridge of the simulator: the node that stands in for gzserver + plugins.

Node ``sim_bridge`` (executable nodes/sim_bridge) steps a ``Simulator`` and
publishes what Gazebo with the original's plugins would, on the same topics.

Publications
  /clock                                   rosgraph_msgs/Clock      every ~clock_period_s of sim time
  /<cam>/color/image_raw                   sensor_msgs/Image        rgb8, cam in realsense_p,
                                                                    realsense_secondary, realsense_tertiary
  /<cam>/color/camera_info                 sensor_msgs/CameraInfo
  /<cam>/depth/color/points                sensor_msgs/PointCloud2  x y z rgb, <cam>_color_optical_frame
  /<cam>/ground_truth/semantic             sensor_msgs/Image        mono8 class ids (0 plant, 1 ground,
                                                                    2 sky, 3 boll) - ground truth
  /points                                  sensor_msgs/PointCloud2  VLP-16: x y z intensity ring, frame velodyne
  /passthrough/output                      sensor_msgs/PointCloud2  the paper's PassThrough filter of /points
  /scan, /vlp/scan                         sensor_msgs/LaserScan    pointcloud_to_laserscan of /points
                                                                    (the original's +/-45 deg forward sector)
  /scan_360                                sensor_msgs/LaserScan    full circle, slice -0.25..0.1 m (SLAM, AMCL)
  /imu/data                                sensor_msgs/Imu          frame imu_link
  /navsat/fix                              sensor_msgs/NavSatFix    hector-style GPS
  /husky_velocity_controller/odom          nav_msgs/Odometry        wheel odometry, odom -> base_link
  /odometry/filtered                       nav_msgs/Odometry        EKF (wheel odometry + IMU)
  /joint_states                            sensor_msgs/JointState   wheels and UR5e
  /ground_truth/odom                       nav_msgs/Odometry        true pose, frame world - evaluation only
  /ground_truth/plant_contacts             cottonsim_msgs/PlantContacts  robot-plant contacts (crop damage)
  /ground_truth/arm_contacts               cottonsim_msgs/ArmContacts  arm-stem and arm-leaf contacts
                                                                    (robot/arm_contacts.py), at contacts_rate_hz
  /sim/stats                               cottonsim_msgs/SimStats  achieved real-time factor, cost per sensor
  /sim/faults/active                       cottonsim_msgs/SensorFaults  latched: the sensor faults active now
                                                                    (ros/fault_topics.py)
  /sim/bolls                               cottonsim_msgs/BollArray latched: every boll's id, plant, position,
                                                                    state, on each state change (ros/boll_topics.py)
  /sim/bolls/held                          cottonsim_msgs/BollArray latched: the held bolls, as they move
Subscriptions
  /sim/frames_done                         std_msgs/Header          a consumer is done with the camera frame
                                           (frame_id) stamped so: cameras with consumer_wait_s > 0 wait for it
                                           (ros/consumer_pacing.py)
  /cmd_vel                                 geometry_msgs/Twist      Husky velocity command (0.25 s time-out)
  /arm_controller/command                  trajectory_msgs/JointTrajectory  UR5e targets (last point's positions);
                                           aborts a running trajectory goal
Action, service and topic of the arm (ros/arm_interface.py)
  /arm_controller/follow_joint_trajectory  cottonsim_msgs/FollowJointTrajectory (control_msgs' fields)
  /arm_controller/vacuum                   std_srvs/SetBool   the vacuum nozzle on / off
  /arm_controller/vacuum/holding           std_msgs/Bool      latched: the nozzle holds a boll
Services
  /sim/set_robot_pose                      cottonsim_msgs/SetRobotPose  teleport the robot (world frame, at rest)
                                           between two physics steps; wheel odometry / EKF do not see it (a
                                           kidnap for localisation tests). success false + message when refused
  /sim/inject_fault, /sim/clear_faults     cottonsim_msgs/InjectFault, ClearFaults  start a sensor fault now,
                                           end them all (ros/fault_topics.py)
  /sim/set_boll_state                      cottonsim_msgs/SetBollState  detach / carry / bin one boll (ros/boll_topics.py)
TF
  odom -> base_link (from the EKF, ~publish_tf); the robot's own frames come from
  robot_state_publisher (URDF + /joint_states).
Parameters (private)
  ~real_time_factor (float, 1.0): target sim/wall rate; 0 = as fast as possible
  ~lazy_sensors (bool, true): render/scan only while a topic of the sensor has subscribers
  ~clock_period_s (float, 0.01): sim-time period of /clock [s] (100 Hz: the fastest sim-time
                               consumers run at 50 Hz; each /clock costs a publish)
  ~stats_period_s (float, 1.0): sim-time period of /sim/stats [s]
  ~publish_tf (bool, true): publish odom -> base_link
  ~urdf_file (str): robot URDF (default: cottonsim_description/urdf/cottonsim_robot.urdf)
  ~sim (dict): simulator settings, shaped as config/sim.yaml (farm, physics, cameras, lidar, faults, ...)
  ~faults (list, []): more scheduled sensor faults, entries as config/sim.yaml's 'faults' (kind, start_s,
                      duration_s, the kind's keys); they apply together with ~sim/faults. Faulty fixes keep
                      NavSatFix conventions: status NO_FIX (-1) with NaN position and covariance type
                      UNKNOWN, degraded fixes the fix type's status and their true variance (DIAGONAL_KNOWN)
  ~seed (int, 0): seed of every random process
  ~bolls_min_period_s (float, 0.1): /sim/bolls/held pacing while held bolls move [s] (ros/boll_topics.py)
  ~sim/sensor_workers (int, 0): threads that render the cameras and scan the LiDAR beside the physics
                               (SimulatorConfig.sensor_workers, 0 = serial); the readings and their
                               stamps stay the same, /clock then follows the last complete stamp
                               (Simulator.delivered_time_s), at most one sensor period behind the
                               physics, which /cmd_vel and teleports act on
"""
from __future__ import annotations

import math
import pathlib
import threading
import time
from typing import Dict

import numpy as np
import rospkg
import rospy
import tf2_ros
from cottonsim_msgs.msg import ArmContact, ArmContacts, PlantContact, PlantContacts, SimStats
from cottonsim_msgs.srv import SetRobotPose, SetRobotPoseResponse
from geometry_msgs.msg import Point, Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState, LaserScan, NavSatFix, PointCloud2, PointField
from trajectory_msgs.msg import JointTrajectory

from cottonsim_common.ros import conversions as conv
from cottonsim_common.transforms import yaw_to_quaternion
from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.robot.urdf_model import UrdfModel
from cottonsim_world.ros.boll_topics import BollTopics
from cottonsim_world.ros.fault_topics import FaultTopics
from cottonsim_world.ros.arm_interface import ArmRosInterface
from cottonsim_world.readings import (ArmContactsReading, CameraReading, ContactsReading, GpsReading,
                                      GroundTruthReading, ImuReading, JointStatesReading, LidarReading,
                                      OdometryReading)
from cottonsim_world.ros.consumer_pacing import ConsumerPacing
from cottonsim_world.simulator import Simulator
from cottonsim_world.simulator_config import ARM_JOINT_NAMES


_XYZRGB_FIELDS = [PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, name in enumerate(("x", "y", "z", "rgb"))]


def packed_xyzrgb_cloud_msg(packed: np.ndarray, stamp: rospy.Time, frame_id: str) -> PointCloud2:
    """PointCloud2 (x, y, z, rgb: FLOAT32 at 0, 4, 8, 12) from ``CameraModel.point_cloud_xyzrgb``'s
    (N, 4) float32 array: its bytes are the message data, no per-field packing. Same message as
    ``conversions.xyzrgb_cloud_msg`` of the unpacked cloud."""
    packed = np.ascontiguousarray(packed, dtype=np.float32)
    if packed.ndim != 2 or packed.shape[1] != 4:
        raise ValueError(f"packed cloud must be (N, 4) float32, got shape {packed.shape}")
    n = packed.shape[0]
    return PointCloud2(header=conv.header(stamp, frame_id), height=1, width=n, fields=list(_XYZRGB_FIELDS),
                       is_bigendian=False, point_step=16, row_step=16 * n, data=packed.tobytes(), is_dense=True)


class SimBridgeNode:
    """Steps the simulator and publishes its readings (see the module docstring for the ROS API)."""

    def __init__(self):
        self.real_time_factor = float(rospy.get_param("~real_time_factor", 1.0))
        if not (math.isfinite(self.real_time_factor) and self.real_time_factor >= 0.0):
            raise ValueError(f"~real_time_factor must be >= 0 (0 = as fast as possible), got {self.real_time_factor}")
        self.lazy = bool(rospy.get_param("~lazy_sensors", True))
        self.clock_period_s = float(rospy.get_param("~clock_period_s", 0.01))
        if not (math.isfinite(self.clock_period_s) and self.clock_period_s > 0.0):
            raise ValueError(f"~clock_period_s must be a finite period > 0 [s], got {self.clock_period_s}")
        self.stats_period_s = float(rospy.get_param("~stats_period_s", 1.0))
        self.publish_tf = bool(rospy.get_param("~publish_tf", True))
        default_urdf = pathlib.Path(rospkg.RosPack().get_path("cottonsim_description")) / "urdf" / "cottonsim_robot.urdf"
        urdf_file = rospy.get_param("~urdf_file", str(default_urdf))
        settings = dict(rospy.get_param("~sim", {}) or {})
        settings.setdefault("seed", int(rospy.get_param("~seed", 0)))
        extra_faults = rospy.get_param("~faults", []) or []
        if not isinstance(extra_faults, list):
            raise ValueError(f"~faults must be a list of faults (config/sim.yaml 'faults'), got {extra_faults!r}")
        if extra_faults:
            settings["faults"] = list(settings.get("faults") or []) + extra_faults
        config = simulator_config_from_dict(settings)
        self.sim = Simulator(config, UrdfModel.from_file(urdf_file))
        rospy.loginfo("sim_bridge: farm of %d plants, %d cameras, lidar %s, physics step %.4f s, target RTF %s, "
                      "sensor workers %d", len(self.sim.farm.plants), len(self.sim.cameras), self.sim.lidar is not None,
                      self.sim.step_s, self.real_time_factor or "max", self.sim.config.sensor_workers)
        for spec in self.sim.config.faults.faults:
            rospy.loginfo("sim_bridge: scheduled fault: %s", spec.describe())
        self._make_publishers()
        self._cmd_lock = threading.Lock()
        self._pending_cmd = None
        self._pending_arm = None
        rospy.Subscriber("/cmd_vel", Twist, self._on_cmd_vel, queue_size=5)
        rospy.Subscriber("/arm_controller/command", JointTrajectory, self._on_arm_command, queue_size=2)
        self._pending_teleport = None       # [pose, threading.Event, refusal or None], done by the sim loop
        rospy.Service("/sim/set_robot_pose", SetRobotPose, self._on_set_robot_pose)
        self.fault_topics = FaultTopics(self.sim)     # /sim/inject_fault, /sim/clear_faults, /sim/faults/active
        self.boll_topics = BollTopics(self.sim.bolls)
        self.arm_ros = ArmRosInterface(self.sim)     # /arm_controller/follow_joint_trajectory, vacuum
        self.pacing = ConsumerPacing.for_cameras(self.sim.config.cameras)   # cameras' consumer_wait_s

    # ------------------------------------------------------------------ setup
    def _make_publishers(self):
        self.clock_pub = rospy.Publisher("/clock", Clock, queue_size=10)
        self.cam_pubs: Dict[str, Dict[str, rospy.Publisher]] = {}
        for name in self.sim.cameras:
            self.cam_pubs[name] = {
                "image": rospy.Publisher(f"/{name}/color/image_raw", Image, queue_size=5),
                "info": rospy.Publisher(f"/{name}/color/camera_info", CameraInfo, queue_size=2),
                "points": rospy.Publisher(f"/{name}/depth/color/points", PointCloud2, queue_size=5),
                "semantic": rospy.Publisher(f"/{name}/ground_truth/semantic", Image, queue_size=2),
            }
        self.lidar_pubs = {
            "points": rospy.Publisher("/points", PointCloud2, queue_size=5),
            "passthrough": rospy.Publisher("/passthrough/output", PointCloud2, queue_size=5),
            "scan": rospy.Publisher("/scan", LaserScan, queue_size=2),
            "vlp_scan": rospy.Publisher("/vlp/scan", LaserScan, queue_size=2),
            "scan_360": rospy.Publisher("/scan_360", LaserScan, queue_size=2),
        }
        self.imu_pub = rospy.Publisher("/imu/data", Imu, queue_size=10)
        self.gps_pub = rospy.Publisher("/navsat/fix", NavSatFix, queue_size=10)
        self.wheel_odom_pub = rospy.Publisher("/husky_velocity_controller/odom", Odometry, queue_size=10)
        self.filtered_odom_pub = rospy.Publisher("/odometry/filtered", Odometry, queue_size=10)
        self.joint_pub = rospy.Publisher("/joint_states", JointState, queue_size=10)
        self.truth_pub = rospy.Publisher("/ground_truth/odom", Odometry, queue_size=10)
        self.contacts_pub = rospy.Publisher("/ground_truth/plant_contacts", PlantContacts, queue_size=10)
        self.arm_contacts_pub = rospy.Publisher("/ground_truth/arm_contacts", ArmContacts, queue_size=10)
        self.stats_pub = rospy.Publisher("/sim/stats", SimStats, queue_size=2)
        self.tf_pub = tf2_ros.TransformBroadcaster()

    # ------------------------------------------------------------------ inputs
    def _on_cmd_vel(self, msg: Twist):
        with self._cmd_lock:
            self._pending_cmd = (msg.linear.x, msg.angular.z)

    def _on_arm_command(self, msg: JointTrajectory):
        if not msg.points:
            rospy.logwarn("sim_bridge: arm command without trajectory points ignored")
            return
        target = dict(zip(msg.joint_names, msg.points[-1].positions))
        missing = [j for j in ARM_JOINT_NAMES if j not in target]
        if missing:
            rospy.logwarn("sim_bridge: arm command lacks joints %s; ignored", missing)
            return
        if not all(math.isfinite(target[j]) for j in ARM_JOINT_NAMES):
            rospy.logwarn("sim_bridge: arm command with NaN/inf positions ignored")
            return
        with self._cmd_lock:
            self._pending_arm = [target[j] for j in ARM_JOINT_NAMES]

    def _on_set_robot_pose(self, req):
        """Hand the teleport to the simulation loop (the only thread that touches the simulator); wait for it."""
        job = [(req.x_m, req.y_m, req.yaw_rad), threading.Event(), None]
        with self._cmd_lock:
            self._pending_teleport = job
        if not job[1].wait(10.0):
            return SetRobotPoseResponse(False, "the simulation loop did not take the teleport within 10 s (wall)")
        if job[2] is not None:
            return SetRobotPoseResponse(False, job[2])
        rospy.logwarn("sim_bridge: robot teleported to (%.2f, %.2f, yaw %.2f) in world", *job[0])
        return SetRobotPoseResponse(True, "robot at (%.3f, %.3f, yaw %.3f) in world" % job[0])

    def _apply_inputs(self):
        with self._cmd_lock:
            cmd, self._pending_cmd = self._pending_cmd, None
            arm, self._pending_arm = self._pending_arm, None
            teleport, self._pending_teleport = self._pending_teleport, None
        self.fault_topics.apply_requests()
        if teleport is not None:
            try:
                self.sim.teleport_robot(*teleport[0])
            except ValueError as exc:
                teleport[2] = str(exc)
            teleport[1].set()
        if cmd is not None:
            refused = self.sim.command_velocity(*cmd)
            if refused:
                rospy.logwarn_throttle(5.0, f"sim_bridge: /cmd_vel refused: {refused}")
        if arm is not None:
            self.sim.command_arm(arm)

    def _update_demand(self):
        """Lazy sensors: only simulate what somebody listens to."""
        for name, pubs in self.cam_pubs.items():
            self.sim.set_sensor_active(name, (not self.lazy) or any(p.get_num_connections() for p in pubs.values()))
            self.sim.set_camera_cloud_wanted(name, (not self.lazy) or pubs["points"].get_num_connections() > 0)
        if self.sim.lidar is not None:
            self.sim.set_sensor_active("lidar", (not self.lazy) or any(
                p.get_num_connections() for p in self.lidar_pubs.values()))

    # ------------------------------------------------------------------ main loop
    def spin(self):
        clock_steps = max(1, int(round(self.clock_period_s / self.sim.step_s)))
        stats_steps = max(1, int(round(self.stats_period_s / self.sim.step_s)))
        demand_every_s, next_demand = 0.25, 0.0
        # /clock is the simulator's delivered_time_s: the sim time up to which every reading is out.
        # Serial it is the physics time; with pipelined sensors (~sim/sensor_workers > 0) it lags
        # the physics by the pending readings, so that no message is stamped after /clock and the
        # readings go out in stamp order. Pacing (~real_time_factor) follows it too.
        sim0 = self.sim.delivered_time_s
        wall0 = time.monotonic()
        window = (wall0, sim0)
        clock_s = sim0
        self.clock_pub.publish(conv.clock_msg(clock_s))
        self.fault_topics.publish_active(clock_s)
        step = 0
        while not rospy.is_shutdown():
            now_wall = time.monotonic()
            if now_wall >= next_demand:
                self._update_demand()
                next_demand = now_wall + demand_every_s
            self._apply_inputs()
            self.boll_topics.update(self.sim.delivered_time_s)
            self.arm_ros.apply_inputs()
            if self.pacing is not None:
                self.pacing.hold(self.sim.delivered_time_s,
                                 lambda: self.clock_pub.publish(conv.clock_msg(self.sim.delivered_time_s)))
            readings = self.sim.step()
            self.arm_ros.after_step()
            step += 1
            delivered_s = self.sim.delivered_time_s
            if (readings or step % clock_steps == 0) and delivered_s > clock_s:
                clock_s = delivered_s
                self.clock_pub.publish(conv.clock_msg(clock_s))
                if not self.sim.faults.idle:
                    self.fault_topics.publish_active(clock_s)
            for reading in readings:
                self._publish(reading)
            if step % stats_steps == 0:
                window = self._publish_stats(wall0, window, clock_s)
            if self.real_time_factor > 0.0:
                ahead = (delivered_s - sim0) / self.real_time_factor - (time.monotonic() - wall0)
                if ahead > 0.0:
                    time.sleep(ahead)
        self.sim.close()

    def _publish_stats(self, wall0: float, window, clock_s: float):
        """/sim/stats over the window since the last one; stamped with the last /clock (clock_s)."""
        now_wall, now_sim = time.monotonic(), clock_s
        rtf = (now_sim - window[1]) / max(now_wall - window[0], 1e-9)
        timing = self.sim.sensor_timing_ms()
        msg = SimStats(sim_time=now_sim, wall_time=now_wall - wall0, real_time_factor=rtf,
                       target_real_time_factor=self.real_time_factor,
                       physics_step_ms=self.sim.physics_step_ms(),
                       sensor_names=list(timing), sensor_ms=list(timing.values()))
        msg.header.stamp = conv.to_time(now_sim)
        self.stats_pub.publish(msg)
        return now_wall, now_sim

    # ------------------------------------------------------------------ readings -> messages
    def _publish(self, reading):
        stamp = conv.to_time(reading.stamp_s)
        if isinstance(reading, CameraReading):
            self._publish_camera(reading, stamp)
        elif isinstance(reading, LidarReading):
            self._publish_lidar(reading, stamp)
        elif isinstance(reading, ImuReading):
            m = reading.measurement
            msg = conv.imu_msg(m.orientation_xyzw, m.angular_velocity_rad_s, m.linear_acceleration_m_s2,
                               0.0, 0.0, 0.0, stamp, reading.frame_id)
            msg.orientation_covariance = [float(v) for v in m.orientation_covariance]
            msg.angular_velocity_covariance = [float(v) for v in m.angular_velocity_covariance]
            msg.linear_acceleration_covariance = [float(v) for v in m.linear_acceleration_covariance]
            self.imu_pub.publish(msg)
        elif isinstance(reading, GpsReading):
            self.gps_pub.publish(conv.navsatfix_msg(reading.latitude_deg, reading.longitude_deg, reading.altitude_m,
                                                    reading.position_variance_m2, stamp, reading.frame_id,
                                                    reading.status))
        elif isinstance(reading, OdometryReading):
            self._publish_odometry(reading, stamp)
        elif isinstance(reading, JointStatesReading):
            self.joint_pub.publish(conv.joint_state_msg(reading.names, reading.positions, reading.velocities, stamp))
        elif isinstance(reading, GroundTruthReading):
            s = reading.state
            self.truth_pub.publish(conv.odometry_msg(s.position_m, s.orientation_xyzw, s.linear_velocity_body_m_s,
                                                     s.angular_velocity_body_rad_s, None, None, stamp,
                                                     "world", "base_link"))
        elif isinstance(reading, ContactsReading):
            self._publish_contacts(reading, stamp)
        elif isinstance(reading, ArmContactsReading):
            self._publish_arm_contacts(reading, stamp)

    def _publish_camera(self, r: CameraReading, stamp):
        pubs = self.cam_pubs[r.camera]
        intr = r.intrinsics
        if pubs["image"].get_num_connections() or not self.lazy:
            pubs["image"].publish(conv.image_msg(r.frame.rgb, stamp, r.frame_id))
            if self.pacing is not None:
                self.pacing.sent(r.camera, r.stamp_s)
        pubs["info"].publish(conv.camera_info_msg(intr.width, intr.height, intr.K, intr.P, stamp, r.frame_id))
        if pubs["semantic"].get_num_connections() or not self.lazy:
            pubs["semantic"].publish(conv.image_msg(r.frame.semantic, stamp, r.frame_id))
        if r.cloud_xyzrgb is not None:
            pubs["points"].publish(packed_xyzrgb_cloud_msg(r.cloud_xyzrgb, stamp, r.frame_id))
        elif r.cloud_xyz is not None:
            pubs["points"].publish(conv.xyzrgb_cloud_msg(r.cloud_xyz, r.cloud_rgb, stamp, r.frame_id))

    def _publish_lidar(self, r: LidarReading, stamp):
        scan = r.scan
        pts = scan.points
        self.lidar_pubs["points"].publish(conv.cloud_msg(
            {"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2], "intensity": scan.intensity.astype(np.float32),
             "ring": scan.ring.astype(np.uint16)}, stamp, r.frame_id))
        kept = r.passthrough_points
        self.lidar_pubs["passthrough"].publish(conv.cloud_msg(
            {"x": kept[:, 0], "y": kept[:, 1], "z": kept[:, 2]}, stamp, r.frame_id))
        c = r.scan_config
        scan_msg = conv.laserscan_msg(r.scan_ranges, c.angle_min_rad, c.angle_max_rad, c.angle_increment_rad,
                                      c.range_min_m, c.range_max_m, 1.0 / self.sim.config.lidar.rate_hz,
                                      stamp, r.frame_id)
        self.lidar_pubs["scan"].publish(scan_msg)
        self.lidar_pubs["vlp_scan"].publish(scan_msg)
        c = r.scan_360_config
        self.lidar_pubs["scan_360"].publish(conv.laserscan_msg(
            r.scan_360_ranges, c.angle_min_rad, c.angle_max_rad, c.angle_increment_rad, c.range_min_m,
            c.range_max_m, 1.0 / self.sim.config.lidar.rate_hz, stamp, r.frame_id))

    def _publish_odometry(self, r: OdometryReading, stamp):
        w = r.wheel
        self.wheel_odom_pub.publish(conv.odometry_msg(
            (w.x_m, w.y_m, 0.0), yaw_to_quaternion(w.yaw_rad), (w.linear_x_m_s, 0.0, 0.0), (0.0, 0.0, w.angular_z_rad_s),
            w.pose_covariance.reshape(-1), w.twist_covariance.reshape(-1), stamp, "odom", "base_link"))
        f = r.filtered
        self.filtered_odom_pub.publish(conv.odometry_msg(
            (f.x_m, f.y_m, 0.0), f.orientation_xyzw, (f.linear_x_m_s, 0.0, 0.0), (0.0, 0.0, f.angular_z_rad_s),
            np.asarray(f.pose_covariance).reshape(-1), np.asarray(f.twist_covariance).reshape(-1),
            stamp, "odom", "base_link"))
        if self.publish_tf:
            translation, rotation = f.transform_odom_to_base_link()
            self.tf_pub.sendTransform(conv.transform_msg("odom", "base_link", translation, rotation, stamp))

    def _publish_contacts(self, r: ContactsReading, stamp):
        msg = PlantContacts(total_contact_events=r.total_contact_events, plants_touched=list(r.plants_touched))
        msg.header.stamp = stamp
        msg.header.frame_id = "world"
        per_row = self.sim.config.farm.plants_per_row
        for e in r.events:
            msg.contacts.append(PlantContact(plant_id=e.plant_id, row=e.plant_id // per_row,
                                             plant=e.plant_id % per_row, robot_part=e.part,
                                             position=Point(*e.point_m), depth=e.depth_m))
        self.contacts_pub.publish(msg)

    def _publish_arm_contacts(self, r: ArmContactsReading, stamp):
        msg = ArmContacts(total_stem_contact_events=r.totals["stem"], total_leaf_contact_events=r.totals["leaf"],
                          plants_touched=list(r.plants_touched))
        msg.header.stamp, msg.header.frame_id = stamp, "world"
        per_row = self.sim.config.farm.plants_per_row
        msg.contacts = [ArmContact(plant_id=e.plant_id, row=e.plant_id // per_row, plant=e.plant_id % per_row,
                                   kind=e.kind, part=e.part, arm_link=e.link, position=Point(*e.point_m),
                                   depth=e.depth_m) for e in r.events]
        self.arm_contacts_pub.publish(msg)

