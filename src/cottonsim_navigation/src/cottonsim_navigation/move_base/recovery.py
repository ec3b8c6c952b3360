"""Recovery behaviours of move_base: clear costmaps, rotate in place.

When move_base cannot find a plan or a valid velocity for too long (or the
robot oscillates), it runs recovery behaviours one after another before it
gives up, exactly like ROS's move_base with its default list
``conservative_reset, rotate_recovery, aggressive_reset, rotate_recovery``:

* :class:`ClearCostmapRecovery` (clear_costmap_recovery) forgets the
  obstacle-layer cells of both costmaps outside a square of side
  ``reset_distance_m`` centred on the robot, so stale obstacles (e.g. seen
  while the localisation was off) stop blocking the plan. Static map cells
  are never cleared. It finishes in one cycle.
* :class:`RotateRecovery` (rotate_recovery) turns the robot once on the spot
  (a full 2 pi) so its sensors see all around and clear the local costmap;
  it stops early if the footprint would hit an obstacle of the local
  costmap a little further along the turn.

Behaviours are stepped by the caller (``start`` once, then ``step`` every
control cycle until it reports done), so no thread or clock is needed here.
"""
from __future__ import annotations

import abc
import math
from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

from cottonsim_common.angles import shortest_angular_distance
from cottonsim_common.pose import Pose2D
from cottonsim_common.validation import require_positive
from cottonsim_navigation.core.grid import INSCRIBED_INFLATED_OBSTACLE
from cottonsim_navigation.planning.costmap import Costmap2D, ObstacleLayer


class RecoveryBehaviour(abc.ABC):
    """One recovery behaviour (nav_core::RecoveryBehavior), stepped by the caller."""

    name: str = "recovery"

    @abc.abstractmethod
    def start(self, local_pose: Pose2D, costmaps: Sequence[Tuple[Costmap2D, Pose2D]]) -> None:
        """Begin with the robot at ``local_pose`` (local costmap frame).

        costmaps: (costmap, robot pose in that costmap's frame) pairs, global and local.
        """

    @abc.abstractmethod
    def step(self, local_pose: Pose2D, velocity: Tuple[float, float], local_costmap: Costmap2D,
             dt_s: float) -> Tuple[float, float, bool]:
        """One cycle: -> (v m/s, w rad/s, done)."""


def clear_obstacles_outside(costmap: Costmap2D, centre_x_m: float, centre_y_m: float, reset_distance_m: float
                            ) -> int:
    """Reset obstacle-layer cells outside a square of side ``reset_distance_m`` around a point.

    The centre is given in the costmap's frame. Cells revert to the layer's
    "nothing known" value (NO_INFORMATION if the costmap tracks unknown
    space, else FREE_SPACE). Returns the number of cells that changed; the
    master grid is refreshed by the costmap's next ``update_map``.
    """
    changed = 0
    spec = costmap.spec
    half = 0.5 * reset_distance_m
    xs = spec.origin_x_m + (np.arange(spec.width) + 0.5) * spec.resolution_m
    ys = spec.origin_y_m + (np.arange(spec.height) + 0.5) * spec.resolution_m
    keep_x = np.abs(xs - centre_x_m) <= half
    keep_y = np.abs(ys - centre_y_m) <= half
    outside = ~(keep_y[:, None] & keep_x[None, :])
    for layer in costmap.layers:
        if isinstance(layer, ObstacleLayer) and layer.grid is not None:
            changed += layer.forget(outside)
    costmap.request_full_update()
    return changed


@dataclass(frozen=True)
class ClearCostmapConfig:
    """clear_costmap_recovery parameters.

    reset_distance_m: side of the square around the robot whose obstacles are
    kept [m]; everything outside is forgotten. ROS's conservative_reset uses
    3.0; its aggressive_reset uses 4 x the circumscribed radius (which the
    move_base core computes from the footprint).
    """

    reset_distance_m: float = 3.0

    def __post_init__(self) -> None:
        if not (isinstance(self.reset_distance_m, (int, float)) and math.isfinite(self.reset_distance_m)
                and self.reset_distance_m >= 0):
            raise ValueError(f"reset_distance_m must be a finite number >= 0, got {self.reset_distance_m!r}")


class ClearCostmapRecovery(RecoveryBehaviour):
    """Forget obstacles farther than reset_distance_m / 2 (square) from the robot, in every costmap."""

    def __init__(self, config: ClearCostmapConfig = ClearCostmapConfig(), name: str = "clear_costmap"):
        self.config = config
        self.name = name
        self.cells_cleared = 0

    def start(self, local_pose, costmaps):
        # the kept square is centred on the robot's position in each costmap's own frame
        self.cells_cleared = 0
        for cm, pose in costmaps:
            self.cells_cleared += clear_obstacles_outside(cm, pose.x_m, pose.y_m, self.config.reset_distance_m)

    def step(self, local_pose, velocity, local_costmap, dt_s):
        return 0.0, 0.0, True


@dataclass(frozen=True)
class RotateRecoveryConfig:
    """rotate_recovery parameters (ROS defaults, the original's limits).

    max_rotational_vel / min_in_place_rotational_vel [rad/s]: speed limits of
    the turn (original max_rot_vel 1.0, min_rot_vel 0.2); acc_lim_th
    [rad/s^2]: the original's 3.2; tolerance_rad: the turn ends this short of
    a full 2 pi (ROS 0.10); sim_granularity_rad: angular step of the
    collision check [rad] (ROS 0.017); lookahead_rad: how far along the turn
    the footprint is checked each cycle [rad] (ROS checks the whole rest of
    the turn; a shorter window lets it turn as far as it can).
    """

    max_rotational_vel: float = 1.0
    min_in_place_rotational_vel: float = 0.2
    acc_lim_th: float = 3.2
    tolerance_rad: float = 0.10
    sim_granularity_rad: float = 0.017
    lookahead_rad: float = 0.5

    def __post_init__(self) -> None:
        for name in ("max_rotational_vel", "acc_lim_th", "sim_granularity_rad", "lookahead_rad"):
            require_positive(name, getattr(self, name))
        for name in ("min_in_place_rotational_vel", "tolerance_rad"):
            require_positive(name, getattr(self, name), allow_zero=True)
        if self.min_in_place_rotational_vel > self.max_rotational_vel:
            raise ValueError(f"min_in_place_rotational_vel ({self.min_in_place_rotational_vel}) exceeds "
                             f"max_rotational_vel ({self.max_rotational_vel})")


class RotateRecovery(RecoveryBehaviour):
    """Turn once in place (counter-clockwise), stopping early before a collision."""

    def __init__(self, config: RotateRecoveryConfig = RotateRecoveryConfig(), name: str = "rotate_recovery"):
        self.config = config
        self.name = name
        self._last_yaw: Optional[float] = None
        self.turned_rad = 0.0
        self.blocked = False

    def start(self, local_pose, costmaps):
        self._last_yaw = local_pose.yaw_rad
        self.turned_rad = 0.0
        self.blocked = False

    def step(self, local_pose, velocity, local_costmap, dt_s):
        c = self.config
        if self._last_yaw is None:
            self.start(local_pose, ())
        # accumulate the turn actually made (counter-clockwise positive)
        self.turned_rad += shortest_angular_distance(self._last_yaw, local_pose.yaw_rad)
        self._last_yaw = local_pose.yaw_rad
        remaining = 2.0 * math.pi - c.tolerance_rad - self.turned_rad
        if remaining <= 0.0:
            return 0.0, 0.0, True
        # collision check along the next part of the turn
        window = min(remaining, c.lookahead_rad)
        n = max(1, int(math.ceil(window / c.sim_granularity_rad)))
        for k in range(1, n + 1):
            pose = Pose2D(local_pose.x_m, local_pose.y_m, local_pose.yaw_rad + window * k / n)
            if local_costmap.footprint_cost(pose) >= INSCRIBED_INFLATED_OBSTACLE:
                self.blocked = True
                return 0.0, 0.0, True
        # speed: the fastest from which the robot can still stop at the end, within limits
        w = min(c.max_rotational_vel, math.sqrt(2.0 * c.acc_lim_th * remaining))
        w = max(c.min_in_place_rotational_vel, w)
        return 0.0, w, False


RECOVERY_NAMES = ("conservative_reset", "aggressive_reset", "rotate_recovery", "clear_costmap")


def make_recovery(name: str, circumscribed_radius_m: float = 0.45,
                  rotate: RotateRecoveryConfig = RotateRecoveryConfig(),
                  conservative_reset_dist_m: float = 3.0) -> RecoveryBehaviour:
    """A recovery behaviour by its move_base name.

    'conservative_reset': clear obstacles beyond ``conservative_reset_dist_m``
    (square side); 'aggressive_reset': clear beyond 4 x circumscribed radius;
    'clear_costmap': clear every obstacle cell (reset distance 0);
    'rotate_recovery': one full turn in place.
    """
    if name == "conservative_reset":
        return ClearCostmapRecovery(ClearCostmapConfig(conservative_reset_dist_m), name)
    if name == "aggressive_reset":
        return ClearCostmapRecovery(ClearCostmapConfig(4.0 * circumscribed_radius_m), name)
    if name == "clear_costmap":
        return ClearCostmapRecovery(ClearCostmapConfig(0.0), name)
    if name == "rotate_recovery":
        return RotateRecovery(rotate, name)
    raise ValueError(f"unknown recovery behaviour {name!r}; known: {', '.join(RECOVERY_NAMES)}")
