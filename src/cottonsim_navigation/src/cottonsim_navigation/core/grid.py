"""Regular 2-D grids: geometry of a map and the cost values costmap_2d uses.

Every map-like thing in navigation (the static occupancy map, the global and
local costmaps, the planner's potential field) is a row-major numpy array of
``height x width`` cells plus a :class:`GridSpec` telling where cell (0, 0)
lies in the world. Index order follows ROS's nav_msgs/OccupancyGrid:
``data[my, mx]`` with ``mx`` along x (columns) and ``my`` along y (rows), and
the origin is the world position of the *corner* of cell (0, 0).

The cost constants are exactly the ones of costmap_2d (cost_values.h), so a
grid produced here can be published unchanged as a costmap and compared with
ROS's numbers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from cottonsim_common.validation import require_fields

# costmap_2d cost values (costmap_2d/cost_values.h)
NO_INFORMATION = 255
LETHAL_OBSTACLE = 254
INSCRIBED_INFLATED_OBSTACLE = 253
FREE_SPACE = 0


@dataclass(frozen=True)
class GridSpec:
    """Geometry of a grid.

    resolution_m: edge length of one square cell [m];
    width, height: number of cells along x and y;
    origin_x_m, origin_y_m: world position of the outer corner of cell (0, 0) [m].
    """

    resolution_m: float
    width: int
    height: int
    origin_x_m: float = 0.0
    origin_y_m: float = 0.0

    def __post_init__(self) -> None:
        require_fields(self, positive=("resolution_m",), counts=("width", "height"), finite=("origin_x_m", "origin_y_m"))

    # --- extents -----------------------------------------------------------
    @property
    def shape(self) -> Tuple[int, int]:
        """numpy shape (height, width) of arrays on this grid."""
        return (int(self.height), int(self.width))

    @property
    def size_x_m(self) -> float:
        return self.width * self.resolution_m

    @property
    def size_y_m(self) -> float:
        return self.height * self.resolution_m

    @classmethod
    def centred(cls, centre_x_m: float, centre_y_m: float, size_x_m: float, size_y_m: float,
                resolution_m: float) -> "GridSpec":
        """A grid of about ``size_x_m x size_y_m`` whose middle is at the given point."""
        width = max(1, int(round(size_x_m / resolution_m)))
        height = max(1, int(round(size_y_m / resolution_m)))
        return cls(resolution_m, width, height,
                   centre_x_m - 0.5 * width * resolution_m, centre_y_m - 0.5 * height * resolution_m)

    # --- conversions (vectorised: scalars or arrays) -----------------------
    def world_to_map(self, x_m, y_m):
        """World [m] -> integer cell indices (mx, my); may lie outside the grid.

        Uses floor like costmap_2d's worldToMapNoBounds, so a point on a cell's
        lower edge belongs to that cell.
        """
        mx = np.floor((np.asarray(x_m, dtype=float) - self.origin_x_m) / self.resolution_m).astype(np.int64)
        my = np.floor((np.asarray(y_m, dtype=float) - self.origin_y_m) / self.resolution_m).astype(np.int64)
        return mx, my

    def map_to_world(self, mx, my):
        """Cell indices -> world position of the cell centre [m]."""
        x = self.origin_x_m + (np.asarray(mx, dtype=float) + 0.5) * self.resolution_m
        y = self.origin_y_m + (np.asarray(my, dtype=float) + 0.5) * self.resolution_m
        return x, y

    def in_bounds(self, mx, my):
        """True where the cell indices lie inside the grid."""
        mx = np.asarray(mx)
        my = np.asarray(my)
        return (mx >= 0) & (mx < self.width) & (my >= 0) & (my < self.height)

    def contains_world(self, x_m, y_m):
        """True where the world point lies inside the grid."""
        mx, my = self.world_to_map(x_m, y_m)
        return self.in_bounds(mx, my)


def _check_array(data: np.ndarray, spec: GridSpec, name: str) -> np.ndarray:
    data = np.asarray(data)
    if data.shape != spec.shape:
        raise ValueError(f"{name} has shape {data.shape}, the grid spec needs {spec.shape} (height, width)")
    return data


@dataclass
class Grid:
    """A numpy array on a :class:`GridSpec` (like nav_msgs/OccupancyGrid).

    data: (height, width) array, indexed ``data[my, mx]``.
    """

    spec: GridSpec
    data: np.ndarray

    def __post_init__(self) -> None:
        self.data = _check_array(self.data, self.spec, "data")

    def value_at_world(self, x_m, y_m, outside=NO_INFORMATION):
        """Cell value at world points; ``outside`` where a point is off the grid."""
        mx, my = self.spec.world_to_map(x_m, y_m)
        inside = self.spec.in_bounds(mx, my)
        out = np.full(np.shape(mx), outside, dtype=self.data.dtype)
        out[inside] = self.data[my[inside], mx[inside]]
        return out


@dataclass(frozen=True)
class OccupancyThresholds:
    """map_server's thresholds on occupancy probability (0..1).

    Probability p = value / 100 for nav_msgs/OccupancyGrid values 0..100;
    p > occupied_thresh -> LETHAL_OBSTACLE, p < free_thresh -> FREE_SPACE,
    -1 -> NO_INFORMATION; values in between are kept as a scaled cost
    (only when ``trinary`` is False, as costmap_2d's StaticLayer does).
    Defaults: the original's saved map (0.65 / 0.196) and costmap_2d's
    lethal_cost_threshold 100 / trinary_costmap true.
    """

    occupied_thresh: float = 0.65
    free_thresh: float = 0.196
    trinary: bool = True

    def __post_init__(self) -> None:
        for name in ("occupied_thresh", "free_thresh"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 1.0):
                raise ValueError(f"{name} must lie in [0, 1], got {value!r}")
        if self.free_thresh > self.occupied_thresh:
            raise ValueError(
                f"free_thresh ({self.free_thresh}) must not exceed occupied_thresh ({self.occupied_thresh})")


def occupancy_to_cost(occupancy: np.ndarray, thresholds: OccupancyThresholds = OccupancyThresholds(),
                      track_unknown_space: bool = True) -> np.ndarray:
    """Convert nav_msgs/OccupancyGrid values (-1 unknown, 0..100) to costmap costs (uint8).

    Unknown cells become NO_INFORMATION when ``track_unknown_space`` is true,
    FREE_SPACE otherwise (costmap_2d's StaticLayer behaviour). Values outside
    -1..100 raise ValueError.
    """
    occ = np.asarray(occupancy)
    if occ.size and (np.any(occ < -1) or np.any(occ > 100)):
        raise ValueError("occupancy values must be -1 (unknown) or 0..100")
    occ = occ.astype(np.int16)
    prob = occ.astype(float) / 100.0
    out = np.zeros(occ.shape, dtype=np.uint8)
    unknown = occ < 0
    lethal = (~unknown) & (prob > thresholds.occupied_thresh)
    free = (~unknown) & (prob < thresholds.free_thresh)
    middle = ~(unknown | lethal | free)
    if thresholds.trinary:
        # costmap_2d trinary: anything not lethal and not unknown is free
        out[middle] = FREE_SPACE
    else:
        # scale like StaticLayer::interpretValue: value / 100 * LETHAL
        out[middle] = np.clip(np.round(prob[middle] * LETHAL_OBSTACLE), 1, INSCRIBED_INFLATED_OBSTACLE - 1)
    out[lethal] = LETHAL_OBSTACLE
    out[unknown] = NO_INFORMATION if track_unknown_space else FREE_SPACE
    return out


def disc_occupancy(spec: GridSpec, centres_xy_m, radius_m: float) -> np.ndarray:
    """An OccupancyGrid-valued int8 array on ``spec``: 100 in every cell whose centre lies within ``radius_m``
    of one of the (x, y) world points ``centres_xy_m`` (plant stems seen as discs), 0 elsewhere."""
    occ = np.zeros(spec.shape, np.int8)
    gx, gy = spec.map_to_world(*np.meshgrid(np.arange(spec.width), np.arange(spec.height)))
    for x, y in centres_xy_m:
        occ[(gx - x) ** 2 + (gy - y) ** 2 <= radius_m ** 2] = 100
    return occ
