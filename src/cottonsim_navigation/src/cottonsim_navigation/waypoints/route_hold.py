"""The route hold, free of ROS: another node (the harvest) asks the navigator to stand still.

A node that needs the robot to stand (the harvest while the arm picks)
publishes "hold" (true) repeatedly, at least every ``max_age_s``, and "release"
(false) when it is done. :class:`RouteHold` decides::

    hold = RouteHold(RouteHoldConfig(max_age_s=1.0))
    hold.report(True, stamp_s)        # every request received
    d = hold.step(now_s)              # every control cycle
    d.started    -> cancel the goal (the robot stops)
    d.halted     -> keep standing
    d.ended      -> send the same goal again

The route is held while the newest request is "hold" and at most
``max_age_s`` old (sim time): a holder that dies, or whose messages stop,
releases the route by itself after ``max_age_s``, so it can never stall the
route forever. A request stamped in the future (sim time went back, a reset)
counts as fresh.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

from cottonsim_navigation.waypoints.boll_halt import HaltDecision


@dataclass(frozen=True)
class RouteHoldConfig:
    """max_age_s [s, sim time]: a hold request older than this no longer holds the route; default 1.0, > 0."""

    max_age_s: float = 1.0

    def __post_init__(self) -> None:
        v = self.max_age_s
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ValueError(f"max_age_s must be a finite number > 0 [s], got {v!r}")


class RouteHold:
    """Hold-the-route state machine; see the module docstring. Times in seconds of sim time."""

    def __init__(self, config: RouteHoldConfig = RouteHoldConfig()):
        self.config = config
        self.holds = 0                       # holds started
        self.hold_time_s = 0.0               # total time of the ended holds [s]
        self._request: Optional[bool] = None
        self._stamp_s = -math.inf
        self._since: Optional[float] = None

    @property
    def held(self) -> bool:
        return self._since is not None

    def report(self, hold: bool, stamp_s: float) -> None:
        """A request received at stamp_s: hold (True) or release (False)."""
        if not math.isfinite(stamp_s):
            raise ValueError(f"stamp_s must be finite, got {stamp_s!r}")
        self._request, self._stamp_s = bool(hold), float(stamp_s)

    def requested(self, now_s: float) -> bool:
        """True while the newest request is a hold at most max_age_s old."""
        return bool(self._request) and now_s - self._stamp_s <= self.config.max_age_s

    def step(self, now_s: float) -> HaltDecision:
        """Advance to now_s (the decision is the halt at bolls': halted = held)."""
        if not math.isfinite(now_s):
            raise ValueError(f"now_s must be finite, got {now_s!r}")
        wanted = self.requested(now_s)
        if self._since is None:
            if not wanted:
                return HaltDecision()
            self._since = now_s
            self.holds += 1
            return HaltDecision(halted=True, started=True)
        if wanted:
            return HaltDecision(halted=True)
        self.hold_time_s += max(0.0, now_s - self._since)
        self._since = None
        return HaltDecision(ended=True)
