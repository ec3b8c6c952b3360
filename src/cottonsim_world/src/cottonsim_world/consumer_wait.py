"""Which camera frame the simulation waits for: a frame's consumer has until the end of its slot.

A camera rendered at its consumer's rate (``CameraConfig.render_rate_hz``) with
``consumer_wait_s`` > 0 sends each frame to a node that runs once per slot of
1 / render_rate_hz seconds of sim time. Run as fast as the CPUs allow, the
simulation would outrun a node that gets too little CPU, and the node would skip
frames: the robot would decide on fewer frames than at real time. So the
simulation does not step past the end of a frame's slot before the consumer has
said it is done with that frame (or a later one): as at real time, where a node
that keeps up is done within its slot. A camera whose consumer does not answer
within ``consumer_wait_s`` of wall time (not started yet, crashed) is no longer
waited for until it answers again, so a missing node costs one wait, not one
per frame.

:class:`ConsumerWait` keeps the frames sent and not answered yet, per camera;
the ROS bridge (``ros/consumer_pacing.py``) feeds it and does the waiting.
"""
from __future__ import annotations

import collections
from typing import Deque, Dict, Optional, Tuple

STAMP_TOLERANCE_S = 1e-6       # a 'done' stamp this close to a frame's answers it (ROS nanoseconds vs floats)


class ConsumerWait:
    """Frames sent and not answered yet; ``slot_s``: camera -> length of its consumer's slot [s, sim time]."""

    def __init__(self, slot_s: Dict[str, float]):
        for camera, slot in slot_s.items():
            if not slot > 0.0:
                raise ValueError(f"slot of camera '{camera}' must be > 0 [s], got {slot!r}")
        self.slot_s = dict(slot_s)
        self._pending: Dict[str, Deque[float]] = {c: collections.deque() for c in slot_s}
        self._answering = {c: True for c in slot_s}
        self.timeouts = {c: 0 for c in slot_s}

    def sent(self, camera: str, stamp_s: float) -> None:
        """A frame of ``camera`` stamped ``stamp_s`` went out (ignored for cameras not waited for)."""
        if camera in self._pending and self._answering[camera]:
            self._pending[camera].append(float(stamp_s))

    def done(self, camera: str, stamp_s: float) -> None:
        """The consumer of ``camera`` is done with the frame stamped ``stamp_s`` and every one before it."""
        pending = self._pending.get(camera)
        if pending is None:
            return
        self._answering[camera] = True
        while pending and pending[0] <= stamp_s + STAMP_TOLERANCE_S:
            pending.popleft()

    def blocking(self, now_s: float) -> Optional[Tuple[str, float]]:
        """(camera, stamp) of the oldest frame whose slot has ended at sim time ``now_s`` without an answer."""
        worst = None
        for camera, pending in self._pending.items():
            if pending and pending[0] + self.slot_s[camera] <= now_s + STAMP_TOLERANCE_S:
                if worst is None or pending[0] < worst[1]:
                    worst = (camera, pending[0])
        return worst

    def next_slot_end_s(self) -> float:
        """Sim time [s] at which the oldest frame not answered yet starts to block (inf: none)."""
        return min((pending[0] + self.slot_s[c] for c, pending in self._pending.items() if pending),
                   default=float("inf"))

    def timed_out(self, camera: str) -> None:
        """Its consumer did not answer in time: drop its frames and stop waiting for it until it answers."""
        self._pending[camera].clear()
        self._answering[camera] = False
        self.timeouts[camera] += 1

    def answering(self, camera: str) -> bool:
        return self._answering[camera]
