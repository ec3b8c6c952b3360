"""Crop an occupancy grid to the part that was observed, plus a margin.

Why: a SLAM map is allocated over a large extent (gmapping's +/-100 m) or in
coarse tiles; the saved map that ships with the package and that AMCL and
move_base load should hold only the farm and its surroundings, so the image
stays small and the costmaps stay cheap.
"""
from __future__ import annotations

import math
from typing import Sequence, Tuple

import numpy as np


def crop_to_known(grid, resolution_m: float, origin: Sequence[float],
                  margin_m: float = 1.0) -> Tuple[np.ndarray, Tuple[float, float, float]]:
    """The bounding box of the known cells (value != -1) of ``grid`` grown by ``margin_m``, clipped to the grid.

    grid: OccupancyGrid values [iy, ix], row 0 at the origin; origin: (x_m, y_m, yaw_rad) of cell (0, 0)'s
    corner. Returns (cropped grid, its origin). A yawed origin is handled (the crop is in the grid's axes).
    Raises ValueError for a grid without known cells or bad numbers.
    """
    g = np.asarray(grid)
    if g.ndim != 2 or g.size == 0:
        raise ValueError(f"grid must be a non-empty 2-D array, got shape {g.shape}")
    if isinstance(resolution_m, bool) or not isinstance(resolution_m, (int, float)) \
            or not math.isfinite(resolution_m) or resolution_m <= 0:
        raise ValueError(f"resolution_m must be a finite number > 0, got {resolution_m!r}")
    if isinstance(margin_m, bool) or not isinstance(margin_m, (int, float)) or not math.isfinite(margin_m) \
            or margin_m < 0:
        raise ValueError(f"margin_m must be a finite number >= 0, got {margin_m!r}")
    try:
        ox, oy, oyaw = (float(v) for v in origin)
    except (TypeError, ValueError):
        raise ValueError(f"origin must be (x_m, y_m, yaw_rad), got {origin!r}") from None
    if not all(math.isfinite(v) for v in (ox, oy, oyaw)):
        raise ValueError(f"origin must be finite, got {origin!r}")
    rows = np.flatnonzero((g != -1).any(axis=1))
    cols = np.flatnonzero((g != -1).any(axis=0))
    if rows.size == 0:
        raise ValueError("the grid has no known cells")
    m = int(math.ceil(margin_m / resolution_m))
    r0, r1 = max(rows[0] - m, 0), min(rows[-1] + m, g.shape[0] - 1)
    c0, c1 = max(cols[0] - m, 0), min(cols[-1] + m, g.shape[1] - 1)
    c, s = math.cos(oyaw), math.sin(oyaw)
    dx, dy = c0 * resolution_m, r0 * resolution_m
    new_origin = (ox + c * dx - s * dy, oy + s * dx + c * dy, oyaw)
    return g[r0:r1 + 1, c0:c1 + 1].copy(), new_origin
