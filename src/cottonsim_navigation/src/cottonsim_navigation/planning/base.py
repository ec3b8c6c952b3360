"""Planner seams: abstract global / local planners and a name registry.

move_base picks its planners by plugin name ('navfn/NavfnROS',
'dwa_local_planner/DWAPlannerROS'); :func:`make_global_planner` and
:func:`make_local_planner` do the same with the same names (and short ones
like 'navfn', 'dwa'), so the ROS layer can pass its base_global_planner /
base_local_planner parameters straight through.
"""
from __future__ import annotations

import abc
import enum
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from cottonsim_common.pose import Pose2D


@dataclass
class Plan:
    """A global plan: poses (K, 3) [x m, y m, yaw rad] from start to goal.

    Empty (shape (0, 3)) when no plan exists; ``reason`` then says why.
    cost: the planner's path cost (navfn potential at the start), or inf.
    """

    poses: np.ndarray
    reason: str = ""
    cost: float = float("inf")

    @property
    def ok(self) -> bool:
        return len(self.poses) > 0

    def __len__(self) -> int:
        return len(self.poses)

    def as_pose_list(self) -> List[Pose2D]:
        return [Pose2D(float(x), float(y), float(t)) for x, y, t in self.poses]

    def length_m(self) -> float:
        if len(self.poses) < 2:
            return 0.0
        return float(np.sum(np.hypot(np.diff(self.poses[:, 0]), np.diff(self.poses[:, 1]))))

    @staticmethod
    def empty(reason: str) -> "Plan":
        return Plan(np.zeros((0, 3)), reason)


class GlobalPlanner(abc.ABC):
    """Finds a path through a costmap (nav_core::BaseGlobalPlanner)."""

    @abc.abstractmethod
    def make_plan(self, costmap, start: Pose2D, goal: Pose2D, tolerance_m: Optional[float] = None) -> Plan:
        """Plan from start to goal (costmap frame). ``tolerance_m`` None -> the planner's default."""


class LocalPlannerStatus(enum.Enum):
    """Outcome of one local planner cycle."""

    OK = "ok"                          # a velocity command was found
    ROTATING_TO_GOAL = "rotating"      # at the goal position, turning to the goal yaw
    GOAL_REACHED = "goal_reached"      # within both tolerances: command (0, 0)
    NO_VALID_TRAJECTORY = "no_valid_trajectory"   # every sample collides: command (0, 0)
    NO_PLAN = "no_plan"                # set_plan was never called / empty plan
    OFF_MAP = "off_map"                # robot outside the local costmap


class LocalPlanner(abc.ABC):
    """Turns a global plan into velocity commands (nav_core::BaseLocalPlanner)."""

    @abc.abstractmethod
    def set_plan(self, path) -> None:
        """New global plan: (K, 2 or 3) array or a list of poses, in the costmap's frame."""

    def update_plan_frame(self, path) -> None:
        """The SAME plan, re-expressed after the global -> local transform moved (localisation
        corrections), in the costmap's frame. Unlike set_plan this is not a new plan: a planner
        keeps its progress and goal latches. Default: set_plan."""
        self.set_plan(path)

    @abc.abstractmethod
    def compute_velocity(self, pose: Pose2D, velocity: Tuple[float, float], costmap
                         ) -> Tuple[float, float, LocalPlannerStatus]:
        """One control cycle: robot pose, current (v m/s, w rad/s) -> (v, w, status)."""

    @abc.abstractmethod
    def is_goal_reached(self, pose: Pose2D, velocity: Tuple[float, float]) -> bool:
        """True once the robot rests at the goal within the tolerances."""


_GLOBAL: Dict[str, Callable[..., GlobalPlanner]] = {}
_LOCAL: Dict[str, Callable[..., LocalPlanner]] = {}


def register_global_planner(names, factory) -> None:
    for n in names:
        _GLOBAL[n] = factory


def register_local_planner(names, factory) -> None:
    for n in names:
        _LOCAL[n] = factory


def _ensure_builtin() -> None:
    # Imported lazily so base.py has no import cycle with the planner modules.
    from cottonsim_navigation.planning.global_planners import navfn  # noqa: F401
    from cottonsim_navigation.planning.local_planners import dwa  # noqa: F401


def make_global_planner(name: str, config=None) -> GlobalPlanner:
    """Planner by move_base plugin name ('navfn/NavfnROS', 'navfn', ...)."""
    _ensure_builtin()
    if name not in _GLOBAL:
        raise ValueError(f"unknown global planner {name!r}; known: {', '.join(sorted(_GLOBAL))}")
    return _GLOBAL[name](config) if config is not None else _GLOBAL[name]()


def make_local_planner(name: str, config=None) -> LocalPlanner:
    """Planner by move_base plugin name ('dwa_local_planner/DWAPlannerROS', 'dwa', ...)."""
    _ensure_builtin()
    if name not in _LOCAL:
        raise ValueError(f"unknown local planner {name!r}; known: {', '.join(sorted(_LOCAL))}")
    return _LOCAL[name](config) if config is not None else _LOCAL[name]()
