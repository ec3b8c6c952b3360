"""The bridge's wait for cameras' consumers: no step past a frame's slot before its consumer is done with it.

ROS side of :mod:`cottonsim_world.consumer_wait`: listens to /sim/frames_done
(std_msgs/Header: the frame's stamp, frame_id the camera) and holds the
stepping loop, at most ``consumer_wait_s`` of wall time per camera, with one
warning when a consumer does not answer in time.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Callable, Dict, Optional, Sequence, Tuple

import rospy
from std_msgs.msg import Header

from cottonsim_common.ros.frames_done import FRAMES_DONE_TOPIC
from cottonsim_world.consumer_wait import ConsumerWait
from cottonsim_world.sensors.camera import CameraConfig


class ConsumerPacing:
    """Feeds a ConsumerWait from the bridge (frames sent) and /sim/frames_done, and waits before a step."""

    def __init__(self, waited: Dict[str, CameraConfig]):
        self.wait = ConsumerWait({name: 1.0 / c.render_rate_hz for name, c in waited.items()})
        self.limit_s = {name: float(c.consumer_wait_s) for name, c in waited.items()}
        self._cond = threading.Condition()
        self._next_end_s = math.inf          # no step before this sim time needs a look under the lock
        rospy.Subscriber(FRAMES_DONE_TOPIC, Header, self._on_done, queue_size=50)
        rospy.loginfo("sim_bridge: stepping waits for the consumers of %s (at most %s s each, wall time)",
                      ", ".join(waited), ", ".join(f"{v:g}" for v in self.limit_s.values()))

    @classmethod
    def for_cameras(cls, cameras: Sequence[Tuple[str, CameraConfig]]) -> Optional["ConsumerPacing"]:
        """The pacing of the cameras with consumer_wait_s > 0, or None if there are none."""
        waited = {name: c for name, c in cameras if c.consumer_wait_s > 0.0}
        return cls(waited) if waited else None

    def _on_done(self, msg: Header):
        with self._cond:
            self.wait.done(msg.frame_id, msg.stamp.to_sec())
            self._next_end_s = self.wait.next_slot_end_s()
            self._cond.notify_all()

    def sent(self, camera: str, stamp_s: float) -> None:
        with self._cond:
            self.wait.sent(camera, stamp_s)
            self._next_end_s = self.wait.next_slot_end_s()

    def hold(self, now_s: float, publish_clock: Callable[[], None]) -> None:
        """Before stepping past sim time ``now_s``: wait until no frame's slot has ended unanswered."""
        if now_s + 1e-6 < self._next_end_s:
            return
        publish_clock()                      # the consumers must see the end of the slot (a node waits for it)
        deadlines: Dict[str, float] = {}
        with self._cond:
            while not rospy.is_shutdown():
                blocking = self.wait.blocking(now_s)
                if blocking is None:
                    break
                camera = blocking[0]
                left = deadlines.setdefault(camera, time.monotonic() + self.limit_s[camera]) - time.monotonic()
                if left <= 0.0:
                    self.wait.timed_out(camera)
                    rospy.logwarn("sim_bridge: the consumer of %s was not done with its frame of %.3f s within "
                                  "%g s (wall); not waiting for it until it answers on %s", camera, blocking[1],
                                  self.limit_s[camera], FRAMES_DONE_TOPIC)
                    continue
                self._cond.wait(min(left, 0.5))
            self._next_end_s = self.wait.next_slot_end_s()
