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
  up to inflation_radius (k = cost_scaling_factor); ``lethal_radius_m``
  puts a smaller radius in place of r_in (a plan may then pass closer). The distance d comes from
  a Euclidean distance transform over cell centres (the same distances
  costmap_2d caches), so the numbers match ROS's.

The whole master grid is recomputed on every update (no bounds tracking),
fast enough for the 5 x 5 m local and 40 x 40 m global maps (see
benchmarks/bench_navigation.py), unless ``update_map`` is given a window: then
only the square of that side around the robot is recomputed (with the
inflation radius as a margin, so its costs equal a full update's), which
keeps a global costmap with an obstacle layer cheap to update as the robot
drives (see :class:`CostmapWindow`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np
from scipy import ndimage

from cottonsim_common.raytrace import clear_rays
from cottonsim_common.validation import require_fields, require_positive
from cottonsim_common.pose import Pose2D, as_pose, transform_points
from cottonsim_navigation.core.footprint import footprint_cells, footprint_radii, pad_footprint, validate_footprint
from cottonsim_navigation.core.grid import (FREE_SPACE, INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE,
                                            NO_INFORMATION, GridSpec)
from cottonsim_navigation.planning.costmap_layer import CostmapLayer, shift_grid
from cottonsim_navigation.planning.obstacle_layer import ObstacleLayer, ObstacleLayerConfig

# The Husky A200's body, 0.99 x 0.67 m, centred on base_link (the original's
# 0.8 x 0.4 m box let plans and trajectories pass 0.13 m closer to plants on
# each side than the body can), and a padding of 0.03 m around it.
DEFAULT_FOOTPRINT = ((0.495, 0.335), (-0.495, 0.335), (-0.495, -0.335), (0.495, -0.335))
DEFAULT_FOOTPRINT_PADDING_M = 0.03


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
    footprint_padding: float = DEFAULT_FOOTPRINT_PADDING_M
    update_frequency: float = 4.0
    publish_frequency: float = 3.0
    transform_tolerance: float = 0.3

    def __post_init__(self) -> None:
        require_fields(self, positive=("width", "height", "resolution"),
                       non_negative=("update_frequency", "publish_frequency", "footprint_padding",
                                     "transform_tolerance"),
                       finite=("origin_x", "origin_y"))
        try:
            validate_footprint(self.footprint)
        except ValueError as exc:
            raise ValueError(f"footprint: {exc}") from None
        if round(self.width / self.resolution) < 1 or round(self.height / self.resolution) < 1:
            raise ValueError("width and height must hold at least one cell of the given resolution")

    def padded_footprint(self) -> np.ndarray:
        return pad_footprint(self.footprint, self.footprint_padding)


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


# --- inflation layer ----------------------------------------------------------------
@dataclass(frozen=True)
class InflationLayerConfig:
    """costmap_2d InflationLayer parameters.

    inflation_radius [m]: cost is spread this far from obstacles (ROS 0.55,
    the original 0.5); cost_scaling_factor [1/m]: exponential decay rate
    (ROS 10.0); inflate_unknown: NO_INFORMATION cells may be overwritten by
    inflation cost below 253 too.
    lethal_radius_m [m] (port's addition): cells this close to an obstacle
    are INSCRIBED (253, impassable for the global planner) and the decay
    starts here; None (the default) = the footprint's inscribed radius,
    costmap_2d's behaviour. A smaller value lets a plan for the robot's
    centre keep less clearance from obstacle marks than the body needs,
    leaving the body to the local planner's footprint check.
    """

    enabled: bool = True
    inflation_radius: float = 0.5
    cost_scaling_factor: float = 10.0
    inflate_unknown: bool = False
    lethal_radius_m: Optional[float] = None

    def __post_init__(self) -> None:
        require_positive("inflation_radius", self.inflation_radius, allow_zero=True)
        require_positive("cost_scaling_factor", self.cost_scaling_factor, allow_zero=True)
        if self.lethal_radius_m is not None:
            require_positive("lethal_radius_m", self.lethal_radius_m, allow_zero=True)


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

    def lethal_radius_m(self, inscribed_radius_m: float) -> float:
        """Distance from an obstacle within which cells are INSCRIBED [m] (see InflationLayerConfig)."""
        r = self.config.lethal_radius_m
        return inscribed_radius_m if r is None else float(r)

    def update_costs(self, master, costmap, robot_pose):
        c = self.config
        res = costmap.spec.resolution_m
        lethal = master == LETHAL_OBSTACLE
        if not lethal.any() or c.inflation_radius <= 0:
            return
        cell_radius = int(math.ceil(c.inflation_radius / res))
        dist_cells = ndimage.distance_transform_edt(~lethal)
        near = dist_cells <= cell_radius
        costs = inflation_cost(dist_cells[near] * res, self.lethal_radius_m(costmap.inscribed_radius_m),
                               c.cost_scaling_factor)
        old = master[near]
        if c.inflate_unknown:
            take_unknown = costs > FREE_SPACE
        else:
            take_unknown = costs >= INSCRIBED_INFLATED_OBSTACLE
        new = np.where(old == NO_INFORMATION, np.where(take_unknown, costs, old), np.maximum(old, costs))
        master[near] = new


# --- the costmap ----------------------------------------------------------------------
@dataclass(frozen=True)
class CostmapWindow:
    """What a layer sees of a :class:`Costmap2D` during a window update.

    spec: the window's cells (the master array the layers write into);
    full_spec: the whole grid; window: (row slice, column slice) of the
    window in the whole grid; config, footprint and inscribed_radius_m as
    the costmap's.
    """

    spec: GridSpec
    full_spec: GridSpec
    window: Tuple[slice, slice]
    config: CostmapConfig
    footprint: np.ndarray
    inscribed_radius_m: float


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
        self.inscribed_radius_m, self.circumscribed_radius_m = footprint_radii(self.footprint)
        self._default = NO_INFORMATION if config.track_unknown_space else FREE_SPACE
        self._full_update_due = True
        self.resize(GridSpec(config.resolution, int(round(config.width / config.resolution)),
                             int(round(config.height / config.resolution)), config.origin_x, config.origin_y))

    # --- structure ---
    def resize(self, spec: GridSpec) -> None:
        """Use a new grid geometry (e.g. the static map's); layers are reallocated."""
        self.spec = spec
        self.costs = np.full(spec.shape, self._default, dtype=np.uint8)
        for layer in self.layers:
            layer.match_size(self)
        self._full_update_due = True

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

    @property
    def lethal_radius_m(self) -> float:
        """How close to an obstacle a cell is INSCRIBED [m]: the inflation layer's lethal radius, else inscribed."""
        inflation = self.inflation_layer
        if inflation is None or not inflation.enabled:
            return self.inscribed_radius_m
        return inflation.lethal_radius_m(self.inscribed_radius_m)

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
        self.costs = shift_grid(self.costs, dx, dy, self._default)
        for layer in self.layers:
            layer.shift(self, dx, dy)

    @property
    def full_spec(self) -> GridSpec:
        return self.spec

    @property
    def window(self) -> Tuple[slice, slice]:
        return (slice(None), slice(None))

    def request_full_update(self) -> None:
        """The next ``update_map`` recomputes the whole grid even when given a window (after a clearing)."""
        self._full_update_due = True

    def update_map(self, robot_pose, window_m: Optional[float] = None) -> np.ndarray:
        """Recompute the master grid for the robot at ``robot_pose`` (costmap frame); returns it.

        window_m [m]: recompute only a square of this side centred on the
        robot (a fixed, non-rolling grid only; None = the whole grid).
        """
        pose = as_pose(robot_pose)
        if self.config.rolling_window:
            self.update_origin(pose.x_m - 0.5 * self.spec.size_x_m, pose.y_m - 0.5 * self.spec.size_y_m)
        if window_m is not None and not self.config.rolling_window and not self._full_update_due:
            require_positive("window_m", window_m)
            self._update_window(pose, float(window_m))
            return self.costs
        master = np.full(self.spec.shape, self._default, dtype=np.uint8)
        for layer in self.layers:
            if layer.enabled:
                layer.update_costs(master, self, pose)
        self.costs = master
        self._full_update_due = False
        return master

    def _update_window(self, pose: Pose2D, window_m: float) -> None:
        spec = self.spec
        res = spec.resolution_m
        inflation = self.inflation_layer
        margin = int(math.ceil(inflation.config.inflation_radius / res)) + 1 if inflation is not None else 0
        cx, cy = spec.world_to_map(pose.x_m, pose.y_m)
        half = int(math.ceil(0.5 * window_m / res))
        inner = [(max(0, int(c) - half), min(n, int(c) + half + 1)) for c, n in ((cx, spec.width), (cy, spec.height))]
        if inner[0][0] >= inner[0][1] or inner[1][0] >= inner[1][1]:
            return                                                  # the window lies off the grid
        (x0, x1), (y0, y1) = [(max(0, a - margin), min(n, b + margin))
                              for (a, b), n in zip(inner, (spec.width, spec.height))]
        view = CostmapWindow(GridSpec(res, x1 - x0, y1 - y0, spec.origin_x_m + x0 * res, spec.origin_y_m + y0 * res),
                             spec, (slice(y0, y1), slice(x0, x1)), self.config, self.footprint,
                             self.inscribed_radius_m)
        master = np.full(view.spec.shape, self._default, dtype=np.uint8)
        for layer in self.layers:
            if layer.enabled:
                layer.update_costs(master, view, pose)
        (ix0, ix1), (iy0, iy1) = inner
        self.costs[iy0:iy1, ix0:ix1] = master[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0]

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
        p = as_pose(pose)
        corners = transform_points(p, self.footprint)
        if not np.all(self.spec.contains_world(corners[:, 0], corners[:, 1])):
            return NO_INFORMATION
        fx, fy = footprint_cells(self.spec, p, self.footprint)
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
    cm.update_map(Pose2D(*spec.map_to_world(0, 0), 0.0))
    return cm


def make_local_costmap(config: Optional[CostmapConfig] = None,
                       obstacles: ObstacleLayerConfig = ObstacleLayerConfig(),
                       inflation: InflationLayerConfig = InflationLayerConfig()) -> Costmap2D:
    """The original's local costmap: rolling 5 x 5 m window, obstacle layer + inflation."""
    if config is None:
        config = CostmapConfig(global_frame="odom", rolling_window=True, width=5.0, height=5.0)
    return Costmap2D(config, [ObstacleLayer(obstacles), InflationLayer(inflation)])
