"""move_base's configuration: :class:`MoveBaseConfig` and :class:`VisionBiasConfig` (ROS names, units in the docstrings)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from cottonsim_common.validation import require_bool, require_fields

from cottonsim_navigation.move_base.recovery import RECOVERY_NAMES

DEFAULT_RECOVERIES = ("conservative_reset", "rotate_recovery", "aggressive_reset", "rotate_recovery")


def _check_number(name: str, value, minimum: float = 0.0, strict: bool = False) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    if value < minimum or (strict and value == minimum):
        raise ValueError(f"{name} must be {'>' if strict else '>='} {minimum}, got {value!r}")


@dataclass(frozen=True)
class MoveBaseConfig:
    """move_base parameters (ROS names; times in s, frequencies in Hz, distances in m).

    base_global_planner / base_local_planner: plugin names (the original's
    'navfn/NavfnROS' and 'dwa_local_planner/DWAPlannerROS').
    controller_frequency [Hz]: control loop rate (original 5.0).
    planner_frequency [Hz]: re-plan rate while controlling; 0 = plan only on
    a new goal or when the controller fails (move_base default 0.0).
    planner_patience [s]: how long planning may fail before recoveries
    (move_base default 5.0). controller_patience [s]: how long the local
    planner may fail before recoveries (move_base default 15.0).
    max_planning_retries: failed plans allowed before recoveries; -1 =
    unlimited (only planner_patience counts; move_base default -1).
    oscillation_timeout [s]: the robot must move oscillation_distance [m]
    within this time, else recoveries (then an abort); 0 disables. Default
    20.0 (move_base's 0.0 lets a pinned robot wait forever);
    oscillation_distance default 0.5 (move_base's).
    recovery_behavior_enabled: run recoveries at all (default true);
    clearing_rotation_allowed: include 'rotate_recovery' entries (default true).
    recovery_behaviours: names in order (move_base's default list:
    conservative_reset, rotate_recovery, aggressive_reset, rotate_recovery).
    conservative_reset_dist [m]: square side kept by conservative_reset (3.0).
    abort_on_blocked_goal: abort a goal the robot cannot stand at (in or
    next to an obstacle): at once on a global costmap recoveries cannot
    clear, else after planner_patience (port's addition, true).
    """

    base_global_planner: str = "navfn/NavfnROS"
    base_local_planner: str = "dwa_local_planner/DWAPlannerROS"
    controller_frequency: float = 5.0
    planner_frequency: float = 0.0
    planner_patience: float = 5.0
    controller_patience: float = 15.0
    max_planning_retries: int = -1
    oscillation_timeout: float = 20.0
    oscillation_distance: float = 0.5
    recovery_behavior_enabled: bool = True
    clearing_rotation_allowed: bool = True
    recovery_behaviours: Tuple[str, ...] = DEFAULT_RECOVERIES
    conservative_reset_dist: float = 3.0
    abort_on_blocked_goal: bool = True

    def __post_init__(self) -> None:
        for name in ("base_global_planner", "base_local_planner"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise ValueError(f"{name} must be a non-empty plugin name, got {getattr(self, name)!r}")
        _check_number("controller_frequency", self.controller_frequency, strict=True)
        for name in ("planner_frequency", "planner_patience", "controller_patience", "oscillation_timeout",
                     "oscillation_distance", "conservative_reset_dist"):
            _check_number(name, getattr(self, name))
        r = self.max_planning_retries
        if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < -1:
            raise ValueError(f"max_planning_retries must be an integer >= -1, got {r!r}")
        require_fields(self, flags=("recovery_behavior_enabled", "clearing_rotation_allowed", "abort_on_blocked_goal"))
        names = self.recovery_behaviours
        if isinstance(names, str) or not all(isinstance(n, str) for n in names):
            raise ValueError(f"recovery_behaviours must be a list of names, got {names!r}")
        for n in names:
            if n not in RECOVERY_NAMES:
                raise ValueError(f"recovery_behaviours: unknown behaviour {n!r}; known: {', '.join(RECOVERY_NAMES)}")
        object.__setattr__(self, "recovery_behaviours", tuple(names))


@dataclass(frozen=True)
class VisionBiasConfig:
    """Row-centring correction blended into move_base's angular velocity.

    enabled: use the correction (default false until perception lands).
    max_age_s [s]: an estimate older than this is ignored (0.5).
    max_vision_rate [rad/s]: bound on the added angular rate. Default
    radians(5) = 0.0873 rad/s: the paper caps a correction at 5 deg, here
    at most 5 deg of heading change per second of correction.
    row_reach_m [m]: the robot counts as inside a crop row when the global
    costmap has a LETHAL cell within this lateral distance on both sides (1.0).
    """

    enabled: bool = False
    max_age_s: float = 0.5
    max_vision_rate: float = math.radians(5.0)
    row_reach_m: float = 1.0

    def __post_init__(self) -> None:
        require_bool("enabled", self.enabled)
        _check_number("max_age_s", self.max_age_s)
        _check_number("max_vision_rate", self.max_vision_rate)
        _check_number("row_reach_m", self.row_reach_m, strict=True)


