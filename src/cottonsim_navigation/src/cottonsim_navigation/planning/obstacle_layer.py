"""costmap_2d's ObstacleLayer: obstacles marked from point clouds, free space cleared along the sensor rays.

Clearing follows costmap_2d (Bresenham rays from the sensor to each point, up
to raytrace_range, the end cell untouched) with one addition,
``clearing_miss_count``: an obstacle cell is freed only after that many
consecutive observations whose rays passed through it without a point
landing in it. With 1 (costmap_2d's behaviour) a single grazing ray erases a
thin stem that the LiDAR saw a moment before; a count of a few observations
keeps the rows of a crop marked while a plant that is really gone (or a
passing object) still clears within a second or two.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from cottonsim_navigation.core.footprint import footprint_cells
from cottonsim_navigation.core.grid import FREE_SPACE, LETHAL_OBSTACLE, NO_INFORMATION, GridSpec
from cottonsim_common.raytrace import clear_rays
from cottonsim_common.validation import require_fields
from cottonsim_navigation.planning.costmap_layer import CostmapLayer, shift_grid


@dataclass(frozen=True)
class ObstacleLayerConfig:
    """costmap_2d ObstacleLayer parameters (one observation source).

    obstacle_range [m]: points farther than this from the sensor are not marked
    (ROS default 2.5, the original 5.5); raytrace_range [m]: free space is
    cleared up to this distance (ROS 3.0, original 6.0);
    min/max_obstacle_height [m]: only points with z in this band mark
    (ROS 0.0 / 2.0); footprint_clearing_enabled: the robot's own footprint is
    cleared every update; marking / clearing switch the two operations;
    clearing_miss_count: consecutive observations whose rays cross an
    obstacle cell before it is cleared (1 = costmap_2d; default 1).
    """

    enabled: bool = True
    obstacle_range: float = 5.5
    raytrace_range: float = 6.0
    min_obstacle_height: float = 0.0
    max_obstacle_height: float = 2.0
    marking: bool = True
    clearing: bool = True
    footprint_clearing_enabled: bool = True
    clearing_miss_count: int = 1

    def __post_init__(self) -> None:
        require_fields(self, positive=("obstacle_range", "raytrace_range"),
                       finite=("min_obstacle_height", "max_obstacle_height"))
        if self.min_obstacle_height > self.max_obstacle_height:
            raise ValueError(f"min_obstacle_height ({self.min_obstacle_height}) exceeds "
                             f"max_obstacle_height ({self.max_obstacle_height})")
        n = self.clearing_miss_count
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 255:
            raise ValueError(f"clearing_miss_count must be an integer in 1..255, got {n!r}")


class ObstacleLayer(CostmapLayer):
    """Obstacles from point clouds, with ray-traced clearing.

    Call ``add_observation(points, sensor_origin)`` with points (N, 3) already
    in the costmap's global frame and the sensor position (3,) in that frame;
    observations are applied (clear, then mark) at the next ``update_map``.
    The layer grid persists between updates and moves with a rolling window.
    ``misses`` counts, per cell, the consecutive observations that saw through
    a marked cell (see the module docstring).
    """

    name = "obstacle_layer"

    def __init__(self, config: ObstacleLayerConfig = ObstacleLayerConfig()):
        self.config = config
        self.enabled = config.enabled
        self.grid: Optional[np.ndarray] = None
        self.misses: Optional[np.ndarray] = None
        self._pending: List[Tuple[np.ndarray, np.ndarray]] = []
        self._default = FREE_SPACE

    def match_size(self, costmap):
        self._default = NO_INFORMATION if costmap.config.track_unknown_space else FREE_SPACE
        self.grid = np.full(costmap.spec.shape, self._default, dtype=np.uint8)
        self.misses = np.zeros(costmap.spec.shape, dtype=np.uint8)

    def shift(self, costmap, dx_cells, dy_cells):
        self.grid = shift_grid(self.grid, dx_cells, dy_cells, self._default)
        self.misses = shift_grid(self.misses, dx_cells, dy_cells, 0)

    def add_observation(self, points: np.ndarray, sensor_origin: Sequence[float]) -> None:
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] < 3:
            raise ValueError(f"points must be an (N, 3) array, got shape {pts.shape}")
        origin = np.asarray(sensor_origin, dtype=float).reshape(-1)
        if origin.size < 2 or not np.all(np.isfinite(origin)):
            raise ValueError(f"sensor_origin must be a finite (x, y[, z]) position, got {sensor_origin!r}")
        pts = pts[np.all(np.isfinite(pts[:, :3]), axis=1), :3]   # NaN returns (no hit) carry nothing
        self._pending.append((pts, origin[:3] if origin.size >= 3 else np.r_[origin[:2], 0.0]))

    def clear_all(self) -> None:
        if self.grid is not None:
            self.grid[...] = self._default
            self.misses[...] = 0

    def forget(self, mask: np.ndarray) -> int:
        """Reset the cells under ``mask`` to "nothing known"; returns how many held something."""
        changed = mask & (self.grid != self._default)
        self.grid[changed] = self._default
        self.misses[mask] = 0
        return int(changed.sum())

    def _clear(self, spec: GridSpec, origin: np.ndarray, ex: np.ndarray, ey: np.ndarray) -> None:
        ox, oy = spec.world_to_map(origin[0], origin[1])
        emx, emy = spec.world_to_map(ex, ey)
        n = self.config.clearing_miss_count
        if n == 1:
            clear_rays(self.grid, np.int64(ox), np.int64(oy), emx.astype(np.int64), emy.astype(np.int64),
                       np.uint8(FREE_SPACE))
            return
        # work on the rays' bounding box only (the global costmap's grid has millions of cells)
        h, w = self.grid.shape
        x0, x1 = max(0, int(min(ox, emx.min()))), min(w, int(max(ox, emx.max())) + 1)
        y0, y1 = max(0, int(min(oy, emy.min()))), min(h, int(max(oy, emy.max())) + 1)
        if x0 >= x1 or y0 >= y1:
            return
        crossed = np.zeros((y1 - y0, x1 - x0), dtype=np.uint8)
        clear_rays(crossed, np.int64(ox - x0), np.int64(oy - y0), (emx - x0).astype(np.int64),
                   (emy - y0).astype(np.int64), np.uint8(1))
        crossed = crossed.astype(bool)
        grid, misses = self.grid[y0:y1, x0:x1], self.misses[y0:y1, x0:x1]
        lethal = crossed & (grid == LETHAL_OBSTACLE)
        misses[lethal] = np.minimum(misses[lethal].astype(np.int16) + 1, 255).astype(np.uint8)
        free = crossed & ((grid != LETHAL_OBSTACLE) | (misses >= n))
        grid[free] = FREE_SPACE
        misses[free] = 0

    def _apply(self, spec: GridSpec, pts: np.ndarray, origin: np.ndarray) -> None:
        c = self.config
        d = np.hypot(pts[:, 0] - origin[0], pts[:, 1] - origin[1])
        if c.clearing and len(pts):
            # shorten rays beyond raytrace_range to that length (as costmap_2d does)
            scale = np.where(d > c.raytrace_range, c.raytrace_range / np.maximum(d, 1e-12), 1.0)
            self._clear(spec, origin, origin[0] + (pts[:, 0] - origin[0]) * scale,
                        origin[1] + (pts[:, 1] - origin[1]) * scale)
        if c.marking and len(pts):
            keep = ((d <= c.obstacle_range) & (pts[:, 2] >= c.min_obstacle_height)
                    & (pts[:, 2] <= c.max_obstacle_height))
            mx, my = spec.world_to_map(pts[keep, 0], pts[keep, 1])
            inside = spec.in_bounds(mx, my)
            self.grid[my[inside], mx[inside]] = LETHAL_OBSTACLE
            self.misses[my[inside], mx[inside]] = 0

    def update_costs(self, master, costmap, robot_pose):
        if self.grid is None:
            self.match_size(costmap)
        spec = costmap.full_spec
        for pts, origin in self._pending:
            self._apply(spec, pts, origin)
        self._pending.clear()
        if self.config.footprint_clearing_enabled:
            fx, fy = footprint_cells(spec, robot_pose, costmap.footprint)
            self.grid[fy, fx] = FREE_SPACE
            self.misses[fy, fx] = 0
        grid = self.grid[costmap.window]
        known = grid != NO_INFORMATION
        write = known & ((master == NO_INFORMATION) | (master < grid))
        master[write] = grid[write]
