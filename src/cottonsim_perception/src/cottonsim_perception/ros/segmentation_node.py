"""Scene segmentation node of Cotton-Eye: plants / ground / sky masks of the front camera.

Node ``segmentation`` (executable nodes/segmentation). Turns each frame of
the front camera into per-class masks and one label image, which the row
centring node (and rviz) consume. Two mask sources, chosen by ~mask_source:

* ``network``: the trained scene segmentation network
  (:class:`cottonsim_perception.inference.Predictor` with ~weights, run by
  ~backend: ONNX Runtime on the ``.onnx`` export beside the weights, falling
  back to torch with a warning if that export is missing or stale). Missing
  or unreadable weights are logged once as an error naming the path; the
  node then stays up, publishes no masks and reports backend 'none' and the
  error on /cotton_eye/health (it never crashes).
* ``ground_truth``: the simulator's semantic image: an oracle that lets
  navigation and tests run before the network is trained and measures what
  perfect segmentation gives.

Frames are processed at ~rate_hz at most (sim time, by their stamps:
:class:`cottonsim_perception.monitoring.rate_gate.RateGate`); the frames in
between are dropped, never queued, and only the newest frame waits
(queue_size 1, large buff_size), so a slow network skips frames instead of
falling behind. A black frame (a camera blackout) is counted and skipped; a
camera that stops is reported stale and used again with its next frame.

Subscriptions
  /<camera>/color/image_raw            sensor_msgs/Image  rgb8 / bgr8 (network source; also the overlay's background)
  /<camera>/ground_truth/semantic      sensor_msgs/Image  mono8 SemanticClass ids (ground_truth source)
Publications
  ~labels          sensor_msgs/Image  mono8: 0 plant, 1 ground, 2 sky, 3 boll, 255 unlabelled (frame and stamp of the input)
  ~mask/plants     sensor_msgs/Image  mono8 0/255 (plant and boll pixels)
  ~mask/ground     sensor_msgs/Image  mono8 0/255
  ~mask/sky        sensor_msgs/Image  mono8 0/255
  ~overlay         sensor_msgs/Image  rgb8, label colours over the camera image (only built while subscribed)
  ~latency_ms      std_msgs/Float32   wall time from receiving a frame to publishing its masks [ms]
  /cotton_eye/health  cottonsim_msgs/CottonEyeHealth  every ~health_period_s: frames received / processed /
                   black / without ground or sky ('no estimate') / stale, the backend (ros/health_reporting.py)
  /sim/frames_done std_msgs/Header    per frame taken: its stamp, frame_id ~camera (a simulator may wait for it,
                                      cottonsim_common/ros/frames_done.py)
Parameters (private; config/segmentation.yaml documents each)
  ~camera (str, realsense_p), ~mask_source (str, network), ~weights (str, ''), ~device (str, cpu),
  ~conf_threshold (float, 0.25), ~iou_threshold (float, 0.7), ~threads (int, 1), ~overlay_alpha (float, 0.5),
  ~mask_threshold (float, -1 = the calibrated value stored in the weights, else 0.5),
  ~backend (str, onnxruntime), ~rate_hz (float, 5.0), ~stale_after_s (float, 1.0), ~black_max_mean (float, 2.0),
  ~black_warn_frames (int, 10), ~no_estimate_warn_frames (int, 25), ~health_period_s (float, 1.0)
TF: none.
"""
from __future__ import annotations

import threading
import time
from typing import Optional

import numpy as np
import rospy
from sensor_msgs.msg import Image
from std_msgs.msg import Float32

from cottonsim_common.ros import conversions as conv
from cottonsim_common.ros.frames_done import FramesDonePublisher
from cottonsim_perception.monitoring.input_health import is_black
from cottonsim_perception.monitoring.rate_gate import RateGate, check_rate_hz
from cottonsim_perception.ros.health_reporting import HealthReporter
from cottonsim_perception.ros.predictor_loading import backend_from_params, load_predictor

from cottonsim_perception.localization import (BOLL, GROUND, PLANT, SKY, colorize_labels,
                                               label_image_from_detections)

MASK_SOURCES = ("network", "ground_truth")
BUFF_SIZE = 1 << 24          # bytes: larger than one 640x480 rgb8 frame, so rospy keeps only the newest


class SegmentationNode:
    """Per-class masks and a label image of one camera (see the module docstring for the ROS API)."""

    def __init__(self):
        self.camera = str(rospy.get_param("~camera", "realsense_p"))
        self.mask_source = str(rospy.get_param("~mask_source", "network"))
        if self.mask_source not in MASK_SOURCES:
            raise ValueError(f"~mask_source must be one of {MASK_SOURCES}, got '{self.mask_source}'")
        self.overlay_alpha = float(rospy.get_param("~overlay_alpha", 0.5))
        if not 0.0 <= self.overlay_alpha <= 1.0:
            raise ValueError(f"~overlay_alpha must be in [0, 1], got {self.overlay_alpha}")
        self.rate_hz = check_rate_hz(rospy.get_param("~rate_hz", 5.0), "~rate_hz")
        self.gate = RateGate(self.rate_hz)
        self.predictor = None
        self.weights = str(rospy.get_param("~weights", ""))
        backend, error = "ground_truth", ""
        if self.mask_source == "network":
            self.predictor, backend, error = load_predictor("segmentation", self.weights, "~mask_source", "seg",
                                                            backend_from_params())
        self.health = HealthReporter("segmentation", [self.camera], backend, error)

        self.labels_pub = rospy.Publisher("~labels", Image, queue_size=1)
        self.mask_pubs = {name: rospy.Publisher(f"~mask/{name}", Image, queue_size=1)
                          for name in ("plants", "ground", "sky")}
        self.overlay_pub = rospy.Publisher("~overlay", Image, queue_size=1)
        self.latency_pub = rospy.Publisher("~latency_ms", Float32, queue_size=1)
        self.frames_done = FramesDonePublisher()        # /sim/frames_done: a simulator may wait for it

        self._lock = threading.Lock()
        self._last_rgb: Optional[Image] = None
        image_topic = f"/{self.camera}/color/image_raw"
        if self.mask_source == "network":
            rospy.Subscriber(image_topic, Image, self._on_image, queue_size=1, buff_size=BUFF_SIZE)
        else:
            rospy.Subscriber(f"/{self.camera}/ground_truth/semantic", Image, self._on_semantic,
                             queue_size=1, buff_size=BUFF_SIZE)
            # the camera image is only the overlay's background here
            rospy.Subscriber(image_topic, Image, self._keep_rgb, queue_size=1, buff_size=BUFF_SIZE)
        self.health.start_timer(self.rate_hz)
        rospy.loginfo("segmentation: camera %s, mask source %s, at most %.1f Hz", self.camera, self.mask_source,
                      self.rate_hz)

    # ------------------------------------------------------------------ callbacks
    def _keep_rgb(self, msg: Image):
        with self._lock:
            self._last_rgb = msg

    def _take(self, msg: Image) -> bool:
        """Count the frame; True if it is to be processed (its rate slot is free)."""
        with self.health.lock:
            self.health.inputs[self.camera].received(rospy.get_time())
            return self.gate.take(msg.header.stamp.to_sec())

    def _count_black(self):
        with self.health.lock:
            self.health.inputs[self.camera].black()

    def _count_processed(self, labels: np.ndarray):
        """A processed frame; without ground or sky pixels it has no estimate (row centring needs both)."""
        has_estimate = bool((labels == GROUND).any() and (labels == SKY).any())
        with self.health.lock:
            self.health.inputs[self.camera].processed(has_estimate)

    def _on_image(self, msg: Image):
        self._keep_rgb(msg)
        self._process_if_taken(msg, self._segment)

    def _process_if_taken(self, msg: Image, process):
        """Count the frame; if its slot is free, process(msg, t0) it and say on /sim/frames_done that it is done."""
        t0 = time.perf_counter()
        if not self._take(msg):
            return
        try:
            process(msg, t0)
        finally:
            self.frames_done.done(self.camera, msg.header.stamp)

    def _segment(self, msg: Image, t0: float):
        if self.predictor is None:
            return
        try:
            rgb = conv.image_to_array(msg)
            if rgb.ndim != 3:
                raise ValueError(f"expected a colour image, got encoding '{msg.encoding}'")
            if is_black(rgb, self.health.config.black_max_mean):
                self._count_black()
                return
            dets = self.predictor.predict(rgb)
            labels = label_image_from_detections(dets, rgb.shape[:2])
        except ValueError as exc:
            rospy.logwarn_throttle(5.0, f"segmentation: frame skipped: {exc}")
            return
        self._count_processed(labels)
        self._publish(labels, msg, t0, rgb)

    def _on_semantic(self, msg: Image):
        self._process_if_taken(msg, self._segment_ground_truth)

    def _segment_ground_truth(self, msg: Image, t0: float):
        try:
            semantic = conv.image_to_array(msg)
            if semantic.ndim != 2:
                raise ValueError(f"ground-truth semantic image must be mono8, got '{msg.encoding}'")
        except ValueError as exc:
            rospy.logwarn_throttle(5.0, f"segmentation: ground-truth frame skipped: {exc}")
            return
        labels = np.where(semantic <= BOLL, semantic, 255).astype(np.uint8)
        self._count_processed(labels)
        self._publish(labels, msg, t0, None)

    def _publish(self, labels: np.ndarray, src: Image, t0: float, rgb: Optional[np.ndarray]):
        stamp, frame = src.header.stamp, src.header.frame_id
        self.labels_pub.publish(conv.image_msg(labels, stamp, frame))
        plants = (labels == PLANT) | (labels == BOLL)
        for name, m in (("plants", plants), ("ground", labels == GROUND), ("sky", labels == SKY)):
            if self.mask_pubs[name].get_num_connections():
                self.mask_pubs[name].publish(conv.image_msg(m.astype(np.uint8) * 255, stamp, frame))
        latency_ms = 1e3 * (time.perf_counter() - t0)
        self.latency_pub.publish(Float32(data=latency_ms))
        rospy.logdebug("segmentation: frame %.3f done in %.1f ms", stamp.to_sec(), latency_ms)
        if self.overlay_pub.get_num_connections():
            self._publish_overlay(labels, stamp, frame, rgb)

    def _publish_overlay(self, labels, stamp, frame, rgb):
        if rgb is None:
            with self._lock:
                last = self._last_rgb
            if last is not None:
                try:
                    rgb = conv.image_to_array(last)
                except ValueError:
                    rgb = None
        if rgb is not None and rgb.shape[:2] != labels.shape:
            rgb = None
        overlay = colorize_labels(labels, rgb, self.overlay_alpha) if rgb is not None else colorize_labels(labels)
        self.overlay_pub.publish(conv.image_msg(overlay, stamp, frame))
