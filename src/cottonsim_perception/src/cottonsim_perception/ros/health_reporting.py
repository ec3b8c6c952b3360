"""Publishing a Cotton-Eye node's health on /cotton_eye/health and logging its changes.

Shared by the segmentation, row-centring and boll-detection nodes. Parameters read (private;
config/*.yaml documents each): ~stale_after_s (float, 1.0), ~black_max_mean (float, 2.0),
~black_warn_frames (int, 10), ~no_estimate_warn_frames (int, 25), ~health_period_s (float, 1.0).
"""
import dataclasses
import math
import threading
from typing import Dict, List, Optional

import rospy
from cottonsim_msgs.msg import CottonEyeCamera, CottonEyeHealth

from cottonsim_perception.monitoring.input_health import HealthConfig, InputHealth

HEALTH_TOPIC = "/cotton_eye/health"


def health_config_from_params() -> HealthConfig:
    """HealthConfig from the node's private parameters (ValueError names a bad one)."""
    values = {f.name: rospy.get_param(f"~{f.name}") for f in dataclasses.fields(HealthConfig)
              if rospy.has_param(f"~{f.name}")}
    try:
        return HealthConfig(**values)
    except ValueError as exc:
        raise ValueError(f"~{exc}") from None


class HealthReporter:
    """The InputHealth of each input of one node, ticked at the node's slots, published every ~health_period_s.

    node: the node's name; inputs: names of its inputs (camera namespaces or topics); backend, error:
    what runs the node's network (see CottonEyeHealth.msg). Use ``lock`` around calls on ``inputs[...]``
    from callbacks; ``tick`` takes it itself.
    """

    def __init__(self, node: str, inputs: List[str], backend: str = "", error: str = ""):
        self.node = node
        self.backend = backend
        self.error = error
        self.config = health_config_from_params()
        self.period_s = float(rospy.get_param("~health_period_s", 1.0))
        if not (math.isfinite(self.period_s) and self.period_s > 0.0):
            raise ValueError(f"~health_period_s must be > 0 [s], got {self.period_s}")
        self.inputs: Dict[str, InputHealth] = {name: InputHealth(name, self.config) for name in inputs}
        self.lock = threading.Lock()
        self._last_published_s: Optional[float] = None
        self.publisher = rospy.Publisher(HEALTH_TOPIC, CottonEyeHealth, queue_size=5)

    def start_timer(self, slot_hz: float) -> rospy.Timer:
        """Tick at slot_hz (sim time) from a timer thread (for nodes without a loop of their own)."""
        return rospy.Timer(rospy.Duration(1.0 / slot_hz), lambda _event: self.tick(rospy.get_time()))

    def tick(self, now_s: float) -> None:
        """A processing slot at sim time now_s: stale checks, log lines for changes, a health message when due."""
        with self.lock:
            events = [e for h in self.inputs.values() for e in h.tick(now_s)]
            due = self._last_published_s is None or not (0.0 <= now_s - self._last_published_s < self.period_s)
            msg = self.message(now_s) if due else None
        for event in events:
            if event.kind == "back":
                rospy.loginfo("%s: %s", self.node, event.message)
            else:
                rospy.logwarn("%s: %s", self.node, event.message)
        if msg is not None:
            self._last_published_s = now_s
            self.publisher.publish(msg)

    def message(self, now_s: float) -> CottonEyeHealth:
        """The health message now (call with ``lock`` held)."""
        msg = CottonEyeHealth(node=self.node, backend=self.backend, error=self.error)
        msg.header.stamp = rospy.Time.from_sec(max(0.0, now_s))
        for h in self.inputs.values():
            msg.cameras.append(CottonEyeCamera(
                camera=h.name, frames_received=h.frames_received, frames_processed=h.frames_processed,
                frames_black=h.frames_black, frames_no_estimate=h.frames_no_estimate,
                frames_stale=h.frames_stale, stale=h.stale, last_frame_age_s=h.age_s(now_s)))
        return msg
