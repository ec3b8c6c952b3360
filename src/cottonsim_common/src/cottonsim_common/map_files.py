"""Occupancy map files as ROS map_server / map_saver use them: reading, writing, an empty map.

Debian has no map_server package, so our map_server, map_saver, the farm's
ground-truth export and the tests all read and write maps through here.

* :func:`load_map_yaml` -- a map_server YAML + image (PGM P5/P2 natively,
  other formats through OpenCV; modes trinary and scale) -> grid;
* :func:`save_map` -- map_saver's trinary export: value >= occupied_thresh
  -> 0 (black), 0 <= value <= free_thresh -> 254 (white), anything else
  (unknown or in between) -> 205 (grey); a YAML with image, resolution,
  origin, negate 0 and the thresholds (map_saver's 0.65 / 0.196 by default);
* :func:`empty_map` -- a free map of a given size (GPS mode serves one so the
  global costmap has a frame and extent to plan in).

Grids in memory follow nav_msgs/OccupancyGrid: numpy int8 ``grid[iy, ix]``
with row 0 at the origin (smallest y), values -1 unknown, 0..100. The image's
first row is the map's top (largest y). The origin is the map pose
(x [m], y [m], yaw [rad]) of the outer corner of cell (0, 0).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import List, Sequence, Tuple

import numpy as np

from cottonsim_common.validation import require_finite_values, require_number, require_positive

PGM_OCCUPIED = 0
PGM_FREE = 254
PGM_UNKNOWN = 205


def _origin(origin: Sequence[float], name: str = "origin") -> Tuple[float, float, float]:
    return require_finite_values(f"{name} [x m, y m, yaw rad]", origin, 3)


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
            require_positive(name, getattr(self, name))
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
            require_number(name, getattr(self, name), 0.0, 100.0)
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
             config: MapSaverConfig = MapSaverConfig(), creator: str = "cottonsim map_saver") -> Tuple[str, str]:
    """Write ``<base_path>.pgm`` and ``<base_path>.yaml``; returns their paths.

    The YAML names the image by its file name (relative), as map_saver does,
    and carries the config's thresholds as fractions (65 -> 0.65). Raises
    ValueError for a bad grid, resolution or origin, and for a folder that
    does not exist.
    """
    resolution_m = require_positive("resolution_m", resolution_m)
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
        fh.write(f"P5\n# CREATOR: {creator} {resolution_m:.3f} m/pix\n{width} {height}\n255\n".encode("ascii"))
        fh.write(img.tobytes())
    with open(yaml_path, "w") as fh:
        fh.write(f"image: {os.path.basename(pgm_path)}\n")
        fh.write(f"resolution: {resolution_m:.6f}\n")
        fh.write(f"origin: [{origin[0]:.6f}, {origin[1]:.6f}, {origin[2]:.6f}]\n")
        fh.write("negate: 0\n")
        fh.write(f"occupied_thresh: {config.occupied_thresh / 100.0:.6g}\n")
        fh.write(f"free_thresh: {config.free_thresh / 100.0:.6g}\n")
        fh.write("\n")
    return pgm_path, yaml_path


def _read_pgm(path: str) -> np.ndarray:
    with open(path, "rb") as fh:
        data = fh.read()
    if data[:2] not in (b"P5", b"P2"):
        raise ValueError(f"{path}: not a PGM file (magic {data[:2]!r}, expected P5 or P2)")
    # header: magic, width, height, maxval, separated by whitespace / comments
    tokens: List[bytes] = []
    pos = 2
    while len(tokens) < 3:
        while pos < len(data) and data[pos:pos + 1].isspace():
            pos += 1
        if pos >= len(data):
            raise ValueError(f"{path}: truncated PGM header")
        if data[pos:pos + 1] == b"#":
            while pos < len(data) and data[pos:pos + 1] not in (b"\n", b"\r"):
                pos += 1
            continue
        start = pos
        while pos < len(data) and not data[pos:pos + 1].isspace():
            pos += 1
        tokens.append(data[start:pos])
    try:
        width, height, maxval = (int(t) for t in tokens)
    except ValueError:
        raise ValueError(f"{path}: bad PGM header {tokens!r}") from None
    if width <= 0 or height <= 0 or not 0 < maxval < 65536:
        raise ValueError(f"{path}: bad PGM size or maxval ({width}x{height}, maxval {maxval})")
    if data[:2] == b"P5":
        pos += 1                                              # single whitespace after maxval
        dtype = np.uint8 if maxval < 256 else np.dtype(">u2")
        need = width * height * np.dtype(dtype).itemsize
        if len(data) - pos < need:
            raise ValueError(f"{path}: PGM pixel data truncated ({len(data) - pos} of {need} bytes)")
        img = np.frombuffer(data, dtype=dtype, count=width * height, offset=pos).reshape(height, width)
    else:
        values = data[pos:].split()
        if len(values) < width * height:
            raise ValueError(f"{path}: PGM pixel data truncated ({len(values)} of {width * height} values)")
        img = np.array([int(v) for v in values[:width * height]]).reshape(height, width)
    return (img.astype(float) * (255.0 / maxval)).round().astype(np.uint8)


def load_map_yaml(path: str):
    """Load a map_server map (YAML + image) into an occupancy grid.

    Returns (grid int8 [iy, ix] with -1 unknown / 0 free / 100 occupied, row 0
    at the origin i.e. the map's bottom; resolution_m; origin (x, y, yaw)).
    Supports PGM (P5/P2) natively and other image formats through OpenCV;
    modes trinary (default) and scale (intermediate values 1..99).
    Raises ValueError naming the problem for a missing / malformed file.
    """
    from cottonsim_common.config.yaml_files import load_yaml_file

    if not os.path.isfile(path):
        raise ValueError(f"map YAML not found: {path}")
    meta = load_yaml_file(path)
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: expected a mapping with image, resolution, origin")
    for key in ("image", "resolution", "origin"):
        if key not in meta:
            raise ValueError(f"{path}: missing key '{key}'")
    try:
        res = float(meta["resolution"])
        origin = tuple(float(v) for v in meta["origin"])
        negate = int(meta.get("negate", 0))
        occ_t = float(meta.get("occupied_thresh", 0.65))
        free_t = float(meta.get("free_thresh", 0.196))
    except (TypeError, ValueError):
        raise ValueError(f"{path}: resolution, origin, negate and thresholds must be numbers") from None
    if not (math.isfinite(res) and res > 0):
        raise ValueError(f"{path}: resolution must be > 0, got {meta['resolution']!r}")
    if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
        raise ValueError(f"{path}: origin must be [x, y, yaw], got {meta['origin']!r}")
    mode = str(meta.get("mode", "trinary"))
    if mode not in ("trinary", "scale"):
        raise ValueError(f"{path}: unsupported mode {mode!r} (trinary or scale)")
    image_path = str(meta["image"])
    if not os.path.isabs(image_path):
        image_path = os.path.join(os.path.dirname(os.path.abspath(path)), image_path)
    if not os.path.isfile(image_path):
        raise ValueError(f"{path}: image file not found: {image_path}")
    if image_path.lower().endswith(".pgm"):
        img = _read_pgm(image_path)
    else:
        import cv2
        img = cv2.imread(image_path, cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise ValueError(f"{path}: cannot read image {image_path}")
    p = img.astype(float) / 255.0 if negate else (255.0 - img.astype(float)) / 255.0
    grid = np.full(img.shape, -1, dtype=np.int8)
    grid[p > occ_t] = 100
    grid[p < free_t] = 0
    if mode == "scale":
        mid = (p >= free_t) & (p <= occ_t)
        grid[mid] = np.clip(np.round(99.0 * (p[mid] - free_t) / (occ_t - free_t)), 1, 99).astype(np.int8)
    return grid[::-1].copy(), res, origin
