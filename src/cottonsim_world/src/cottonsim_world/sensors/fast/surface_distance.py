"""How far apart two small meshes are: point-to-triangle distances and a sampled Hausdorff distance.

The levels of detail (``level_of_detail``) keep a simplified part only when
its surface stays within a tolerance of the full part; these numba kernels
measure that. Lengths in metres.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _point_triangle_d2(px, py, pz, tri, j):  # pragma: no cover - compiled
    """Squared distance of point p to triangle j of tri (T, 3, 3): the closest point by the triangle's
    Voronoi regions (vertex, edge or face; Ericson, Real-Time Collision Detection, 5.1.5)."""
    ax, ay, az = tri[j, 0, 0], tri[j, 0, 1], tri[j, 0, 2]
    abx, aby, abz = tri[j, 1, 0] - ax, tri[j, 1, 1] - ay, tri[j, 1, 2] - az
    acx, acy, acz = tri[j, 2, 0] - ax, tri[j, 2, 1] - ay, tri[j, 2, 2] - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    bpx, bpy, bpz = apx - abx, apy - aby, apz - abz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    cpx, cpy, cpz = apx - acx, apy - acy, apz - acz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    if d1 <= 0.0 and d2 <= 0.0:                                  # vertex a
        s, t = 0.0, 0.0
    elif d3 >= 0.0 and d4 <= d3:                                 # vertex b
        s, t = 1.0, 0.0
    elif d6 >= 0.0 and d5 <= d6:                                 # vertex c
        s, t = 0.0, 1.0
    elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:                  # edge ab
        s, t = d1 / (d1 - d3), 0.0
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:                  # edge ac
        s, t = 0.0, d2 / (d2 - d6)
    elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:    # edge bc
        u = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        s, t = 1.0 - u, u
    else:                                                        # inside
        den = va + vb + vc
        if den == 0.0:                                           # degenerate: its first corner
            s, t = 0.0, 0.0
        else:
            s, t = vb / den, vc / den
    dx = apx - s * abx - t * acx
    dy = apy - s * aby - t * acy
    dz = apz - s * abz - t * acz
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, nogil=True)
def point_mesh_distance(points, tri):  # pragma: no cover - compiled
    """Distance of each point (N, 3) to the nearest of the triangles tri (T, 3, 3) [m]: (N,)."""
    out = np.empty(points.shape[0])
    for i in range(points.shape[0]):
        best = np.inf
        for j in range(tri.shape[0]):
            best = min(best, _point_triangle_d2(points[i, 0], points[i, 1], points[i, 2], tri, j))
        out[i] = math.sqrt(best)
    return out


_SAMPLE_STEPS = 3          # a face is sampled at the barycentric grid (i / 3, j / 3), i + j <= 3: 10 points


@njit(cache=True, nogil=True)
def _directed_surface_distance(tri_a, tri_b):  # pragma: no cover - compiled
    """Largest distance from the sample points of triangles tri_a (A, 3, 3) to the surface tri_b [m]."""
    worst = 0.0
    n = _SAMPLE_STEPS
    for k in range(tri_a.shape[0]):
        for i in range(n + 1):
            for j in range(n + 1 - i):
                s, t = i / n, j / n
                px = tri_a[k, 0, 0] + s * (tri_a[k, 1, 0] - tri_a[k, 0, 0]) + t * (tri_a[k, 2, 0] - tri_a[k, 0, 0])
                py = tri_a[k, 0, 1] + s * (tri_a[k, 1, 1] - tri_a[k, 0, 1]) + t * (tri_a[k, 2, 1] - tri_a[k, 0, 1])
                pz = tri_a[k, 0, 2] + s * (tri_a[k, 1, 2] - tri_a[k, 0, 2]) + t * (tri_a[k, 2, 2] - tri_a[k, 0, 2])
                best = np.inf
                for m in range(tri_b.shape[0]):
                    best = min(best, _point_triangle_d2(px, py, pz, tri_b, m))
                    if best <= worst * worst:                    # cannot raise the maximum
                        break
                worst = max(worst, math.sqrt(best))
    return worst


def surface_distance(va: np.ndarray, fa: np.ndarray, vb: np.ndarray, fb: np.ndarray) -> float:
    """Symmetric Hausdorff distance of two small meshes [m], estimated on a grid of 10 points per face.

    If every point of one surface is within d of the other and back, their
    outlines seen from any camera are within d too (d f / z pixels at depth z).
    """
    ta = np.ascontiguousarray(va[fa], dtype=np.float64)
    tb = np.ascontiguousarray(vb[fb], dtype=np.float64)
    return float(max(_directed_surface_distance(ta, tb), _directed_surface_distance(tb, ta)))
