"""Node ``route_driver``: drives the farm's default route with pure pursuit on odometry.

The simulator's own demo drive (the main job before the navigation stack):
it steers from /odometry/filtered only (the odom frame starts at the spawn
pose), never from ground truth; ground truth and plant contacts are only
recorded for the summary written at the end.

Subscriptions
  /odometry/filtered            nav_msgs/Odometry       the robot's pose estimate (odom frame)
  /ground_truth/odom            nav_msgs/Odometry       recorded for the summary only
  /ground_truth/plant_contacts  cottonsim_msgs/PlantContacts  recorded for the summary only
Publications
  /cmd_vel                      geometry_msgs/Twist     at ~rate_hz
  ~done                         std_msgs/Bool (latched) true when the route is finished
Parameters
  ~farm (dict, {}): FarmConfig overrides (must match the simulator's farm)
  ~cruise_speed (float, 0.5 m/s), ~lookahead (float, 0.8 m): pure pursuit
  ~rate_hz (float, 20 Hz): control rate (sim time)
  ~results_dir (str, ''): where <run>/summary.json and trajectory.csv go ('' = none)
  ~run (str, 'drive'): run name
  ~timeout_s (float, 1800): sim-time limit of the drive [s]
  ~max_waypoints (int, 0): drive only the first N waypoints of the route (0 = the whole route);
      reduced runs such as the mapping bringup's rostest
"""
from __future__ import annotations

import csv
import json
import math
import pathlib
import time

import numpy as np
import rospy
from cottonsim_msgs.msg import PlantContacts
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from std_msgs.msg import Bool

from cottonsim_common.ros.conversions import yaw_from_quaternion_msg
from cottonsim_world.driving.pure_pursuit import PurePursuit, PurePursuitConfig
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.export import route_in_frame
from cottonsim_world.farm.generator import generate_farm


def in_row_cross_track(farm, xy: np.ndarray) -> np.ndarray:
    """|x - lane centre| of trajectory points inside a lane beside the plants [m]."""
    errors = []
    for lane in farm.lanes:
        inside = (np.abs(xy[:, 0] - lane.x_m) < 0.45) & (xy[:, 1] > lane.y_start_m) & (xy[:, 1] < lane.y_end_m)
        errors.append(np.abs(xy[inside, 0] - lane.x_m))
    return np.concatenate(errors) if errors else np.zeros(0)


class RouteDriverNode:
    def __init__(self):
        farm_cfg = FarmConfig.from_dict(dict(rospy.get_param("~farm", {}) or {}))
        self.farm = generate_farm(farm_cfg)
        route = route_in_frame(self.farm, self.farm.spawn)[:, :2]
        max_waypoints = rospy.get_param("~max_waypoints", 0)
        if not isinstance(max_waypoints, int) or isinstance(max_waypoints, bool) or max_waypoints < 0:
            raise ValueError(f"~max_waypoints must be an integer >= 0 (0 = whole route), got {max_waypoints!r}")
        if max_waypoints:
            route = route[:max_waypoints]
        path = np.vstack([[0.0, 0.0], route])
        self.follower = PurePursuit(path, PurePursuitConfig(
            cruise_speed_m_s=float(rospy.get_param("~cruise_speed", 0.5)),
            lookahead_m=float(rospy.get_param("~lookahead", 0.8))))
        self.rate_hz = float(rospy.get_param("~rate_hz", 20.0))
        self.results_dir = str(rospy.get_param("~results_dir", ""))
        self.run_name = str(rospy.get_param("~run", "drive"))
        self.timeout_s = float(rospy.get_param("~timeout_s", 1800.0))
        self.pose = None
        self.truth = []
        self.contacts = 0
        self.cmd_pub = rospy.Publisher("/cmd_vel", Twist, queue_size=1)
        self.done_pub = rospy.Publisher("~done", Bool, queue_size=1, latch=True)
        rospy.Subscriber("/odometry/filtered", Odometry, self._on_odom, queue_size=1)
        rospy.Subscriber("/ground_truth/odom", Odometry, self._on_truth, queue_size=50)
        rospy.Subscriber("/ground_truth/plant_contacts", PlantContacts, self._on_contacts, queue_size=10)

    def _on_odom(self, msg):
        p = msg.pose.pose
        self.pose = (p.position.x, p.position.y, yaw_from_quaternion_msg(p.orientation))

    def _on_truth(self, msg):
        p = msg.pose.pose.position
        self.truth.append((msg.header.stamp.to_sec(), p.x, p.y))

    def _on_contacts(self, msg):
        self.contacts = msg.total_contact_events

    def run(self):
        while self.pose is None and not rospy.is_shutdown():
            rospy.rostime.wallsleep(0.05)
        rate = rospy.Rate(self.rate_hz)
        t0_sim, t0_wall = rospy.Time.now().to_sec(), time.monotonic()
        rospy.loginfo("route_driver: driving %.1f m of route", self.follower.length_m)
        while not rospy.is_shutdown() and not self.follower.done:
            if rospy.Time.now().to_sec() - t0_sim > self.timeout_s:
                rospy.logerr("route_driver: time-out after %.0f s of sim time", self.timeout_s)
                break
            v, w = self.follower.command(*self.pose)
            cmd = Twist()
            cmd.linear.x, cmd.angular.z = v, w
            self.cmd_pub.publish(cmd)
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                break
        self.cmd_pub.publish(Twist())
        self._write_summary(rospy.Time.now().to_sec() - t0_sim, time.monotonic() - t0_wall)
        self.done_pub.publish(Bool(data=self.follower.done))
        rospy.signal_shutdown("route finished" if self.follower.done else "route not finished")

    def _write_summary(self, sim_s, wall_s):
        xy = np.array([(x, y) for _, x, y in self.truth]).reshape(-1, 2)
        cross = in_row_cross_track(self.farm, xy)
        summary = {
            "finished": bool(self.follower.done),
            "route_length_m": round(self.follower.length_m, 3),
            "travelled_m": round(float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1))) if len(xy) > 1 else 0.0, 3),
            "sim_duration_s": round(sim_s, 2), "wall_duration_s": round(wall_s, 2),
            "real_time_factor": round(sim_s / wall_s, 3) if wall_s > 0 else None,
            "plant_contacts": int(self.contacts),
            "cross_track_mean_m": round(float(cross.mean()), 4) if len(cross) else None,
            "cross_track_max_m": round(float(cross.max()), 4) if len(cross) else None,
        }
        rospy.loginfo("route_driver: %s", json.dumps(summary))
        if not self.results_dir:
            return
        out = pathlib.Path(self.results_dir) / self.run_name
        out.mkdir(parents=True, exist_ok=True)
        (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        with open(out / "trajectory.csv", "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["t_s", "world_x_m", "world_y_m"])
            writer.writerows(self.truth)
        rospy.loginfo("route_driver: wrote %s", out)
