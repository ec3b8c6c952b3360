"""The DWA planner's trajectories: exact unicycle arcs of velocity samples and what they cost on a costmap.

Used by ``dwa.DWAPlanner`` (steps 4 and 5 of its cycle): all samples are
simulated at once with numpy; the footprint scan along them is a small
compiled (numba) loop. A trajectory collides when any pose has a LETHAL or
NO_INFORMATION cell under its footprint outline, an INSCRIBED-or-worse cell
under its centre (base_local_planner's CostmapModel rules), or leaves the
costmap. Distances in metres, angles in radians.
"""
from __future__ import annotations

from typing import Tuple

import numpy as np
from scipy import ndimage

from cottonsim_navigation.core.footprint import footprint_outline_points
from cottonsim_navigation.core.grid import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION

try:
    from numba import njit
except ImportError as exc:  # pragma: no cover
    raise ImportError("the DWA planner needs numba (pip install numba)") from exc


def simulate_arcs(x: float, y: float, yaw: float, v: np.ndarray, w: np.ndarray, t: np.ndarray
                  ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact unicycle poses for constant (v[s], w[s]) at times t[k]: arrays (S, K)."""
    v = np.asarray(v, dtype=float)[:, None]
    w = np.asarray(w, dtype=float)[:, None]
    t = np.asarray(t, dtype=float)[None, :]
    th = yaw + w * t
    small = np.abs(w) < 1e-9
    wsafe = np.where(small, 1.0, w)
    xs = np.where(small, x + v * t * np.cos(yaw), x + v / wsafe * (np.sin(th) - np.sin(yaw)))
    ys = np.where(small, y + v * t * np.sin(yaw), y - v / wsafe * (np.cos(th) - np.cos(yaw)))
    return xs, ys, np.broadcast_to(th, xs.shape)


def polyline_distance(qx: np.ndarray, qy: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Exact distance [m] of each query point (S,) to the polyline ``poly`` (K, 2)."""
    if len(poly) == 1:
        return np.hypot(qx - poly[0, 0], qy - poly[0, 1])
    a = poly[:-1]
    ab = poly[1:] - a
    l2 = np.einsum("ij,ij->i", ab, ab)
    l2 = np.where(l2 > 0.0, l2, 1.0)
    rx = qx[:, None] - a[None, :, 0]
    ry = qy[:, None] - a[None, :, 1]
    t = np.clip((rx * ab[None, :, 0] + ry * ab[None, :, 1]) / l2[None, :], 0.0, 1.0)
    dx = rx - t * ab[None, :, 0]
    dy = ry - t * ab[None, :, 1]
    return np.sqrt(np.min(dx * dx + dy * dy, axis=1))


def distance_fields(spec, local):
    """Euclidean distance [m] of every cell to the local plan and to the local goal."""
    res = spec.resolution_m
    pmx, pmy = spec.world_to_map(local[:, 0], local[:, 1])
    mask = np.ones(spec.shape, dtype=bool)
    mask[pmy, pmx] = False
    path_d = ndimage.distance_transform_edt(mask) * res
    gmask = np.ones(spec.shape, dtype=bool)
    gmask[pmy[-1], pmx[-1]] = False
    goal_d = ndimage.distance_transform_edt(gmask) * res
    return path_d, goal_d


@njit(cache=True, nogil=True)
def _scan_trajectories(costs, ox, oy, res, xs, ys, ths, outline):
    """Per trajectory: (collides, highest footprint cost) over all its poses.

    costs: (H, W) uint8 grid with origin (ox, oy) [m] and cell size res [m];
    xs, ys, ths: (S, K) poses; outline: (M, 2) footprint outline points in the
    robot frame. Rules as in the module docstring; a trajectory stops being
    scanned at its first colliding pose.
    """
    h, w = costs.shape
    S, K = xs.shape
    M = outline.shape[0]
    collide = np.zeros(S, dtype=np.bool_)
    occ = np.zeros(S)
    for s in range(S):
        worst = 0
        bad = False
        for k in range(K):
            x = xs[s, k]
            y = ys[s, k]
            mx = int(np.floor((x - ox) / res))
            my = int(np.floor((y - oy) / res))
            if mx < 0 or mx >= w or my < 0 or my >= h or costs[my, mx] >= INSCRIBED_INFLATED_OBSTACLE:
                bad = True
                break
            cc = costs[my, mx]
            if cc > worst:
                worst = cc
            c = np.cos(ths[s, k])
            si = np.sin(ths[s, k])
            for m in range(M):
                px = x + c * outline[m, 0] - si * outline[m, 1]
                py = y + si * outline[m, 0] + c * outline[m, 1]
                mx = int(np.floor((px - ox) / res))
                my = int(np.floor((py - oy) / res))
                if mx < 0 or mx >= w or my < 0 or my >= h:
                    bad = True
                    break
                cc = costs[my, mx]
                if cc == LETHAL_OBSTACLE or cc == NO_INFORMATION:
                    bad = True
                    break
                if cc > worst:
                    worst = cc
            if bad:
                break
        collide[s] = bad
        occ[s] = worst
    return collide, occ


def footprint_collides(costmap, xs, ys, ths, return_cost: bool = False):
    """Collision flags (S,) and highest footprint cost (S,) of trajectories (S, K) of poses."""
    spec = costmap.spec
    outline = footprint_outline_points(np.asarray(costmap.footprint, dtype=float), spec.resolution_m)
    collide, occ = _scan_trajectories(np.ascontiguousarray(costmap.costs, dtype=np.uint8),
                                      float(spec.origin_x_m), float(spec.origin_y_m), float(spec.resolution_m),
                                      np.ascontiguousarray(xs, dtype=float), np.ascontiguousarray(ys, dtype=float),
                                      np.ascontiguousarray(ths, dtype=float), outline)
    if return_cost:
        return collide, occ
    return collide
