"""The move_base node's two costmaps: built from parameters, fed with the map and the point cloud, published.

The local costmap (rolling window in the local frame) takes every cloud at
~local_costmap/update_frequency. The global costmap takes the static map
and, when its plugins include an obstacle layer (GPS mode: the static map is
empty), the latest cloud too, at ~global_costmap/update_frequency, recomputing
only a window around the robot that covers everything one cloud can mark or
clear (2 x the layer's longer range plus the robot's travel between updates).
"""
from __future__ import annotations

import math
import threading
from typing import Optional, Tuple

import numpy as np
import rospy
import tf2_ros
from nav_msgs.msg import OccupancyGrid
from sensor_msgs.msg import PointCloud2

from cottonsim_common.pose import Pose2D, compose, inverse
from cottonsim_navigation.planning.costmap import (Costmap2D, CostmapConfig, InflationLayer, InflationLayerConfig,
                                                   StaticLayer, StaticLayerConfig)
from cottonsim_navigation.planning.obstacle_layer import ObstacleLayer, ObstacleLayerConfig
from cottonsim_navigation.ros.move_base_messages import costmap_msg, occupancy_from_msg, transform_matrix
from cottonsim_common.ros.params import config_from_params, typed_param
from cottonsim_common.ros import conversions as conv

_LAYERS = {"static_layer": (StaticLayerConfig, StaticLayer), "obstacle_layer": (ObstacleLayerConfig, ObstacleLayer),
           "inflation_layer": (InflationLayerConfig, InflationLayer)}

# How far the robot may drive between two global updates, added on each side of the update window [m].
_WINDOW_TRAVEL_MARGIN_M = 1.0


def make_costmap_from_params(ns: str, default_layers, use_static_map: bool) -> Costmap2D:
    """A Costmap2D from ~ns/* (CostmapConfig keys, ~ns/plugins and each layer's keys)."""
    config = config_from_params(CostmapConfig, f"~{ns}/")
    plugins = typed_param(f"~{ns}/plugins", tuple(default_layers))
    layers = []
    for name in plugins:
        if name not in _LAYERS:
            raise ValueError(f"parameter ~{ns}/plugins: unknown layer {name!r}; known: {', '.join(_LAYERS)}")
        if name == "static_layer" and not use_static_map:
            continue
        config_cls, layer_cls = _LAYERS[name]
        layers.append(layer_cls(config_from_params(config_cls, f"~{ns}/{name}/")))
    return Costmap2D(config, layers)


def update_window_m(costmap: Costmap2D) -> Optional[float]:
    """Side of the square a cloud can change in ``costmap`` [m]; None = update the whole grid."""
    layer = costmap.obstacle_layer
    if layer is None or costmap.config.rolling_window:
        return None
    reach = max(layer.config.obstacle_range, layer.config.raytrace_range)
    return 2.0 * (reach + _WINDOW_TRAVEL_MARGIN_M)


class MoveBaseCostmaps:
    """The global and local costmaps of the move_base node (see the module docstring).

    ``pose_in(frame)`` gives the robot's Pose2D in a frame or None; ``lock``
    guards the costmaps against the control loop.
    """

    def __init__(self, lock: threading.RLock, tf_buffer: tf2_ros.Buffer, use_static_map: bool, pose_in):
        self.lock = lock
        self.tf_buffer = tf_buffer
        self.pose_in = pose_in
        self.use_static_map = use_static_map
        self.global_costmap = make_costmap_from_params("global_costmap", ("static_layer", "inflation_layer"),
                                                       use_static_map)
        self.local_costmap = make_costmap_from_params("local_costmap", ("obstacle_layer", "inflation_layer"),
                                                      use_static_map)
        self.global_frame = self.global_costmap.config.global_frame
        self.local_frame = self.local_costmap.config.global_frame
        self.base_frame = self.local_costmap.config.robot_base_frame
        self.global_window_m = update_window_m(self.global_costmap)
        self.map_received = not use_static_map
        self._cloud: Optional[Tuple[np.ndarray, np.ndarray]] = None          # latest, local frame
        self._global_cloud: Optional[Tuple[np.ndarray, np.ndarray]] = None   # latest, for the global costmap
        self._global_dirty = True
        self._map_unsent = True

    def start(self) -> None:
        """Subscribe, advertise and start the update timers."""
        self.global_pub = rospy.Publisher("~global_costmap/costmap", OccupancyGrid, queue_size=1, latch=True)
        self.local_pub = rospy.Publisher("~local_costmap/costmap", OccupancyGrid, queue_size=1)
        if self.use_static_map:
            rospy.Subscriber(typed_param("~map_topic", "/map"), OccupancyGrid, self._on_map, queue_size=1)
        if self.local_costmap.obstacle_layer is not None or self.global_costmap.obstacle_layer is not None:
            topic = typed_param("~local_costmap/obstacle_layer/point_cloud_topic", "/passthrough/output")
            rospy.Subscriber(topic, PointCloud2, self._on_cloud, queue_size=1, buff_size=2 ** 24)
        lc, gc = self.local_costmap.config, self.global_costmap.config
        rospy.Timer(rospy.Duration(1.0 / max(lc.update_frequency, 0.1)), self.update_local)
        if self.global_costmap.obstacle_layer is not None:
            rospy.Timer(rospy.Duration(1.0 / max(gc.update_frequency, 0.1)), self.update_global)
        rospy.Timer(rospy.Duration(1.0 / max(lc.publish_frequency, 0.1)), self.publish)

    # ------------------------------------------------------------- inputs
    def _on_map(self, msg: OccupancyGrid) -> None:
        try:
            occ, spec = occupancy_from_msg(msg)
        except ValueError as exc:
            rospy.logwarn("move_base: ignoring map: %s", exc)
            return
        if msg.header.frame_id and msg.header.frame_id.lstrip("/") != self.global_frame:
            rospy.logwarn("move_base: map is in frame %s, the global costmap in %s; using it as %s",
                          msg.header.frame_id, self.global_frame, self.global_frame)
        with self.lock:
            cm = self.global_costmap
            if not cm.config.rolling_window:
                cm.resize(spec)
            cm.static_layer.set_map(occ, spec, track_unknown_space=cm.config.track_unknown_space)
            cm.update_map(Pose2D(*spec.map_to_world(0, 0), 0.0))
            self.map_received = True
            self._global_dirty = True
            self._map_unsent = True
        rospy.loginfo("move_base: static map %d x %d cells at %.3f m", spec.width, spec.height, spec.resolution_m)

    def _on_cloud(self, msg: PointCloud2) -> None:
        try:
            xyz = conv.cloud_to_xyz(msg, skip_nans=True)
            t = self.tf_buffer.lookup_transform(self.local_frame, msg.header.frame_id, msg.header.stamp,
                                                rospy.Duration(0.2)).transform
        except ValueError as exc:
            rospy.logwarn_throttle(5.0, f"move_base: ignoring cloud: {exc}")
            return
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            rospy.logwarn_throttle(5.0, f"move_base: no TF for the cloud: {exc}")
            return
        m = transform_matrix(t)
        pts = xyz.astype(float) @ m[:3, :3].T + m[:3, 3]
        with self.lock:
            self._cloud = (pts, m[:3, 3].copy())
            self._global_cloud = self._cloud

    # ------------------------------------------------------------- updates
    def update_local(self, _event=None) -> None:
        pose = self.pose_in(self.local_frame)
        if pose is None:
            return
        with self.lock:
            if self._cloud is not None and self.local_costmap.obstacle_layer is not None:
                self.local_costmap.obstacle_layer.add_observation(*self._cloud)
                self._cloud = None
            self.local_costmap.update_map(pose)

    def update_global(self, _event=None) -> None:
        """Mark the latest cloud (local frame, moved into the global frame) in the global obstacle layer."""
        if not self.map_received:
            return
        gpose, lpose = self.pose_in(self.global_frame), self.pose_in(self.local_frame)
        if gpose is None or lpose is None:
            return
        to_global = compose(gpose, inverse(lpose))            # global <- local
        c, s = math.cos(to_global.yaw_rad), math.sin(to_global.yaw_rad)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        shift = np.array([to_global.x_m, to_global.y_m, 0.0])
        with self.lock:
            if self._global_cloud is not None:
                pts, origin = self._global_cloud
                self.global_costmap.obstacle_layer.add_observation(pts @ rot.T + shift, rot @ origin + shift)
                self._global_cloud = None
            self.global_costmap.update_map(gpose, self.global_window_m)
            self._global_dirty = True

    def publish(self, _event=None) -> None:
        stamp = rospy.Time.now()
        with self.lock:
            # the whole global grid (4 M cells for GPS mode's 100 x 100 m map) goes out once per map and
            # then only while someone listens
            if self._global_dirty and self.map_received and (self._map_unsent or self.global_pub.get_num_connections()):
                self._map_unsent = False
                self.global_pub.publish(costmap_msg(self.global_costmap, self.global_frame, stamp))
                self._global_dirty = False
            if self.local_pub.get_num_connections() > 0:
                self.local_pub.publish(costmap_msg(self.local_costmap, self.local_frame, stamp))
