"""Layered 2-D costmaps, the pure equivalent of ROS's costmap_2d.

A :class:`Costmap2D` owns a master grid of uint8 costs (values of
``core.grid``) and an ordered list of layers. Each update (``update_map``)
re-centres a rolling window on the robot if configured, resets the master
grid and lets every layer write into it in order, exactly like costmap_2d's
LayeredCostmap:

* :class:`StaticLayer` copies a map (nav_msgs/OccupancyGrid values) into the
  master grid (overwrite), looked up by world position so it also works in a
  rolling window;
* :class:`ObstacleLayer` keeps its own grid: it clears cells along the rays
  from the sensor to each point (Bresenham, up to raytrace_range) and marks
  the points between min and max obstacle height within obstacle_range as
  LETHAL; it is merged with "max" (NO_INFORMATION cells of the layer leave
  the master untouched);
* :class:`InflationLayer` spreads cost around LETHAL cells: 254 on the
  obstacle, 253 within the inscribed radius, ``252 * exp(-k (d - r_in))``
  up to inflation_radius (k = cost_scaling_factor). The distance d comes from
  a Euclidean distance transform over cell centres (the same distances
  costmap_2d caches), so the numbers match ROS's.

The whole master grid is recomputed on every update (no bounds tracking):
simpler, and fast enough for the 5 x 5 m local and 40 x 40 m global maps
(see benchmarks/bench_navigation.py).
"""
from __future__ import annotations

import abc
import math
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import numpy as np
from scipy import ndimage

from cottonsim_common.raytrace import clear_rays
from cottonsim_common.validation import require_positive
from cottonsim_navigation.core import geometry as geo
from cottonsim_navigation.core.grid import (FREE_SPACE, INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE,
                                            NO_INFORMATION, GridSpec)

# The original's footprint (0.8 x 0.4 m). NOTE: the real Husky A200 body is
# 0.99 x 0.67 m; the original's smaller footprint is kept as the default so the
# robot fits its narrow lanes the way the paper's runs did.
DEFAULT_FOOTPRINT = ((0.4, 0.2), (-0.4, 0.2), (-0.4, -0.2), (0.4, -0.2))


@dataclass(frozen=True)
class CostmapConfig:
    """costmap_2d's top-level parameters (same names; sizes in metres).

    width / height [m]; resolution [m/cell]; origin_x / origin_y [m] (ignored
    when rolling_window, where the window is centred on the robot);
    footprint: polygon in base_link [m]; footprint_padding [m];
    update_frequency / publish_frequency [Hz] are for the ROS node;
    track_unknown_space: unknown cells stay NO_INFORMATION (else FREE_SPACE).
    """

    global_frame: str = "map"
    robot_base_frame: str = "base_link"
    width: float = 40.0
    height: float = 40.0
    resolution: float = 0.05
    origin_x: float = 0.0
    origin_y: float = 0.0
    rolling_window: bool = False
    track_unknown_space: bool = False
    footprint: Tuple[Tuple[float, float], ...] = DEFAULT_FOOTPRINT
    footprint_padding: float = 0.005
    update_frequency: float = 4.0
    publish_frequency: float = 3.0
    transform_tolerance: float = 0.3

    def __post_init__(self) -> None:
        for name in ("width", "height", "resolution"):
            require_positive(name, getattr(self, name))
        for name in ("update_frequency", "publish_frequency", "footprint_padding", "transform_tolerance"):
            require_positive(name, getattr(self, name), allow_zero=True)
        for name in ("origin_x", "origin_y"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite")
        try:
            geo.validate_footprint(self.footprint)
        except ValueError as exc:
            raise ValueError(f"footprint: {exc}") from None
        if round(self.width / self.resolution) < 1 or round(self.height / self.resolution) < 1:
            raise ValueError("width and height must hold at least one cell of the given resolution")

    def padded_footprint(self) -> np.ndarray:
        return geo.pad_footprint(self.footprint, self.footprint_padding)


class CostmapLayer(abc.ABC):
    """One layer of a :class:`Costmap2D` (a costmap_2d plugin)."""

    name: str = "layer"
    enabled: bool = True

    def match_size(self, costmap: "Costmap2D") -> None:
        """The master grid was (re)created: allocate layer storage. Default: nothing."""

    def shift(self, costmap: "Costmap2D", dx_cells: int, dy_cells: int) -> None:
        """The rolling window moved by (dx, dy) cells: keep what stays in view. Default: nothing."""

    @abc.abstractmethod
    def update_costs(self, master: np.ndarray, costmap: "Costmap2D", robot_pose: geo.Pose2D) -> None:
        """Write this layer's contribution into ``master`` (uint8, in place)."""


# --- static layer ---------------------------------------------------------------
@dataclass(frozen=True)
class StaticLayerConfig:
    """costmap_2d StaticLayer parameters.

    lethal_cost_threshold: occupancy value (0..100) at or above which a cell is
    LETHAL (costmap_2d default 100); unknown_cost_value: occupancy value read as
    unknown (-1); trinary_costmap: everything else is FREE (else scaled 0..252).
    """

    enabled: bool = True
    lethal_cost_threshold: int = 100
    unknown_cost_value: int = -1
    trinary_costmap: bool = True

    def __post_init__(self) -> None:
        if not 0 <= int(self.lethal_cost_threshold) <= 100:
            raise ValueError(f"lethal_cost_threshold must lie in 0..100, got {self.lethal_cost_threshold}")


class StaticLayer(CostmapLayer):
    """A fixed map (e.g. from map_server) copied into the master grid.

    ``set_map(occupancy, spec)`` takes nav_msgs/OccupancyGrid values (-1,
    0..100) as a (height, width) array on ``spec``. Master cells whose centre
    falls outside the map are left as they are.
    """

    name = "static_layer"

    def __init__(self, config: StaticLayerConfig = StaticLayerConfig()):
        self.config = config
        self.enabled = config.enabled
        self.map_spec: Optional[GridSpec] = None
        self.map_costs: Optional[np.ndarray] = None
        self._track_unknown = True

    def set_map(self, occupancy: np.ndarray, spec: GridSpec, track_unknown_space: bool = True) -> None:
        occ = np.asarray(occupancy)
        if occ.shape != spec.shape:
            raise ValueError(f"static map has shape {occ.shape}, its spec says {spec.shape}")
        if occ.size and (occ.min() < -1 or occ.max() > 100):
            raise ValueError("static map values must be -1 (unknown) or 0..100")
        occ = occ.astype(np.int16)
        c = self.config
        costs = np.zeros(occ.shape, dtype=np.uint8)
        unknown = occ == c.unknown_cost_value
        lethal = (~unknown) & (occ >= c.lethal_cost_threshold)
        rest = ~(unknown | lethal)
        if not c.trinary_costmap:
            costs[rest] = np.round(occ[rest].astype(float) / c.lethal_cost_threshold * LETHAL_OBSTACLE
                                   ).clip(0, INSCRIBED_INFLATED_OBSTACLE - 1)
        costs[lethal] = LETHAL_OBSTACLE
        costs[unknown] = NO_INFORMATION if track_unknown_space else FREE_SPACE
        self.map_spec = spec
        self.map_costs = costs

    def update_costs(self, master, costmap, robot_pose):
        if self.map_costs is None:
            return
        spec = costmap.spec
        if (self.map_spec == spec):
            master[...] = self.map_costs
            return
        mx, my = np.meshgrid(np.arange(spec.width), np.arange(spec.height))
        wx, wy = spec.map_to_world(mx, my)
        sx, sy = self.map_spec.world_to_map(wx, wy)
        inside = self.map_spec.in_bounds(sx, sy)
        master[inside] = self.map_costs[sy[inside], sx[inside]]


# --- obstacle layer ---------------------------------------------------------------
@dataclass(frozen=True)
class ObstacleLayerConfig:
    """costmap_2d ObstacleLayer parameters (one observation source).

    obstacle_range [m]: points farther than this from the sensor are not marked
    (ROS default 2.5, the original 5.5); raytrace_range [m]: free space is
    cleared up to this distance (ROS 3.0, original 6.0);
    min/max_obstacle_height [m]: only points with z in this band mark
    (ROS 0.0 / 2.0); footprint_clearing_enabled: the robot's own footprint is
    cleared every update; marking / clearing switch the two operations.
    """

    enabled: bool = True
    obstacle_range: float = 5.5
    raytrace_range: float = 6.0
    min_obstacle_height: float = 0.0
    max_obstacle_height: float = 2.0
    marking: bool = True
    clearing: bool = True
    footprint_clearing_enabled: bool = True

    def __post_init__(self) -> None:
        require_positive("obstacle_range", self.obstacle_range)
        require_positive("raytrace_range", self.raytrace_range)
        for name in ("min_obstacle_height", "max_obstacle_height"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite")
        if self.min_obstacle_height > self.max_obstacle_height:
            raise ValueError(f"min_obstacle_height ({self.min_obstacle_height}) exceeds "
                             f"max_obstacle_height ({self.max_obstacle_height})")


class ObstacleLayer(CostmapLayer):
    """Obstacles from point clouds, with ray-traced clearing.

    Call ``add_observation(points, sensor_origin)`` with points (N, 3) already
    in the costmap's global frame and the sensor position (3,) in that frame;
    observations are applied (clear, then mark) at the next ``update_map``.
    The layer grid persists between updates and moves with a rolling window.
    """

    name = "obstacle_layer"

    def __init__(self, config: ObstacleLayerConfig = ObstacleLayerConfig()):
        self.config = config
        self.enabled = config.enabled
        self.grid: Optional[np.ndarray] = None
        self._pending: List[Tuple[np.ndarray, np.ndarray]] = []
        self._default = FREE_SPACE

    def match_size(self, costmap):
        self._default = NO_INFORMATION if costmap.config.track_unknown_space else FREE_SPACE
        self.grid = np.full(costmap.spec.shape, self._default, dtype=np.uint8)

    def shift(self, costmap, dx_cells, dy_cells):
        self.grid = _shift_grid(self.grid, dx_cells, dy_cells, self._default)

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

    def _apply(self, spec: GridSpec, pts: np.ndarray, origin: np.ndarray) -> None:
        c = self.config
        d = np.hypot(pts[:, 0] - origin[0], pts[:, 1] - origin[1])
        ox, oy = spec.world_to_map(origin[0], origin[1])
        if c.clearing and len(pts):
            # shorten rays beyond raytrace_range to that length (as costmap_2d does)
            scale = np.where(d > c.raytrace_range, c.raytrace_range / np.maximum(d, 1e-12), 1.0)
            ex = origin[0] + (pts[:, 0] - origin[0]) * scale
            ey = origin[1] + (pts[:, 1] - origin[1]) * scale
            emx, emy = spec.world_to_map(ex, ey)
            clear_rays(self.grid, np.int64(ox), np.int64(oy), emx.astype(np.int64), emy.astype(np.int64),
                       np.uint8(FREE_SPACE))
        if c.marking and len(pts):
            keep = ((d <= c.obstacle_range) & (pts[:, 2] >= c.min_obstacle_height)
                    & (pts[:, 2] <= c.max_obstacle_height))
            mx, my = spec.world_to_map(pts[keep, 0], pts[keep, 1])
            inside = spec.in_bounds(mx, my)
            self.grid[my[inside], mx[inside]] = LETHAL_OBSTACLE

    def update_costs(self, master, costmap, robot_pose):
        if self.grid is None:
            self.match_size(costmap)
        for pts, origin in self._pending:
            self._apply(costmap.spec, pts, origin)
        self._pending.clear()
        if self.config.footprint_clearing_enabled:
            fx, fy = geo.footprint_cells(costmap.spec, robot_pose, costmap.footprint)
            self.grid[fy, fx] = FREE_SPACE
        known = self.grid != NO_INFORMATION
        write = known & ((master == NO_INFORMATION) | (master < self.grid))
        master[write] = self.grid[write]


# --- inflation layer ----------------------------------------------------------------
@dataclass(frozen=True)
class InflationLayerConfig:
    """costmap_2d InflationLayer parameters.

    inflation_radius [m]: cost is spread this far from obstacles (ROS 0.55,
    the original 0.5); cost_scaling_factor [1/m]: exponential decay rate
    (ROS 10.0); inflate_unknown: NO_INFORMATION cells may be overwritten by
    inflation cost below 253 too.
    """

    enabled: bool = True
    inflation_radius: float = 0.5
    cost_scaling_factor: float = 10.0
    inflate_unknown: bool = False

    def __post_init__(self) -> None:
        require_positive("inflation_radius", self.inflation_radius, allow_zero=True)
        require_positive("cost_scaling_factor", self.cost_scaling_factor, allow_zero=True)


def inflation_cost(distance_m, inscribed_radius_m: float, cost_scaling_factor: float) -> np.ndarray:
    """costmap_2d's InflationLayer::computeCost as uint8 for distances [m] to the nearest obstacle."""
    d = np.asarray(distance_m, dtype=float)
    factor = np.exp(-cost_scaling_factor * (d - inscribed_radius_m))
    cost = ((INSCRIBED_INFLATED_OBSTACLE - 1) * factor).astype(np.int64)   # truncation like the C++ cast
    cost = np.where(d <= inscribed_radius_m, INSCRIBED_INFLATED_OBSTACLE, cost)
    cost = np.where(d == 0.0, LETHAL_OBSTACLE, cost)
    return cost.astype(np.uint8)


class InflationLayer(CostmapLayer):
    """Spreads decaying cost around LETHAL cells of the master grid."""

    name = "inflation_layer"

    def __init__(self, config: InflationLayerConfig = InflationLayerConfig()):
        self.config = config
        self.enabled = config.enabled

    def update_costs(self, master, costmap, robot_pose):
        c = self.config
        res = costmap.spec.resolution_m
        lethal = master == LETHAL_OBSTACLE
        if not lethal.any() or c.inflation_radius <= 0:
            return
        cell_radius = int(math.ceil(c.inflation_radius / res))
        dist_cells = ndimage.distance_transform_edt(~lethal)
        near = dist_cells <= cell_radius
        costs = inflation_cost(dist_cells[near] * res, costmap.inscribed_radius_m, c.cost_scaling_factor)
        old = master[near]
        if c.inflate_unknown:
            take_unknown = costs > FREE_SPACE
        else:
            take_unknown = costs >= INSCRIBED_INFLATED_OBSTACLE
        new = np.where(old == NO_INFORMATION, np.where(take_unknown, costs, old), np.maximum(old, costs))
        master[near] = new


# --- the costmap ----------------------------------------------------------------------
def _shift_grid(grid: np.ndarray, dx: int, dy: int, fill: int) -> np.ndarray:
    """Content moved so that new[y, x] = old[y + dy, x + dx]; uncovered cells = fill."""
    out = np.full_like(grid, fill)
    h, w = grid.shape
    if abs(dx) >= w or abs(dy) >= h:
        return out
    sx0, sx1 = max(0, dx), min(w, w + dx)
    sy0, sy1 = max(0, dy), min(h, h + dy)
    out[sy0 - dy:sy1 - dy, sx0 - dx:sx1 - dx] = grid[sy0:sy1, sx0:sx1]
    return out


class Costmap2D:
    """A layered costmap: master uint8 grid + ordered layers.

    Typical use::

        cm = Costmap2D(CostmapConfig(rolling_window=True, width=5, height=5),
                       [ObstacleLayer(), InflationLayer()])
        cm.obstacle_layer.add_observation(points_xyz, sensor_xyz)
        cm.update_map(robot_pose)
        cm.costs            # (height, width) uint8
        cm.footprint_cost(pose)
    """

    def __init__(self, config: CostmapConfig = CostmapConfig(), layers: Sequence[CostmapLayer] = ()):
        self.config = config
        self.layers: List[CostmapLayer] = list(layers)
        for layer in self.layers:
            if not isinstance(layer, CostmapLayer):
                raise ValueError(f"layers must be CostmapLayer instances, got {type(layer).__name__}")
        self.footprint = config.padded_footprint()
        self.inscribed_radius_m, self.circumscribed_radius_m = geo.footprint_radii(self.footprint)
        self._default = NO_INFORMATION if config.track_unknown_space else FREE_SPACE
        self.resize(GridSpec(config.resolution, int(round(config.width / config.resolution)),
                             int(round(config.height / config.resolution)), config.origin_x, config.origin_y))

    # --- structure ---
    def resize(self, spec: GridSpec) -> None:
        """Use a new grid geometry (e.g. the static map's); layers are reallocated."""
        self.spec = spec
        self.costs = np.full(spec.shape, self._default, dtype=np.uint8)
        for layer in self.layers:
            layer.match_size(self)

    def layer(self, cls) -> Optional[CostmapLayer]:
        for layer in self.layers:
            if isinstance(layer, cls):
                return layer
        return None

    @property
    def static_layer(self) -> Optional[StaticLayer]:
        return self.layer(StaticLayer)

    @property
    def obstacle_layer(self) -> Optional[ObstacleLayer]:
        return self.layer(ObstacleLayer)

    @property
    def inflation_layer(self) -> Optional[InflationLayer]:
        return self.layer(InflationLayer)

    # --- updates ---
    def update_origin(self, new_origin_x_m: float, new_origin_y_m: float) -> None:
        """Move the grid to a new origin, snapped to whole cells; overlapping cells are kept."""
        res = self.spec.resolution_m
        dx = int(math.floor((new_origin_x_m - self.spec.origin_x_m) / res + 0.5))
        dy = int(math.floor((new_origin_y_m - self.spec.origin_y_m) / res + 0.5))
        if dx == 0 and dy == 0:
            return
        self.spec = GridSpec(res, self.spec.width, self.spec.height,
                             self.spec.origin_x_m + dx * res, self.spec.origin_y_m + dy * res)
        self.costs = _shift_grid(self.costs, dx, dy, self._default)
        for layer in self.layers:
            layer.shift(self, dx, dy)

    def update_map(self, robot_pose) -> np.ndarray:
        """Recompute the master grid for the robot at ``robot_pose`` (costmap frame); returns it."""
        pose = geo.as_pose(robot_pose)
        if self.config.rolling_window:
            self.update_origin(pose.x_m - 0.5 * self.spec.size_x_m, pose.y_m - 0.5 * self.spec.size_y_m)
        master = np.full(self.spec.shape, self._default, dtype=np.uint8)
        for layer in self.layers:
            if layer.enabled:
                layer.update_costs(master, self, pose)
        self.costs = master
        return master

    # --- queries ---
    def cost_at_world(self, x_m, y_m):
        """Cost of the cells under world points; NO_INFORMATION off the map."""
        mx, my = self.spec.world_to_map(x_m, y_m)
        inside = self.spec.in_bounds(mx, my)
        out = np.full(np.shape(mx), NO_INFORMATION, dtype=np.uint8)
        out[inside] = self.costs[my[inside], mx[inside]]
        return out

    def footprint_cost(self, pose) -> int:
        """Highest cost under the padded footprint placed at ``pose`` (interior and outline).

        NO_INFORMATION (255) when any part is off the map; >= 253 means the
        robot would touch an obstacle.
        """
        p = geo.as_pose(pose)
        corners = geo.transform_points(p, self.footprint)
        if not np.all(self.spec.contains_world(corners[:, 0], corners[:, 1])):
            return NO_INFORMATION
        fx, fy = geo.footprint_cells(self.spec, p, self.footprint)
        if fx.size == 0:
            return NO_INFORMATION
        return int(self.costs[fy, fx].max())

    def to_occupancy(self) -> np.ndarray:
        """Costs as nav_msgs/OccupancyGrid values the way costmap_2d publishes them (int8)."""
        out = np.round(self.costs.astype(float) * 100.0 / LETHAL_OBSTACLE).astype(np.int16)
        out[self.costs == LETHAL_OBSTACLE] = 100
        out[self.costs == INSCRIBED_INFLATED_OBSTACLE] = 99
        out[self.costs == NO_INFORMATION] = -1
        return out.astype(np.int8)


def make_global_costmap(occupancy: np.ndarray, spec: GridSpec, config: Optional[CostmapConfig] = None,
                        static: StaticLayerConfig = StaticLayerConfig(),
                        inflation: InflationLayerConfig = InflationLayerConfig()) -> Costmap2D:
    """The original's global costmap: static map + inflation, map-sized, unknown tracked."""
    if config is None:
        config = CostmapConfig(track_unknown_space=True)
    cm = Costmap2D(config, [StaticLayer(static), InflationLayer(inflation)])
    cm.resize(spec)
    cm.static_layer.set_map(occupancy, spec, track_unknown_space=config.track_unknown_space)
    cm.update_map(geo.Pose2D(*spec.map_to_world(0, 0), 0.0))
    return cm


def make_local_costmap(config: Optional[CostmapConfig] = None,
                       obstacles: ObstacleLayerConfig = ObstacleLayerConfig(),
                       inflation: InflationLayerConfig = InflationLayerConfig()) -> Costmap2D:
    """The original's local costmap: rolling 5 x 5 m window, obstacle layer + inflation."""
    if config is None:
        config = CostmapConfig(global_frame="odom", rolling_window=True, width=5.0, height=5.0)
    return Costmap2D(config, [ObstacleLayer(obstacles), InflationLayer(inflation)])
