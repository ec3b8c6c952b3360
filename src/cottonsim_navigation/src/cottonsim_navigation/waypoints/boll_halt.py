"""The paper's halt at bolls, free of ROS: stop while cotton is in the arm's reach, then drive on.

Cotton-Eye's side cameras report whether a boll lies within the UR5e's reach
(``/cotton_eye/bolls_in_reach``); the robot halts there so the arm can pick,
then goes on along its route. :class:`BollHalt` decides when::

    halt = BollHalt(BollHaltConfig(dwell_s=2.0, rearm_distance_m=0.7))
    d = halt.step(now_s, x_m, y_m, bolls_in_reach)   # every control cycle
    d.started    -> cancel the goal (the robot stops)
    d.halted     -> keep waiting
    d.ended      -> send the same goal again

A halt lasts ``dwell_s`` of sim time, whatever the cameras say meanwhile, so
a boll that stays in view can never stall the route. After a halt the next
one may start only once the robot has moved ``rearm_distance_m`` away from
where it halted *and* ``min_gap_s`` has passed: a robot that is not moving
(blocked, or still accelerating out of the halt) cannot halt again at the
same boll. Without a position (``x_m``/``y_m`` None or NaN) the halt is not
re-armed; the distance then counts from the first position known after it.

:class:`BollVerdicts` merges the verdicts of several publishers (one boll
node per side camera, each publishing its own true/false per frame): bolls
are in reach while the newest verdict of any publisher, younger than
``max_age_s``, is true.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, Optional, Tuple

from cottonsim_common.validation import require_fields, require_positive


@dataclass(frozen=True)
class BollHaltConfig:
    """enabled: halt at bolls at all (false: the route never halts).

    dwell_s [s, sim time]: how long one halt lasts (the arm's picking time);
    default 2.0. Must be > 0.
    rearm_distance_m [m]: how far the robot must move from a halt's position
    before it may halt again; default 0.7 (the farm's plant spacing: about
    one halt per plant). Must be > 0, so a boll that stays in reach of a
    standing robot cannot halt it twice.
    min_gap_s [s, sim time]: least time between the end of one halt and the
    start of the next; default 1.0.
    max_age_s [s, sim time]: a verdict older than this no longer counts
    (a camera or detector that went quiet); default 1.0.
    """

    enabled: bool = True
    dwell_s: float = 2.0
    rearm_distance_m: float = 0.7
    min_gap_s: float = 1.0
    max_age_s: float = 1.0

    def __post_init__(self) -> None:
        require_fields(self, flags=("enabled",), positive=("dwell_s", "rearm_distance_m", "max_age_s"),
                       non_negative=("min_gap_s",))


@dataclass(frozen=True)
class HaltDecision:
    """What one :meth:`BollHalt.step` asks of the navigator."""

    halted: bool = False      # the robot must stand still now
    started: bool = False     # a halt began this step (cancel the goal)
    ended: bool = False       # a halt ended this step (send the goal again)


class BollHalt:
    """Halt-at-bolls state machine; see the module docstring. Times in seconds of sim time."""

    def __init__(self, config: BollHaltConfig = BollHaltConfig()):
        self.config = config
        self.halts = 0                      # halts started
        self.halt_time_s = 0.0              # total time of the ended halts [s]
        self._since: Optional[float] = None             # start of the current halt
        self._halt_xy: Optional[Tuple[float, float]] = None   # where the last halt happened
        self._last_end_s: Optional[float] = None
        self._armed = True

    @property
    def halted(self) -> bool:
        return self._since is not None

    def step(self, now_s: float, x_m: Optional[float], y_m: Optional[float], bolls_in_reach: bool) -> HaltDecision:
        """Advance to ``now_s`` with the robot at (x_m, y_m) (None: unknown) and the cameras' verdict."""
        if not math.isfinite(now_s):
            raise ValueError(f"now_s must be finite, got {now_s!r}")
        xy = None
        if x_m is not None and y_m is not None and math.isfinite(x_m) and math.isfinite(y_m):
            xy = (float(x_m), float(y_m))
        if self._since is not None:
            if now_s < self._since:          # sim time went back (a reset): the dwell starts again
                self._since = now_s
            if now_s - self._since < self.config.dwell_s:
                return HaltDecision(halted=True)
            self.halt_time_s += max(0.0, now_s - self._since)
            self._since = None
            self._last_end_s = now_s
            return HaltDecision(ended=True)
        if not self._armed and self._may_rearm(now_s, xy):
            self._armed = True
        if self.config.enabled and self._armed and bolls_in_reach:
            self._since = now_s
            self._halt_xy = xy
            self._armed = False
            self.halts += 1
            return HaltDecision(halted=True, started=True)
        return HaltDecision()

    def cancel(self, now_s: float) -> bool:
        """End a halt early (the route ended, or the navigator goes Home); True when one was on."""
        if self._since is None:
            return False
        self.halt_time_s += max(0.0, now_s - self._since)
        self._since = None
        self._last_end_s = now_s
        return True

    def _may_rearm(self, now_s: float, xy: Optional[Tuple[float, float]]) -> bool:
        if self._last_end_s is not None and now_s - self._last_end_s < self.config.min_gap_s:
            return False
        if xy is None:
            return False
        if self._halt_xy is None:            # halted without a position: measure from the first one known
            self._halt_xy = xy
            return False
        return math.hypot(xy[0] - self._halt_xy[0], xy[1] - self._halt_xy[1]) >= self.config.rearm_distance_m


class BollVerdicts:
    """The newest in-reach verdict of each publisher; see the module docstring."""

    def __init__(self, max_age_s: float = 1.0):
        require_positive("max_age_s", max_age_s, allow_zero=True)
        self.max_age_s = float(max_age_s)
        self._latest: Dict[str, Tuple[bool, float]] = {}

    def report(self, source: str, in_reach: bool, stamp_s: float) -> None:
        """One verdict of publisher ``source`` received at ``stamp_s`` (sim time)."""
        if not math.isfinite(stamp_s):
            raise ValueError(f"stamp_s must be finite, got {stamp_s!r}")
        self._latest[str(source)] = (bool(in_reach), float(stamp_s))

    def in_reach(self, now_s: float) -> bool:
        """True while some publisher's newest verdict is true and at most max_age_s old."""
        return any(v and 0.0 <= now_s - t <= self.max_age_s for v, t in self._latest.values())
