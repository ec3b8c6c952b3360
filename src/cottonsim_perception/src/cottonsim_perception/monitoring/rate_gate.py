"""Which frames a node processes at a given rate: the first frame at or after each slot, the rest dropped.

A camera sends 24 frames per second; the nodes need fewer (``rate_hz``: the
segmentation ~5 Hz, boll detection ~2 Hz). :class:`RateGate` decides per frame
stamp, with no queue: a frame is taken when its stamp reaches the next slot,
slots are 1 / rate_hz apart, so a 24 fps camera through a 5 Hz gate gives
5 frames per second on average (never more than one per slot). A node that
falls behind skips the slots it missed instead of catching up in a burst; a
stamp that goes back (the simulator restarted) starts the schedule again.
"""
from __future__ import annotations

import math
from typing import Optional


def check_rate_hz(rate_hz: float, key: str = "rate_hz") -> float:
    """``rate_hz`` as a float if it is finite and > 0, else ValueError naming ``key``."""
    try:
        value = float(rate_hz)
    except (TypeError, ValueError):
        raise ValueError(f"{key} must be a number [Hz], got {rate_hz!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{key} must be > 0 [Hz], got {rate_hz!r}")
    return value


class RateGate:
    """Takes at most one frame per slot of 1 / rate_hz seconds (stamps in seconds, sim time)."""

    def __init__(self, rate_hz: float):
        self.period_s = 1.0 / check_rate_hz(rate_hz)
        self._next_s: Optional[float] = None
        self._last_s: Optional[float] = None

    def take(self, stamp_s: float) -> bool:
        """True if the frame stamped ``stamp_s`` is to be processed (and the slot is used up)."""
        stamp_s = float(stamp_s)
        if self._last_s is not None and stamp_s < self._last_s:      # time went back: start again
            self._next_s = None
        self._last_s = stamp_s
        if self._next_s is not None and stamp_s < self._next_s - 1e-9:
            return False
        if self._next_s is None or stamp_s - self._next_s >= self.period_s:
            self._next_s = stamp_s + self.period_s        # first frame, or slots missed: no catching up
        else:
            self._next_s += self.period_s
        return True
