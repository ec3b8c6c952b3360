"""Robot footprints on a grid, for costmaps and planners.

Angles in radians, positions in metres. Footprints are (N, 2) polygons in the
robot frame (base_link: x forward, y left), given counter-clockwise or
clockwise. The pose algebra, angle wrap and quaternions live in
cottonsim_common (``pose``, ``angles``, ``transforms``).
"""
from __future__ import annotations

import math
from typing import Tuple

import numpy as np

from cottonsim_common.pose import Pose2D, transform_points


def rectangle_footprint(length_m: float, width_m: float, centre_x_m: float = 0.0) -> np.ndarray:
    """Corners (4, 2) of a length x width rectangle around (centre_x_m, 0), counter-clockwise."""
    if not (length_m > 0 and width_m > 0):
        raise ValueError(f"footprint length_m and width_m must be > 0, got {length_m}, {width_m}")
    hl, hw = 0.5 * length_m, 0.5 * width_m
    return np.array([[centre_x_m + hl, hw], [centre_x_m - hl, hw],
                     [centre_x_m - hl, -hw], [centre_x_m + hl, -hw]], dtype=float)


def validate_footprint(footprint) -> np.ndarray:
    """(N >= 3, 2) finite polygon or ValueError naming 'footprint'."""
    fp = np.asarray(footprint, dtype=float)
    if fp.ndim != 2 or fp.shape[1] != 2 or fp.shape[0] < 3:
        raise ValueError(f"footprint must be a list of >= 3 [x, y] points, got shape {fp.shape}")
    if not np.all(np.isfinite(fp)):
        raise ValueError("footprint contains non-finite coordinates")
    return fp


def pad_footprint(footprint, padding_m: float) -> np.ndarray:
    """Grow each vertex away from the origin by ``padding_m`` in x and y.

    This is costmap_2d's padFootprint: each coordinate moves by the padding
    in the direction of its sign (a rectangle grows by 2 * padding per side).
    """
    fp = validate_footprint(footprint).copy()
    fp += np.sign(fp) * float(padding_m)
    return fp


def _point_segment_distance(px: float, py: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    L2 = np.sum(d * d, axis=1)
    t = np.where(L2 > 0, ((px - a[:, 0]) * d[:, 0] + (py - a[:, 1]) * d[:, 1]) / np.where(L2 > 0, L2, 1), 0.0)
    t = np.clip(t, 0.0, 1.0)
    cx = a[:, 0] + t * d[:, 0]
    cy = a[:, 1] + t * d[:, 1]
    return np.hypot(px - cx, py - cy)


def footprint_radii(footprint) -> Tuple[float, float]:
    """(inscribed, circumscribed) radius [m] about the robot origin, like costmap_2d.

    Inscribed: the smallest distance from the origin to an edge;
    circumscribed: the largest distance to a vertex.
    """
    fp = validate_footprint(footprint)
    a = fp
    b = np.roll(fp, -1, axis=0)
    inscribed = float(np.min(_point_segment_distance(0.0, 0.0, a, b)))
    circumscribed = float(np.max(np.hypot(fp[:, 0], fp[:, 1])))
    return inscribed, circumscribed


def footprint_outline_points(footprint, spacing_m: float) -> np.ndarray:
    """Points (M, 2) along the closed polygon outline, at most ``spacing_m`` apart."""
    fp = validate_footprint(footprint)
    if spacing_m <= 0:
        raise ValueError(f"spacing_m must be > 0, got {spacing_m}")
    pts = []
    for i in range(len(fp)):
        a, b = fp[i], fp[(i + 1) % len(fp)]
        n = max(1, int(math.ceil(np.hypot(*(b - a)) / spacing_m)))
        t = np.arange(n)[:, None] / n
        pts.append(a + t * (b - a))
    return np.vstack(pts)


def points_in_polygon(px: np.ndarray, py: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd test: which points (px, py) lie inside the polygon (vectorised)."""
    px = np.asarray(px, dtype=float)
    py = np.asarray(py, dtype=float)
    inside = np.zeros(px.shape, dtype=bool)
    poly = validate_footprint(polygon)
    n = len(poly)
    for i in range(n):
        x1, y1 = poly[i]
        x2, y2 = poly[(i + 1) % n]
        crosses = (y1 > py) != (y2 > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            xint = x1 + (py - y1) * (x2 - x1) / (y2 - y1)
        inside ^= crosses & (px < xint)
    return inside


def footprint_cells(spec, pose: Pose2D, footprint) -> Tuple[np.ndarray, np.ndarray]:
    """Cells (mx, my) covered by the footprint placed at ``pose`` on grid ``spec``.

    A cell counts when its centre lies inside the polygon, plus every cell the
    outline passes through (so thin footprints still cover a cell). Cells off
    the grid are dropped.
    """
    world = transform_points(pose, validate_footprint(footprint))
    xmin, ymin = world.min(axis=0)
    xmax, ymax = world.max(axis=0)
    mx0, my0 = spec.world_to_map(xmin, ymin)
    mx1, my1 = spec.world_to_map(xmax, ymax)
    mxs = np.arange(int(mx0), int(mx1) + 1)
    mys = np.arange(int(my0), int(my1) + 1)
    gx, gy = np.meshgrid(mxs, mys)
    cx, cy = spec.map_to_world(gx, gy)
    inside = points_in_polygon(cx, cy, world)
    cells = set(zip(gx[inside].tolist(), gy[inside].tolist()))
    outline = footprint_outline_points(world, 0.5 * spec.resolution_m)
    omx, omy = spec.world_to_map(outline[:, 0], outline[:, 1])
    cells.update(zip(omx.tolist(), omy.tolist()))
    if not cells:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    arr = np.array(sorted(cells), dtype=np.int64)
    keep = spec.in_bounds(arr[:, 0], arr[:, 1])
    return arr[keep, 0], arr[keep, 1]
