"""Planar geometry used by costmaps and planners.

Angles in radians, positions in metres. Poses are :class:`Pose2D` (x, y, yaw)
in some fixed frame; footprints are (N, 2) polygons in the robot frame
(base_link: x forward, y left), given counter-clockwise or clockwise.
Functions accept numpy arrays wherever a scalar angle makes sense.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence, Tuple

import numpy as np


@dataclass(frozen=True)
class Pose2D:
    """A planar pose: position [m] and heading [rad] (counter-clockwise from +x).

    Field names match ``cottonsim_world.farm.model.Pose2D`` so either can be
    passed to the planners (they only read x_m, y_m, yaw_rad).
    """

    x_m: float
    y_m: float
    yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "yaw_rad"):
            value = getattr(self, name)
            try:
                ok = math.isfinite(float(value))
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(f"Pose2D.{name} must be a finite number, got {value!r}")

    def as_array(self) -> np.ndarray:
        return np.array([self.x_m, self.y_m, self.yaw_rad], dtype=float)


def as_pose(p) -> Pose2D:
    """Any object with x_m/y_m/yaw_rad (or a 3-sequence) -> Pose2D (validated)."""
    if isinstance(p, Pose2D):
        return p
    if hasattr(p, "x_m") and hasattr(p, "y_m"):
        return Pose2D(float(p.x_m), float(p.y_m), float(getattr(p, "yaw_rad", 0.0)))
    seq = list(p)
    if len(seq) not in (2, 3):
        raise ValueError(f"a pose needs (x, y[, yaw]), got {len(seq)} values")
    return Pose2D(float(seq[0]), float(seq[1]), float(seq[2]) if len(seq) == 3 else 0.0)


# --- angles -------------------------------------------------------------------
def normalize_angle(a):
    """Wrap angles [rad] to [-pi, pi); scalars stay floats, arrays stay arrays."""
    if np.ndim(a) == 0:
        return (float(a) + math.pi) % (2.0 * math.pi) - math.pi
    return (np.asarray(a, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def shortest_angular_distance(from_rad, to_rad):
    """Signed smallest rotation [rad] taking ``from_rad`` to ``to_rad`` (like angles::)."""
    if np.ndim(from_rad) == 0 and np.ndim(to_rad) == 0:
        return normalize_angle(float(to_rad) - float(from_rad))
    return normalize_angle(np.asarray(to_rad, dtype=float) - np.asarray(from_rad, dtype=float))


def yaw_to_quaternion(yaw_rad: float) -> Tuple[float, float, float, float]:
    """A rotation about z as a quaternion (x, y, z, w)."""
    h = 0.5 * float(yaw_rad)
    return (0.0, 0.0, math.sin(h), math.cos(h))


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """Yaw [rad] of a quaternion (x, y, z, w); roll and pitch are ignored.

    Raises ValueError for a zero-length or non-finite quaternion.
    """
    vals = (x, y, z, w)
    if not all(math.isfinite(v) for v in vals):
        raise ValueError(f"quaternion has non-finite components: {vals}")
    n = math.sqrt(sum(v * v for v in vals))
    if n < 1e-12:
        raise ValueError("quaternion has zero length")
    x, y, z, w = (v / n for v in vals)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


# --- pose algebra -------------------------------------------------------------
def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """a (+) b: pose b given in frame a, expressed in a's parent frame."""
    c, s = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    return Pose2D(a.x_m + c * b.x_m - s * b.y_m, a.y_m + s * b.x_m + c * b.y_m,
                  normalize_angle(a.yaw_rad + b.yaw_rad))


def inverse(a: Pose2D) -> Pose2D:
    """The pose p with compose(a, p) == identity."""
    c, s = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    return Pose2D(-c * a.x_m - s * a.y_m, s * a.x_m - c * a.y_m, normalize_angle(-a.yaw_rad))


def transform_points(pose: Pose2D, points: np.ndarray) -> np.ndarray:
    """(N, 2) points in the pose's frame -> parent frame."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    out = np.empty_like(pts)
    out[:, 0] = pose.x_m + c * pts[:, 0] - s * pts[:, 1]
    out[:, 1] = pose.y_m + s * pts[:, 0] + c * pts[:, 1]
    return out


# --- footprints ----------------------------------------------------------------
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
