"""Boll detection node of Cotton-Eye: cotton bolls of the side cameras, located in 3-D.

Node ``boll_detection`` (executable nodes/boll_detection; one instance serves
every camera of ~cameras, by default both side cameras). Per slot of
1 / ~rate_hz seconds of sim time (by stamp, ``monitoring/rate_gate.py``'s slots)
it takes the first image + depth-cloud pair of each camera as soon as the pairs
of every camera that is not stale are in (a camera late by a whole slot is not
waited for), runs the detector once on all of their images together (one
batched forward pass), then for each box the 3-D position (per-axis median of the depth-cloud
points that project into the box,
:func:`cottonsim_perception.localization.localize_boxes`), transformed into
base_link with tf2, and whether any boll lies within the UR5e's reach
(distance from ~arm_base_frame <= ~reach_m) so that a navigator can halt for
picking. The other frames of a slot are dropped, never queued; a simulator that
renders the side cameras at ~rate_hz only (``render_rate_hz``) sends just the
frames taken.

Box sources (~source):
* ``network``: the trained boll detector (Predictor with ~weights, run by
  ~backend: ONNX Runtime on the ``.onnx`` export beside the weights, falling
  back to torch with a warning). Missing or unreadable weights are logged
  once as an error naming the path; the node stays up, publishes no
  detections and reports backend 'none' on /cotton_eye/health.
* ``ground_truth``: connected components of boll pixels (class 3) in the
  simulator's semantic image, score 1: an oracle for tests and for
  measuring the rest of the chain before the detector is trained.

Frames and their depth clouds are paired by equal stamps (the simulator
stamps both with the render time). A black frame (a camera blackout) is
counted and skipped; a camera without frames for ~stale_after_s is reported
stale, counts as seeing no boll in reach, and is used again with its next frame.

Subscriptions (per camera <c> of ~cameras)
  /<c>/color/image_raw          sensor_msgs/Image        rgb8 (network source; overlay background)
  /<c>/ground_truth/semantic    sensor_msgs/Image        mono8 (ground_truth source)
  /<c>/depth/color/points       sensor_msgs/PointCloud2  x y z [rgb] in <c>_color_optical_frame
  /<c>/color/camera_info        sensor_msgs/CameraInfo   K: projects cloud points into the boxes
Publications (per camera, <o> its entry of ~output_namespaces)
  /<o>/detections            cottonsim_msgs/BollDetections  header.frame_id = ~target_frame (base_link), camera,
                                                            boxes [px], scores, positions [m], in_reach
  /<o>/overlay               sensor_msgs/Image              rgb8 boxes (green: in reach) (only built while subscribed)
  /cotton_eye/bolls_in_reach std_msgs/Bool                  after each slot with a processed frame: true if the
                                                            newest verdict of some fresh camera has a boll in reach
  /cotton_eye/health         cottonsim_msgs/CottonEyeHealth every ~health_period_s: per camera frames received /
                                                            processed / black / stale, the backend
  /sim/frames_done           std_msgs/Header                per frame taken: its stamp, frame_id the camera (a
                                                            simulator may wait for it, cottonsim_common/ros/frames_done.py)
Parameters (private; config/boll_detection.yaml documents each)
  ~cameras (list, [realsense_secondary, realsense_tertiary]), ~output_namespaces (list,
  [boll_detection_left, boll_detection_right]), ~source (str, network), ~weights (str, ''),
  ~backend (str, onnxruntime), ~device (str, cpu), ~conf_threshold (float, 0.25), ~iou_threshold (float, 0.7),
  ~threads (int, 1), ~target_frame (str, base_link), ~arm_base_frame (str, ur5e_base_link), ~reach_m (float, 0.85),
  ~min_box_area_px (int, 4), ~min_points (int, 3), ~box_shrink_fraction (float, 0.15),
  ~max_depth_m (float, 4.0), ~front_depth_m (float, 0.15), ~surface_to_centre (bool, true), ~rate_hz (float, 2.0),
  ~stale_after_s (float, 1.0), ~black_max_mean (float, 2.0), ~black_warn_frames (int, 10), ~health_period_s (float, 1.0)
TF (looked up): ~target_frame <- <c>_color_optical_frame, ~arm_base_frame <- <c>_color_optical_frame
"""
from __future__ import annotations

import collections
import threading
from typing import Dict, List, Optional

import numpy as np
import rospy
import tf2_ros
from cottonsim_msgs.msg import BollDetection, BollDetections
from geometry_msgs.msg import Point
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_msgs.msg import Bool

from cottonsim_common.rate_slots import slot_index
from cottonsim_common.ros import conversions as conv
from cottonsim_common.ros.frames_done import FramesDonePublisher
from cottonsim_common.ros.params import config_from_params
from cottonsim_common.transforms import transform_points
from cottonsim_perception.monitoring.input_health import is_black
from cottonsim_perception.monitoring.rate_gate import check_rate_hz
from cottonsim_perception.ros.health_reporting import HealthReporter
from cottonsim_perception.ros.predictor_loading import backend_from_params, load_predictor

from cottonsim_perception.localization import (BOLL, BollLocalizationConfig, boxes_from_semantic, localize_boxes,
                                               points_within_reach)

SOURCES = ("network", "ground_truth")
BUFF_SIZE = 1 << 25
KEPT_PER_TOPIC = 4          # newest messages kept per topic while waiting for their partner
WAKE_PERIOD_S = 0.1         # wall time between looks at the inputs when no message wakes the loop


def _string_list(name: str, default: List[str]) -> List[str]:
    value = rospy.get_param(name, default)
    if not isinstance(value, (list, tuple)) or not value or not all(isinstance(v, str) and v for v in value):
        raise ValueError(f"{name} must be a non-empty list of names, got {value!r}")
    return list(value)


class CameraInputs:
    """The newest messages of one camera, paired by stamp (filled by subscriber callbacks, under the node's lock)."""

    def __init__(self, camera: str, output_namespace: str):
        self.camera = camera
        self.optical_frame = f"{camera}_color_optical_frame"
        self.frames = collections.OrderedDict()      # stamp ns -> Image (box source)
        self.rgb = collections.OrderedDict()         # stamp ns -> Image (overlay)
        self.clouds = collections.OrderedDict()      # stamp ns -> PointCloud2
        self.info: Optional[CameraInfo] = None
        self.done_ns = -1
        self.done_slot: Optional[int] = None
        self.in_reach = False
        self.detections_pub = rospy.Publisher(f"/{output_namespace}/detections", BollDetections, queue_size=2)
        self.overlay_pub = rospy.Publisher(f"/{output_namespace}/overlay", Image, queue_size=1)

    def pending_stamp(self, rate_hz: float) -> Optional[int]:
        """Stamp [ns] of the first pair (image and cloud) of the newest slot not processed yet, or None."""
        common = sorted(set(self.frames) & set(self.clouds))
        if not common or self.info is None:
            return None
        if common[-1] < self.done_ns:          # the clock went back (the simulator restarted): start again
            self.done_slot = None
        newest_slot = slot_index(common[-1] * 1e-9, rate_hz)
        if self.done_slot is not None and newest_slot <= self.done_slot:
            return None
        return next(ns for ns in common if slot_index(ns * 1e-9, rate_hz) == newest_slot)

    def take(self, ns: int, rate_hz: float):
        """(frame, cloud, rgb or None, info) of the pair stamped ``ns``; its slot is used up."""
        self.done_ns = ns
        self.done_slot = slot_index(ns * 1e-9, rate_hz)
        return self.frames[ns], self.clouds[ns], self.rgb.get(ns), self.info


class BollDetectionNode:
    """Boxes + depth -> BollDetections in base_link, for every camera (see the module docstring for the ROS API)."""

    def __init__(self):
        cameras = _string_list("~cameras", ["realsense_secondary", "realsense_tertiary"])
        outputs = _string_list("~output_namespaces", ["boll_detection_left", "boll_detection_right"])
        if len(outputs) != len(cameras):
            raise ValueError(f"~output_namespaces needs one entry per camera of ~cameras: {outputs} for {cameras}")
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
        self.loc_config = config_from_params(BollLocalizationConfig, "~")
        self.rate_hz = check_rate_hz(rospy.get_param("~rate_hz", 2.0), "~rate_hz")
        self.weights = str(rospy.get_param("~weights", ""))
        self.predictor, backend, error = None, "ground_truth", ""
        if self.source == "network":
            self.predictor, backend, error = load_predictor("boll_detection", self.weights, "~source", "det",
                                                            backend_from_params())
        self.health = HealthReporter("boll_detection", cameras, backend, error)
        self.lock = self.health.lock
        self.inputs_changed = threading.Condition(self.lock)     # notified by every stored message
        self._idle_next_s: Optional[float] = None

        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.in_reach_pub = rospy.Publisher("/cotton_eye/bolls_in_reach", Bool, queue_size=2)
        self.frames_done = FramesDonePublisher()        # /sim/frames_done: a simulator may wait for it
        self.cameras: Dict[str, CameraInputs] = {}
        for camera, output in zip(cameras, outputs):
            inputs = self.cameras[camera] = CameraInputs(camera, output)
            base = f"/{camera}"
            frame_topic = f"{base}/color/image_raw" if self.source == "network" else f"{base}/ground_truth/semantic"
            rospy.Subscriber(frame_topic, Image, self._store_frame, (camera,), queue_size=2, buff_size=BUFF_SIZE)
            if self.source == "ground_truth":
                rospy.Subscriber(f"{base}/color/image_raw", Image, self._store, (inputs.rgb,), queue_size=2,
                                 buff_size=BUFF_SIZE)
            rospy.Subscriber(f"{base}/depth/color/points", PointCloud2, self._store, (inputs.clouds,), queue_size=2,
                             buff_size=BUFF_SIZE)
            rospy.Subscriber(f"{base}/color/camera_info", CameraInfo, self._on_info, (camera,), queue_size=1)
        rospy.loginfo("boll_detection: cameras %s, source %s, %.1f Hz, reach %.2f m from %s", ", ".join(cameras),
                      self.source, self.rate_hz, self.reach_m, self.arm_base_frame)

    # ------------------------------------------------------------------ inputs
    def _store(self, msg, args):
        (store,) = args
        with self.inputs_changed:
            store[msg.header.stamp.to_nsec()] = msg
            while len(store) > KEPT_PER_TOPIC:
                store.popitem(last=False)
            self.inputs_changed.notify()

    def _store_frame(self, msg: Image, args):
        (camera,) = args
        with self.lock:
            self.health.inputs[camera].received(rospy.get_time())
        self._store(msg, (self.cameras[camera].frames,))

    def _on_info(self, msg: CameraInfo, args):
        (camera,) = args
        with self.lock:
            self.cameras[camera].info = msg

    # ------------------------------------------------------------------ processing
    def spin(self):
        self.health.start_timer(self.rate_hz)
        while not rospy.is_shutdown():
            with self.inputs_changed:
                self.inputs_changed.wait(WAKE_PERIOD_S)
            self.step()

    def _take_pairs(self, now_s: float):
        """camera -> pair of the slot to process now ({} if none): every fresh camera's, or those of a slot
        whose partners are late by a whole slot."""
        with self.lock:
            pending = {c: inputs.pending_stamp(self.rate_hz) for c, inputs in self.cameras.items()}
            ready = {c: ns for c, ns in pending.items() if ns is not None}
            if not ready:
                return {}
            waiting = [c for c in self.cameras if c not in ready and not self.health.inputs[c].stale]
            if waiting and now_s < min(ready.values()) * 1e-9 + 1.0 / self.rate_hz:
                return {}
            return {c: self.cameras[c].take(ns, self.rate_hz) for c, ns in ready.items()}

    def step(self):
        """The slot's pair of every camera through the detector (one batch), then published; with no
        frame to process for a slot's length, an all-stale 'no boll in reach'."""
        now_s = rospy.get_time()
        pairs = self._take_pairs(now_s)
        if not pairs:
            due = self._idle_next_s is not None and now_s >= self._idle_next_s
            if due:
                self._publish_in_reach_if_all_stale()
            if due or self._idle_next_s is None or self._idle_next_s - now_s > 1.0 / self.rate_hz:
                self._idle_next_s = now_s + 1.0 / self.rate_hz      # (also after the clock went back)
            return
        self._idle_next_s = now_s + 1.0 / self.rate_hz
        try:
            self._detect(pairs)
        finally:
            for camera, pair in pairs.items():
                self.frames_done.done(camera, pair[0].header.stamp)

    def _detect(self, pairs):
        work = {}
        for camera, pair in pairs.items():
            try:
                image = self._frame_array(pair[0])
            except ValueError as exc:
                rospy.logwarn_throttle(5.0, f"boll_detection: {camera}: frame skipped: {exc}")
                continue
            if self.source == "network" and is_black(image, self.health.config.black_max_mean):
                with self.lock:
                    self.health.inputs[camera].black()
                    self.cameras[camera].in_reach = False
                continue
            work[camera] = (image, pair)
        if not work:
            self._publish_in_reach_if_all_stale()
            return
        boxes = self._boxes({c: image for c, (image, _) in work.items()})
        if boxes is None:
            return
        for camera, (image, pair) in work.items():
            try:
                self.process(camera, *pair, *boxes[camera], image)
            except ValueError as exc:
                rospy.logwarn_throttle(5.0, f"boll_detection: {camera}: frame skipped: {exc}")
                continue
            with self.lock:
                self.health.inputs[camera].processed()
        self._publish_in_reach()

    def _frame_array(self, frame: Image) -> np.ndarray:
        image = conv.image_to_array(frame)
        if self.source == "ground_truth" and image.ndim != 2:
            raise ValueError(f"ground-truth semantic image must be mono8, got '{frame.encoding}'")
        if self.source == "network" and image.ndim != 3:
            raise ValueError(f"expected a colour image, got encoding '{frame.encoding}'")
        return image

    def _boxes(self, images: Dict[str, np.ndarray]):
        """camera -> (boxes, scores) for each image, the network's in one forward pass; None without a network."""
        if self.source == "ground_truth":
            out = {}
            for camera, semantic in images.items():
                boxes = boxes_from_semantic(semantic, BOLL, self.min_box_area_px)
                out[camera] = (boxes, np.ones(len(boxes), dtype=np.float32))
            return out
        if self.predictor is None:
            return None
        detections = self.predictor.predict_batch(list(images.values()))
        return {camera: (d.boxes_xyxy, d.scores) for camera, d in zip(images, detections)}

    def _lookup(self, target: str, source: str, stamp) -> np.ndarray:
        """The 4x4 ``target_T_source`` at ``stamp`` (else the latest), or ValueError naming both frames."""
        try:
            return conv.transform_matrix(self.tf_buffer.lookup_transform(target, source, stamp, rospy.Duration(0.2)))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            try:       # camera and arm are fixed to the base: the latest transform is as good
                return conv.transform_matrix(self.tf_buffer.lookup_transform(target, source, rospy.Time(0)))
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                    tf2_ros.ExtrapolationException):
                raise ValueError(f"no transform {target} <- {source}: {exc}")

    def process(self, camera: str, frame: Image, cloud: PointCloud2, rgb_msg: Optional[Image], info: CameraInfo,
                boxes: np.ndarray, scores: np.ndarray, image: np.ndarray):
        """Locate one camera's boxes in 3-D and publish its BollDetections (and overlay)."""
        inputs = self.cameras[camera]
        xyz = conv.cloud_to_xyz(cloud)
        colour = image if image.ndim == 3 else None            # the network's rgb8 frame (not a semantic image)
        positions, valid = localize_boxes(boxes, xyz, info.K, self.loc_config, colour)
        stamp = frame.header.stamp
        in_base = transform_points(self._lookup(self.target_frame, inputs.optical_frame, stamp), positions)
        in_arm = transform_points(self._lookup(self.arm_base_frame, inputs.optical_frame, stamp), positions)
        reach = points_within_reach(in_arm, self.reach_m) & valid
        msg = BollDetections(camera=camera, in_reach=bool(reach.any()))
        msg.header.stamp = stamp
        msg.header.frame_id = self.target_frame
        for box, score, ok, p in zip(boxes, scores, valid, in_base):
            d = BollDetection(x_min=float(box[0]), y_min=float(box[1]), x_max=float(box[2]), y_max=float(box[3]),
                              score=float(score), has_position=bool(ok))
            if ok:
                d.position = Point(float(p[0]), float(p[1]), float(p[2]))
            msg.detections.append(d)
        inputs.detections_pub.publish(msg)
        with self.lock:
            inputs.in_reach = msg.in_reach
        if inputs.overlay_pub.get_num_connections():
            rgb = image if self.source == "network" else None
            self._publish_overlay(inputs.overlay_pub, frame, rgb, rgb_msg, boxes, reach)

    def _publish_in_reach(self):
        with self.lock:
            verdict = any(inputs.in_reach and not self.health.inputs[c].stale for c, inputs in self.cameras.items())
        self.in_reach_pub.publish(Bool(data=verdict))

    def _publish_in_reach_if_all_stale(self):
        """With no camera sending, say once per slot that no boll is in reach (a halted robot goes on)."""
        with self.lock:
            all_stale = all(self.health.inputs[c].stale for c in self.cameras)
        if all_stale:
            self.in_reach_pub.publish(Bool(data=False))

    @staticmethod
    def _publish_overlay(publisher, frame, rgb, rgb_msg, boxes, reach):
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
        publisher.publish(conv.image_msg(img, frame.header.stamp, frame.header.frame_id))
