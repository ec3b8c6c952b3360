"""Occupancy maps for map_server and map_saver: an empty map, and saving a map.

Why: Debian has no map_server package. Loading a map_server YAML + image is
done once, in ``cottonsim_world.farm.export.load_map_yaml``; this module adds
the two other pieces the navigation nodes need:

* :func:`empty_map` -- a free map of a given size (the original's GPS mode
  served an empty map so the global costmap had a frame and extent to plan in);
* :func:`occupancy_to_pgm` / :func:`save_map` -- ROS map_saver's trinary
  export: a nav_msgs/OccupancyGrid-ordered grid (row 0 = smallest y, values
  -1 unknown, 0..100) becomes a P5 PGM with the first image row at the top:
  value >= occupied_thresh -> 0 (black), 0 <= value <= free_thresh -> 254
  (white), anything else (unknown or in between) -> 205 (grey); and a YAML
  with image, resolution, origin, negate 0, occupied_thresh 0.65,
  free_thresh 0.196 (map_saver's fixed values, what map_server reads back).

Grids are numpy int8 arrays ``grid[iy, ix]``; the origin is the map pose
(x [m], y [m], yaw [rad]) of the outer corner of cell (0, 0).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np

PGM_OCCUPIED = 0
PGM_FREE = 254
PGM_UNKNOWN = 205


def _finite(name: str, value, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if positive and value <= 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return value


def _origin(origin: Sequence[float], name: str = "origin") -> Tuple[float, float, float]:
    try:
        values = tuple(origin)
    except TypeError:
        raise ValueError(f"{name} must be [x m, y m, yaw rad], got {origin!r}") from None
    if len(values) != 3:
        raise ValueError(f"{name} must be [x m, y m, yaw rad], got {origin!r}")
    return tuple(_finite(f"{name}[{i}]", v) for i, v in enumerate(values))


@dataclass(frozen=True)
class EmptyMapConfig:
    """Size of the empty map served in GPS mode.

    width_m, height_m: extent along x / y [m] (default 100 x 100, enough for
    the farm around the datum); resolution: cell size [m] (map_server's 0.05);
    origin: (x m, y m, yaw rad) of the map's lower-left corner (default
    centred on the map frame's origin: (-50, -50, 0)).
    """

    width_m: float = 100.0
    height_m: float = 100.0
    resolution: float = 0.05
    origin: Tuple[float, float, float] = (-50.0, -50.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("width_m", "height_m", "resolution"):
            _finite(name, getattr(self, name), positive=True)
        object.__setattr__(self, "origin", _origin(self.origin))
        cells = (self.width_m / self.resolution) * (self.height_m / self.resolution)
        if cells > 1e8:
            raise ValueError(f"width_m / height_m / resolution give {cells:.3g} cells (at most 1e8)")


def empty_map(config: EmptyMapConfig = EmptyMapConfig()) -> Tuple[np.ndarray, float, Tuple[float, float, float]]:
    """A free map: (grid int8 of zeros [height, width], resolution [m], origin)."""
    width = max(1, int(round(config.width_m / config.resolution)))
    height = max(1, int(round(config.height_m / config.resolution)))
    return np.zeros((height, width), dtype=np.int8), float(config.resolution), config.origin


@dataclass(frozen=True)
class MapSaverConfig:
    """map_saver's thresholds on OccupancyGrid values [0..100].

    occupied_thresh: values >= this are written black (default 65);
    free_thresh: values in 0..this are written white (default 19.6).
    """

    occupied_thresh: float = 65.0
    free_thresh: float = 19.6

    def __post_init__(self) -> None:
        for name in ("occupied_thresh", "free_thresh"):
            value = _finite(name, getattr(self, name))
            if not 0.0 <= value <= 100.0:
                raise ValueError(f"{name} must lie in [0, 100], got {value}")
        if self.free_thresh >= self.occupied_thresh:
            raise ValueError(f"free_thresh ({self.free_thresh}) must be below occupied_thresh "
                             f"({self.occupied_thresh})")


def _check_grid(grid) -> np.ndarray:
    g = np.asarray(grid)
    if g.ndim != 2 or g.size == 0:
        raise ValueError(f"grid must be a non-empty 2-D array [height, width], got shape {g.shape}")
    if not np.issubdtype(g.dtype, np.integer):
        raise ValueError(f"grid must hold integers (-1 unknown, 0..100), got dtype {g.dtype}")
    return g.astype(np.int16)


def occupancy_to_pgm(grid, config: MapSaverConfig = MapSaverConfig()) -> np.ndarray:
    """OccupancyGrid-ordered grid -> uint8 image (row 0 = top of the map), trinary."""
    g = _check_grid(grid)
    img = np.full(g.shape, PGM_UNKNOWN, dtype=np.uint8)
    img[(g >= 0) & (g <= config.free_thresh)] = PGM_FREE
    img[g >= config.occupied_thresh] = PGM_OCCUPIED
    return img[::-1].copy()


def save_map(base_path: str, grid, resolution_m: float, origin: Sequence[float],
             config: MapSaverConfig = MapSaverConfig()) -> Tuple[str, str]:
    """Write ``<base_path>.pgm`` and ``<base_path>.yaml``; returns their paths.

    The YAML names the image by its file name (relative), as map_saver does.
    Raises ValueError for a bad grid, resolution or origin, and for a folder
    that does not exist.
    """
    resolution_m = _finite("resolution_m", resolution_m, positive=True)
    origin = _origin(origin)
    img = occupancy_to_pgm(grid, config)
    base_path = str(base_path)
    if base_path.endswith((".yaml", ".pgm")):
        base_path = os.path.splitext(base_path)[0]
    folder = os.path.dirname(os.path.abspath(base_path))
    if not os.path.isdir(folder):
        raise ValueError(f"cannot save the map: folder {folder} does not exist")
    pgm_path, yaml_path = base_path + ".pgm", base_path + ".yaml"
    height, width = img.shape
    with open(pgm_path, "wb") as fh:
        fh.write(f"P5\n# CREATOR: cottonsim map_saver {resolution_m:.3f} m/pix\n{width} {height}\n255\n"
                 .encode("ascii"))
        fh.write(img.tobytes())
    with open(yaml_path, "w") as fh:
        fh.write(f"image: {os.path.basename(pgm_path)}\n")
        fh.write(f"resolution: {resolution_m:.6f}\n")
        fh.write(f"origin: [{origin[0]:.6f}, {origin[1]:.6f}, {origin[2]:.6f}]\n")
        fh.write("negate: 0\n")
        fh.write("occupied_thresh: 0.65\n")
        fh.write("free_thresh: 0.196\n")
        fh.write("\n")
    return pgm_path, yaml_path
