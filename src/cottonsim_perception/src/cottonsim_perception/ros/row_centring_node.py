"""Row-centring node of Cotton-Eye: steering from the ground and sky masks (paper Fig. 10).

Node ``row_centring`` (executable nodes/row_centring). Reads the label image
of the segmentation node, runs
:func:`cottonsim_perception.row_centring.compute_row_centring` on its ground
and sky masks and publishes the original's two outputs. When a frame gives
no estimate (masks missing, lines parallel, a wrong encoding, an empty
frame) nothing is published on those two topics - a consumer never acts on
a stale value - and ~status says why.

Subscriptions
  ~labels_topic (default /segmentation/labels)  sensor_msgs/Image  mono8 SemanticClass ids
                                                (1 ground, 2 sky; others ignored)
Publications
  /mask/intersection/centerskyground  std_msgs/Int16              intersection x [px] (the original's topic), only with an estimate
  /husky/cv/coords                    std_msgs/Float64MultiArray  [linear_x m/s, angular_z rad/s], only with an estimate
  ~status                             std_msgs/String             'ok: <decision> x=<px>' or 'no_estimate: <reason>', every frame
  ~overlay                            sensor_msgs/Image           rgb8: masks, lines, points, decision (only built while subscribed)
  /cotton_eye/health                  cottonsim_msgs/CottonEyeHealth  every ~health_period_s: label frames received /
                                      processed / without an estimate / stale (backend ''); a run of
                                      ~no_estimate_warn_frames frames without an estimate is logged as a warning
Parameters (private; config/row_centring.yaml documents each)
  ~labels_topic (str), and every field of RowCentringConfig under the same name
  (dead_band_px, gain_per_s, max_correction_rad, forward_speed_mps, horizontal_fov_rad,
  min_mask_area_px, band_rows, min_row_pixels, parallel_tolerance, intersection_margin_px,
  coincident_tolerance_px, trace_strips); a field left out keeps its default;
  ~check_hz (float, 5.0): how often the label images' staleness is checked [Hz, sim time], and the health keys
  ~stale_after_s, ~no_estimate_warn_frames, ~health_period_s (ros/health_reporting.py).
TF: none.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import rospy
from sensor_msgs.msg import Image
from std_msgs.msg import Float64MultiArray, Int16, String

from cottonsim_common.ros import conversions as conv

from cottonsim_perception.localization import GROUND, SKY, colorize_labels
from cottonsim_perception.monitoring.rate_gate import check_rate_hz
from cottonsim_perception.ros.health_reporting import HealthReporter
from cottonsim_perception.row_centring import RowCentringConfig, compute_row_centring, draw_row_centring

INT16_MAX = 32767


def config_from_params() -> RowCentringConfig:
    """RowCentringConfig from the node's private parameters (ValueError names a bad one)."""
    values = {}
    for field in dataclasses.fields(RowCentringConfig):
        if rospy.has_param(f"~{field.name}"):
            values[field.name] = rospy.get_param(f"~{field.name}")
    return RowCentringConfig(**values)


class RowCentringNode:
    """Label image -> row-centring command (see the module docstring for the ROS API)."""

    def __init__(self):
        self.config = config_from_params()
        self.labels_topic = str(rospy.get_param("~labels_topic", "/segmentation/labels"))
        self.intersection_pub = rospy.Publisher("/mask/intersection/centerskyground", Int16, queue_size=1)
        self.coords_pub = rospy.Publisher("/husky/cv/coords", Float64MultiArray, queue_size=1)
        self.status_pub = rospy.Publisher("~status", String, queue_size=5)
        self.overlay_pub = rospy.Publisher("~overlay", Image, queue_size=1)
        self.health = HealthReporter("row_centring", [self.labels_topic])
        self.health.start_timer(check_rate_hz(rospy.get_param("~check_hz", 5.0), "~check_hz"))
        rospy.Subscriber(self.labels_topic, Image, self._on_labels, queue_size=1, buff_size=1 << 24)
        rospy.loginfo("row_centring: reading %s, dead band %.1f px, gain %.2f 1/s, speed %.2f m/s",
                      self.labels_topic, self.config.dead_band_px, self.config.gain_per_s,
                      self.config.forward_speed_mps)

    def _counted(self, has_estimate: bool):
        with self.health.lock:
            self.health.inputs[self.labels_topic].processed(has_estimate)

    def _on_labels(self, msg: Image):
        with self.health.lock:
            self.health.inputs[self.labels_topic].received(rospy.get_time())
        try:
            labels = conv.image_to_array(msg)
            if labels.ndim != 2:
                raise ValueError(f"label image must be mono8, got '{msg.encoding}'")
        except ValueError as exc:
            self._counted(False)
            self.status_pub.publish(String(data=f"no_estimate: {exc}"))
            return
        ground, sky = labels == GROUND, labels == SKY
        result = compute_row_centring(ground, sky, self.config)
        self._counted(result.ok)
        if result.ok:
            x = int(round(result.intersection_px[0]))
            self.intersection_pub.publish(Int16(data=max(-INT16_MAX, min(INT16_MAX, x))))
            self.coords_pub.publish(Float64MultiArray(data=[result.linear_x, result.angular_z]))
            self.status_pub.publish(String(data=f"ok: {result.decision} x={result.intersection_px[0]:.1f}"))
        else:
            self.status_pub.publish(String(data=f"no_estimate: {result.reason}"))
        if self.overlay_pub.get_num_connections():
            image = colorize_labels(labels)
            overlay = draw_row_centring(image, result, ground, sky, self.config)
            self.overlay_pub.publish(conv.image_msg(np.ascontiguousarray(overlay), msg.header.stamp,
                                                    msg.header.frame_id))
