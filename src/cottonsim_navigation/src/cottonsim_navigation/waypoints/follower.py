"""A waypoint-following state machine, free of ROS.

The ROS navigator node owns the move_base action client; this class decides
what to send next. Usage::

    f = WaypointFollower(goals, FollowerConfig(on_failure="skip"), home=home_pose)
    goal = f.next_goal(localization_ready=True)   # a goal to send, or None (wait / finished)
    ...                                           # when move_base ends:
    f.report_result(GoalResult.SUCCEEDED)
    f.battery_low()                               # paper: at 40 % go Home and stop
    f.passed(distance_m)                          # pass-through waypoints: True = counted, send the next
    f.hold()                                      # localisation lost: the active goal is withdrawn, not
                                                  # counted; next_goal(True) gives the same goal again

Pass-through (``FollowerConfig.pass_through_radius_m`` > 0 and the goal
flagged in ``pass_through``): a waypoint where the route goes on straight
counts as reached once the robot is within the radius, and the next goal is
sent at once, so the robot drives through it instead of braking to a stop
(move_base only knows one goal at a time). The paper's error of a waypoint
is the trajectory's closest approach, which the robot still makes a moment
later on its way to the next goal.

Holding (``hold``): when localisation is lost mid-route (a kidnap) the ROS
layer cancels the active goal so the robot stops; the goal is neither
succeeded nor aborted, and the next ``next_goal(localization_ready=True)``
returns the same goal again (the route is resumed, never cut short).

States: WAITING (localisation not ready, or a held goal), READY (a goal may be sent),
ACTIVE (a goal is out), FINISHED. Goals are any objects (map poses or GPS
waypoints); Home must be of the same kind.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any, List, Optional, Sequence


class GoalResult(enum.Enum):
    SUCCEEDED = "succeeded"
    ABORTED = "aborted"         # move_base gave up (or goal rejected / timed out)


class FollowerState(enum.Enum):
    WAITING = "waiting"
    READY = "ready"
    ACTIVE = "active"
    FINISHED = "finished"


@dataclass(frozen=True)
class FollowerConfig:
    """on_failure: 'skip' (go on with the next waypoint) or 'stop' (end the route).

    pass_through_radius_m [m]: a pass-through waypoint counts as reached within
    this distance of the robot; 0 (default) = every waypoint is a full stop.
    """

    on_failure: str = "skip"
    pass_through_radius_m: float = 0.0

    def __post_init__(self) -> None:
        if self.on_failure not in ("skip", "stop"):
            raise ValueError(f"on_failure must be 'skip' or 'stop', got {self.on_failure!r}")
        r = self.pass_through_radius_m
        if isinstance(r, bool) or not isinstance(r, (int, float)) or not math.isfinite(r) or r < 0:
            raise ValueError(f"pass_through_radius_m must be a finite number >= 0, got {r!r}")


@dataclass
class FollowerSummary:
    total: int = 0                 # route waypoints (Home excluded)
    succeeded: int = 0             # includes the passed ones
    passed: int = 0                # pass-through waypoints driven through
    aborted: int = 0
    skipped: int = 0               # never attempted (stop on failure / battery)
    returned_home: bool = False
    home_reached: Optional[bool] = None
    stopped_reason: str = ""
    holds: int = 0                 # goals withdrawn while localisation was lost (then sent again)
    results: List[str] = field(default_factory=list)    # per attempted goal, in order
    # per aborted route waypoint, in order: {"index": 1-based waypoint number, "reason": why}
    aborted_waypoints: List[dict] = field(default_factory=list)


class WaypointFollower:
    """Holds the route and the current index; see the module docstring."""

    def __init__(self, goals: Sequence[Any], config: FollowerConfig = FollowerConfig(), home: Any = None,
                 pass_through: Optional[Sequence[bool]] = None):
        if len(goals) == 0:
            raise ValueError("goals must contain at least one waypoint")
        self.config = config
        self.goals: List[Any] = list(goals)
        flags = [False] * len(self.goals) if pass_through is None else [bool(f) for f in pass_through]
        if len(flags) != len(self.goals):
            raise ValueError(f"pass_through has {len(flags)} flags for {len(self.goals)} goals")
        self.pass_through: List[bool] = flags
        self.home = home
        self.index = 0
        self.state = FollowerState.WAITING
        self._going_home = False
        self.summary = FollowerSummary(total=len(self.goals))

    @property
    def finished(self) -> bool:
        return self.state is FollowerState.FINISHED

    @property
    def current_goal(self) -> Optional[Any]:
        if self.finished or self.index >= len(self.goals):
            return None
        return self.goals[self.index]

    @property
    def going_home(self) -> bool:
        return self._going_home

    def next_goal(self, localization_ready: bool = True) -> Optional[Any]:
        """The goal to send now, or None (still waiting for localisation, a goal is active, or done)."""
        if self.finished or self.state is FollowerState.ACTIVE:
            return None
        if not localization_ready:
            self.state = FollowerState.WAITING
            return None
        if self.index >= len(self.goals):
            self._finish("route complete")
            return None
        self.state = FollowerState.ACTIVE
        return self.goals[self.index]

    def report_result(self, result: GoalResult, reason: str = "") -> None:
        """move_base finished the active goal; ``reason`` says why when it did not succeed."""
        if self.state is not FollowerState.ACTIVE:
            raise ValueError(f"report_result called with no active goal (state {self.state.value})")
        result = GoalResult(result)
        self.summary.results.append(result.value)
        if self._going_home:
            self.summary.home_reached = result is GoalResult.SUCCEEDED
            self._finish("returned home on low battery")
            return
        if result is GoalResult.SUCCEEDED:
            self.summary.succeeded += 1
        else:
            self.summary.aborted += 1
            self.summary.aborted_waypoints.append({"index": self.index + 1, "reason": str(reason)})
            if self.config.on_failure == "stop":
                self.summary.skipped = len(self.goals) - self.index - 1
                self.index = len(self.goals)
                self._finish(f"waypoint {self.index} aborted (on_failure=stop)")
                return
        self.index += 1
        self.state = FollowerState.READY
        if self.index >= len(self.goals):
            self._finish("route complete")

    @property
    def current_is_pass_through(self) -> bool:
        """The active goal may be driven through (flagged, radius > 0, not the way Home)."""
        return (self.state is FollowerState.ACTIVE and not self._going_home and self.config.pass_through_radius_m > 0
                and self.index < len(self.pass_through) and self.pass_through[self.index])

    def passed(self, distance_m: float) -> bool:
        """The robot is ``distance_m`` [m] from the active goal: True when that passes it.

        Only for a pass-through goal within ``pass_through_radius_m``; it then
        counts as succeeded (and passed) and the next goal may be sent. A
        non-finite distance never passes.
        """
        if not self.current_is_pass_through or not math.isfinite(distance_m):
            return False
        if distance_m > self.config.pass_through_radius_m:
            return False
        self.summary.passed += 1
        self.report_result(GoalResult.SUCCEEDED)
        return True

    def hold(self, count: bool = True) -> bool:
        """Withdraw the active goal without a result (localisation lost); True when one was active.

        The index stays, so ``next_goal(localization_ready=True)`` returns the
        same goal (or Home) once the caller is ready again. Nothing happens
        when no goal is active (READY / WAITING / FINISHED). count=False: not
        counted in ``summary.holds`` (a halt at bolls, which is counted apart).
        """
        if self.state is not FollowerState.ACTIVE:
            return False
        self.state = FollowerState.WAITING
        if count:
            self.summary.holds += 1
        return True

    def battery_low(self) -> None:
        """Replace the remaining goals by Home; the follower stops once Home is reached.

        The active goal (if any) is abandoned: the ROS layer should cancel it
        and then call ``next_goal`` to get Home.
        """
        if self.finished or self._going_home:
            return
        if self.home is None:
            raise ValueError("battery_low needs a home goal (pass home= to the follower)")
        remaining = len(self.goals) - self.index
        self.summary.skipped += remaining
        self.summary.returned_home = True
        self.goals = self.goals[:self.index] + [self.home]
        self._going_home = True
        self.state = FollowerState.READY

    def _finish(self, reason: str) -> None:
        self.state = FollowerState.FINISHED
        if not self.summary.stopped_reason:
            self.summary.stopped_reason = reason


class LocalisationGate:
    """Is the localiser lost? True once it has reported "localised" and then reports "not localised".

    The first "localised" is not waited for: AMCL reports it only after the robot has moved, so a
    navigator starts on the initial pose and pauses only when a localised filter loses its pose (a
    kidnap, a re-initialisation). Feed every verdict to :meth:`report`.
    """

    def __init__(self) -> None:
        self.last: Optional[bool] = None
        self.ever_localized = False

    def report(self, localized: bool) -> None:
        if not isinstance(localized, (bool, int)):
            raise ValueError(f"localized must be a bool, got {localized!r}")
        self.last = bool(localized)
        self.ever_localized = self.ever_localized or self.last

    @property
    def lost(self) -> bool:
        return self.ever_localized and self.last is False
