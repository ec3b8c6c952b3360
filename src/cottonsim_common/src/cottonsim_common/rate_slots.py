"""Slots of sim time at a rate: which frames of a faster camera a slower consumer takes.

Slot k of a rate r [Hz] holds the stamps in [k / r, (k + 1) / r). A consumer at
rate r takes the first frame of each slot and drops the rest
(:class:`FirstOfSlotGate`; the perception nodes' ``RateGate``). The simulator,
asked to render a camera at r only (``CameraConfig.render_rate_hz``), renders
the same frames: both decide with :func:`slot_index` on the frame's stamp, so a
consumer at r takes exactly the frames it would have taken from every frame.
"""
from __future__ import annotations

import math
from typing import Optional

# A stamp this fraction of a slot below a boundary counts as on it: the simulator's float stamps and the
# integer nanoseconds of a ROS stamp of the same frame then fall into the same slot.
SLOT_EPSILON = 1e-6


def slot_index(stamp_s: float, rate_hz: float) -> int:
    """The slot of ``stamp_s`` [s] at ``rate_hz`` [Hz]: floor(stamp * rate), boundaries as SLOT_EPSILON says."""
    return math.floor(stamp_s * rate_hz + SLOT_EPSILON)


class FirstOfSlotGate:
    """Takes the first stamp of each slot at ``rate_hz`` (> 0, checked by the caller) and drops the others.

    No queue and no catching up: after a gap the next stamp is taken and the slots go on from it.
    A stamp in an earlier slot than the last one taken (the clock went back: the simulator
    restarted) is taken and starts the schedule again.
    """

    def __init__(self, rate_hz: float):
        self.rate_hz = float(rate_hz)
        self.period_s = 1.0 / self.rate_hz
        self._last_slot: Optional[int] = None

    def take(self, stamp_s: float) -> bool:
        """True if the frame stamped ``stamp_s`` [s] is the first of its slot (the slot is used up)."""
        slot = slot_index(float(stamp_s), self.rate_hz)
        if slot == self._last_slot:
            return False
        self._last_slot = slot
        return True
