"""Boll detection node of Cotton-Eye: cotton bolls of one side camera, located in 3-D.

Node ``boll_detection`` (executable nodes/boll_detection; one instance per
side camera, ~camera). For each frame: 2-D boxes from the detector, then for
each box the 3-D position (per-axis median of the depth-cloud points that
project into the box, :func:`cottonsim_perception.localization.localize_boxes`),
transformed into base_link with tf2, and whether any boll lies within the
UR5e's reach (distance from ~arm_base_frame <= ~reach_m) so that a
navigator can halt for picking.

Box sources (~source):
* ``network``: the trained boll detector (Predictor with ~weights). Missing
  or unreadable weights are logged as an error naming the path, and nothing
  is published (the node stays up).
* ``ground_truth``: connected components of boll pixels (class 3) in the
  simulator's semantic image, score 1: an oracle for tests and for
  measuring the rest of the chain before the detector is trained.

Frames and their depth clouds are paired by equal stamps (the simulator
stamps both with the render time); the newest pair is processed by the
main loop, older unprocessed pairs are dropped.

Subscriptions
  /<camera>/color/image_raw          sensor_msgs/Image        rgb8 (network source; overlay background)
  /<camera>/ground_truth/semantic    sensor_msgs/Image        mono8 (ground_truth source)
  /<camera>/depth/color/points       sensor_msgs/PointCloud2  x y z [rgb] in <camera>_color_optical_frame
  /<camera>/color/camera_info        sensor_msgs/CameraInfo   K: projects cloud points into the boxes
Publications
  ~detections                cottonsim_msgs/BollDetections  header.frame_id = ~target_frame (base_link), camera,
                                                            boxes [px], scores, positions [m], in_reach
  /cotton_eye/bolls_in_reach std_msgs/Bool                  true while some camera sees a boll in reach
                                                            (each instance publishes its own verdict per frame)
  ~overlay                   sensor_msgs/Image              rgb8 boxes (green: in reach) (only built while subscribed)
Parameters (private; config/boll_detection.yaml documents each)
  ~camera (str, realsense_secondary), ~source (str, network), ~weights (str, ''), ~device (str, cpu),
  ~conf_threshold (float, 0.25), ~iou_threshold (float, 0.7), ~threads (int, 1),
  ~target_frame (str, base_link), ~arm_base_frame (str, ur5e_base_link), ~reach_m (float, 0.85),
  ~min_box_area_px (int, 4), ~min_points (int, 3), ~box_shrink_fraction (float, 0.15),
  ~max_depth_m (float, 4.0), ~front_depth_m (float, 0.15), ~rate_hz (float, 10.0): how often the main loop looks for a new pair
TF (looked up): ~target_frame <- <camera>_color_optical_frame, ~arm_base_frame <- <camera>_color_optical_frame
"""
from __future__ import annotations

import collections
import threading
from typing import Optional

import numpy as np
import rospy
import tf2_ros
from cottonsim_msgs.msg import BollDetection, BollDetections
from geometry_msgs.msg import Point
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_msgs.msg import Bool

from cottonsim_world.ros import conversions as conv
from cottonsim_perception.ros.predictor_loading import load_predictor

from cottonsim_perception.localization import (BOLL, BollLocalizationConfig, boxes_from_semantic, localize_boxes,
                                               points_within_reach, transform_points)

SOURCES = ("network", "ground_truth")
BUFF_SIZE = 1 << 25


class BollDetectionNode:
    """Boxes + depth -> BollDetections in base_link (see the module docstring for the ROS API)."""

    def __init__(self):
        self.camera = str(rospy.get_param("~camera", "realsense_secondary"))
        self.source = str(rospy.get_param("~source", "network"))
        if self.source not in SOURCES:
            raise ValueError(f"~source must be one of {SOURCES}, got '{self.source}'")
        self.target_frame = str(rospy.get_param("~target_frame", "base_link"))
        self.arm_base_frame = str(rospy.get_param("~arm_base_frame", "ur5e_base_link"))
        self.reach_m = float(rospy.get_param("~reach_m", 0.85))
        if not (np.isfinite(self.reach_m) and self.reach_m > 0):
            raise ValueError(f"~reach_m must be > 0, got {self.reach_m}")
        self.min_box_area_px = int(rospy.get_param("~min_box_area_px", 4))
        if self.min_box_area_px < 1:
            raise ValueError(f"~min_box_area_px must be >= 1, got {self.min_box_area_px}")
        self.loc_config = BollLocalizationConfig(
            min_points=int(rospy.get_param("~min_points", 3)),
            box_shrink_fraction=float(rospy.get_param("~box_shrink_fraction", 0.15)),
            max_depth_m=float(rospy.get_param("~max_depth_m", 4.0)),
            front_depth_m=float(rospy.get_param("~front_depth_m", 0.15)))
        self.rate_hz = float(rospy.get_param("~rate_hz", 10.0))
        if not (np.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ValueError(f"~rate_hz must be > 0, got {self.rate_hz}")
        self.weights = str(rospy.get_param("~weights", ""))
        self.predictor = (load_predictor("boll_detection", self.weights, "~source")
                          if self.source == "network" else None)
        self.optical_frame = f"{self.camera}_color_optical_frame"

        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.detections_pub = rospy.Publisher("~detections", BollDetections, queue_size=2)
        self.in_reach_pub = rospy.Publisher("/cotton_eye/bolls_in_reach", Bool, queue_size=2)
        self.overlay_pub = rospy.Publisher("~overlay", Image, queue_size=1)

        self._lock = threading.Lock()
        self._frames = collections.OrderedDict()      # stamp ns -> Image (box source)
        self._rgb = collections.OrderedDict()         # stamp ns -> Image (overlay)
        self._clouds = collections.OrderedDict()      # stamp ns -> PointCloud2
        self._info: Optional[CameraInfo] = None
        self._done_ns = -1
        base = f"/{self.camera}"
        frame_topic = f"{base}/color/image_raw" if self.source == "network" else f"{base}/ground_truth/semantic"
        rospy.Subscriber(frame_topic, Image, self._store, (self._frames,), queue_size=2, buff_size=BUFF_SIZE)
        if self.source == "ground_truth":
            rospy.Subscriber(f"{base}/color/image_raw", Image, self._store, (self._rgb,), queue_size=2,
                             buff_size=BUFF_SIZE)
        rospy.Subscriber(f"{base}/depth/color/points", PointCloud2, self._store, (self._clouds,), queue_size=2,
                         buff_size=BUFF_SIZE)
        rospy.Subscriber(f"{base}/color/camera_info", CameraInfo, self._on_info, queue_size=1)
        rospy.loginfo("boll_detection: camera %s, source %s, reach %.2f m from %s", self.camera, self.source,
                      self.reach_m, self.arm_base_frame)


    # ------------------------------------------------------------------ inputs
    def _store(self, msg, args):
        (store,) = args
        with self._lock:
            store[msg.header.stamp.to_nsec()] = msg
            while len(store) > 4:
                store.popitem(last=False)

    def _on_info(self, msg: CameraInfo):
        with self._lock:
            self._info = msg

    def _newest_pair(self):
        """(frame, cloud, rgb or None, info) of the newest stamp seen on both, or None."""
        with self._lock:
            common = sorted(set(self._frames) & set(self._clouds))
            if not common or self._info is None or common[-1] <= self._done_ns:
                return None
            ns = common[-1]
            self._done_ns = ns
            return self._frames[ns], self._clouds[ns], self._rgb.get(ns), self._info

    # ------------------------------------------------------------------ processing
    def spin(self):
        rate = rospy.Rate(self.rate_hz)
        while not rospy.is_shutdown():
            pair = self._newest_pair()
            if pair is not None:
                try:
                    self.process(*pair)
                except ValueError as exc:
                    rospy.logwarn_throttle(5.0, f"boll_detection: frame skipped: {exc}")
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                break

    def _boxes(self, frame: Image):
        if self.source == "ground_truth":
            semantic = conv.image_to_array(frame)
            if semantic.ndim != 2:
                raise ValueError(f"ground-truth semantic image must be mono8, got '{frame.encoding}'")
            boxes = boxes_from_semantic(semantic, BOLL, self.min_box_area_px)
            return boxes, np.ones(len(boxes), dtype=np.float32), None
        if self.predictor is None:
            return None
        rgb = conv.image_to_array(frame)
        if rgb.ndim != 3:
            raise ValueError(f"expected a colour image, got encoding '{frame.encoding}'")
        dets = self.predictor.predict(rgb)
        return dets.boxes_xyxy, dets.scores, rgb

    def _lookup(self, target: str, stamp):
        try:
            return self.tf_buffer.lookup_transform(target, self.optical_frame, stamp, rospy.Duration(0.2))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            try:       # camera and arm are fixed to the base: the latest transform is as good
                return self.tf_buffer.lookup_transform(target, self.optical_frame, rospy.Time(0))
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                    tf2_ros.ExtrapolationException):
                raise ValueError(f"no transform {target} <- {self.optical_frame}: {exc}")

    @staticmethod
    def _apply(tf_msg, points):
        t, q = tf_msg.transform.translation, tf_msg.transform.rotation
        return transform_points(points, (t.x, t.y, t.z), (q.x, q.y, q.z, q.w))

    def process(self, frame: Image, cloud: PointCloud2, rgb_msg: Optional[Image], info: CameraInfo):
        out = self._boxes(frame)
        if out is None:
            return
        boxes, scores, rgb = out
        xyz = conv.cloud_to_xyz(cloud)
        positions, valid = localize_boxes(boxes, xyz, info.K, self.loc_config)
        stamp = frame.header.stamp
        in_base = self._apply(self._lookup(self.target_frame, stamp), positions)
        in_arm = self._apply(self._lookup(self.arm_base_frame, stamp), positions)
        reach = points_within_reach(in_arm, self.reach_m) & valid
        msg = BollDetections(camera=self.camera, in_reach=bool(reach.any()))
        msg.header.stamp = stamp
        msg.header.frame_id = self.target_frame
        for box, score, ok, p in zip(boxes, scores, valid, in_base):
            d = BollDetection(x_min=float(box[0]), y_min=float(box[1]), x_max=float(box[2]), y_max=float(box[3]),
                              score=float(score), has_position=bool(ok))
            if ok:
                d.position = Point(float(p[0]), float(p[1]), float(p[2]))
            msg.detections.append(d)
        self.detections_pub.publish(msg)
        self.in_reach_pub.publish(Bool(data=msg.in_reach))
        if self.overlay_pub.get_num_connections():
            self._publish_overlay(frame, rgb, rgb_msg, boxes, reach)

    def _publish_overlay(self, frame, rgb, rgb_msg, boxes, reach):
        import cv2

        if rgb is None and rgb_msg is not None:
            rgb = conv.image_to_array(rgb_msg)
        if rgb is None or rgb.ndim != 3:
            rgb = np.zeros((frame.height, frame.width, 3), dtype=np.uint8)
        img = np.ascontiguousarray(rgb.copy())
        for (x0, y0, x1, y1), near in zip(boxes, reach):
            colour = (0, 255, 0) if near else (255, 160, 0)
            cv2.rectangle(img, (int(x0), int(y0)), (int(np.ceil(x1)) - 1, int(np.ceil(y1)) - 1), colour, 1)
        text = f"{len(boxes)} bolls, {int(reach.sum())} in reach"
        cv2.putText(img, text, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
        self.overlay_pub.publish(conv.image_msg(img, frame.header.stamp, frame.header.frame_id))


def main():
    rospy.init_node("boll_detection")
    try:
        node = BollDetectionNode()
    except ValueError as exc:
        rospy.logfatal(f"boll_detection: {exc}")
        raise SystemExit(2)
    node.spin()
