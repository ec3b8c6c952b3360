"""Which frames a node processes at a given rate: the first frame of each slot of sim time, the rest dropped.

A camera sends 24 frames per second; the nodes need fewer (``rate_hz``: the
segmentation ~5 Hz, boll detection ~2 Hz). :class:`RateGate` decides per frame
stamp, with no queue: slot k holds the stamps in [k / rate_hz, (k + 1) / rate_hz)
of sim time and the first frame of each is taken, so a 24 fps camera through a
5 Hz gate gives 5 frames per second (never more than one per slot). A node that
falls behind skips the slots it missed instead of catching up in a burst; a
stamp that goes back (the simulator restarted) starts the schedule again. The
slots are those of ``cottonsim_common.rate_slots``, which the simulator uses to
render a camera at its consumer's rate only (``render_rate_hz``): the gate then
takes the same frames from the rendered ones as from every frame.
"""
from __future__ import annotations

import math

from cottonsim_common.rate_slots import FirstOfSlotGate


def check_rate_hz(rate_hz: float, key: str = "rate_hz") -> float:
    """``rate_hz`` as a float if it is finite and > 0, else ValueError naming ``key``."""
    try:
        value = float(rate_hz)
    except (TypeError, ValueError):
        raise ValueError(f"{key} must be a number [Hz], got {rate_hz!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{key} must be > 0 [Hz], got {rate_hz!r}")
    return value


class RateGate(FirstOfSlotGate):
    """Takes the first frame of each slot of 1 / rate_hz seconds (stamps in seconds, sim time)."""

    def __init__(self, rate_hz: float):
        super().__init__(check_rate_hz(rate_hz))
