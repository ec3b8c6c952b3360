"""Levels of detail of a plant model for the numba camera: simplified and proxy meshes.

Why: a plant 20 m from the camera covers a few hundred pixels, but its full
model has thousands of triangles. ``instanced_plants.InstancedPlants`` draws
far plants with fewer triangles, made here from the full model:

``simplified_model_arrays``
    every part (a leaf, bract, boll or tube, found as a connected set of
    faces) in its fewest-face version whose surface stays within a
    tolerance of the full part (``part_levels``: fan decimations of leaf
    outlines and ellipsoid proxies, measured by a sampled two-sided surface
    distance, ``_surface_distance``);
``proxy_model_arrays``
    each part replaced by a few triangles of the same area, for plants far
    enough that a part is only a few pixels.

Frames: plant-local as in ``farm.model`` [m].
"""
from __future__ import annotations

import collections
import hashlib
import math
import threading
from typing import Dict, List, Optional, Tuple

import numpy as np
from numba import njit

from cottonsim_world.farm.model import PlantModel


def _model_arrays(model: PlantModel) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One model's meshes merged: vertices, faces, face semantic, face rgb, face unit normal."""
    verts, faces, sem, rgb = [], [], [], []
    offset = 0
    for mesh in model.meshes.values():
        v = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
        if len(f) == 0:
            continue
        verts.append(v)
        faces.append(f + offset)
        sem.append(np.full(len(f), int(mesh.semantic), dtype=np.uint8))
        rgb.append(np.tile(np.asarray(mesh.rgba[:3], dtype=np.float64), (len(f), 1)))
        offset += len(v)
    if not faces:
        return (np.zeros((0, 3)), np.zeros((0, 3), np.int32), np.zeros(0, np.uint8), np.zeros((0, 3)),
                np.zeros((0, 3)))
    v = np.concatenate(verts)
    f = np.concatenate(faces)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 0.0, n / np.maximum(length, 1e-300), 0.0)
    return v, f.astype(np.int32), np.concatenate(sem), np.concatenate(rgb), n


def _hull_area(points: np.ndarray) -> float:
    """Surface area of the convex hull of 3-D points [m^2]; 0 if they are (nearly) coplanar or too few."""
    from scipy.spatial import ConvexHull, QhullError

    if len(points) < 4:
        return 0.0
    try:
        return float(ConvexHull(points).area)
    except (QhullError, ValueError):
        return 0.0


def _octahedron_faces() -> np.ndarray:
    """Faces of an octahedron with vertices +a0, -a0, +a1, -a1, +a2, -a2 (indices 0..5)."""
    out = []
    for sx in (0, 1):
        for sy in (2, 3):
            for sz in (4, 5):
                out.append((sx, sy, sz))
    return np.array(out, dtype=np.int64)


def _mesh_parts(v: np.ndarray, f: np.ndarray) -> Tuple[int, np.ndarray]:
    """Connected components of a mesh: (count, part label per face)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(v)
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    n_parts, label = connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)),
                                          directed=False)
    return n_parts, label[f[:, 0]]


def _split_parts(v: np.ndarray, f: np.ndarray):
    """Each connected part of a mesh, in label order: (its face indices, its vertices, its faces indexing
    those vertices, its surface area [m^2])."""
    n_parts, face_part = _mesh_parts(v, f)
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    face_area = 0.5 * np.linalg.norm(cross, axis=1)
    for part in range(n_parts):
        fi = np.nonzero(face_part == part)[0]
        if len(fi) == 0:
            continue
        vi = np.unique(f[fi])
        remap = np.full(len(v), -1, dtype=np.int64)
        remap[vi] = np.arange(len(vi))
        yield fi, v[vi], remap[f[fi]], float(face_area[fi].sum())


def _wind_outward(corners: np.ndarray, faces: np.ndarray, centre: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """(corners, faces) with every face of a closed proxy around ``centre`` counter-clockwise seen from outside."""
    nrm = np.cross(corners[faces[:, 1]] - corners[faces[:, 0]], corners[faces[:, 2]] - corners[faces[:, 0]])
    outward = np.einsum("ij,ij->i", nrm, corners[faces].mean(axis=1) - centre) > 0.0
    return corners, np.where(outward[:, None], faces, faces[:, ::-1])


def _assemble_parts(parts, sem: np.ndarray, rgb: np.ndarray) -> Tuple[np.ndarray, ...]:
    """One model from (vertices, faces, first face of the source part) per part: the five arrays of
    ``_model_arrays``, each part with the semantic class and base colour of its source part's first face."""
    out_v, out_f, out_sem, out_rgb = [], [], [], []
    count = 0
    for pv, pf, face0 in parts:
        out_v.append(pv)
        out_f.append(pf + count)
        out_sem.append(np.full(len(pf), sem[face0], dtype=np.uint8))
        out_rgb.append(np.tile(rgb[face0], (len(pf), 1)))
        count += len(pv)
    return _with_normals(np.concatenate(out_v), np.concatenate(out_f), np.concatenate(out_sem),
                         np.concatenate(out_rgb))


def _part_proxy(pts: np.ndarray, part_faces: np.ndarray, area: float, flat_ratio: float, thin_ratio: float
                ) -> Tuple[Optional[Tuple[np.ndarray, np.ndarray]], float]:
    """The far proxy of one part (see ``proxy_model_arrays``): ((corners, faces) or None, outline error bound [m]).

    pts: the part's vertices; part_faces: its faces indexing ``pts``; area:
    its surface area [m^2].
    """
    centre = pts.mean(axis=0)
    lam, axes = np.linalg.eigh(np.cov((pts - centre).T) if len(pts) > 1 else np.zeros((3, 3)))
    lam = np.maximum(lam[::-1], 0.0)                  # descending
    axes = axes[:, ::-1]
    hull_area = _hull_area(pts)
    proxy = None
    error_m = 0.0
    if lam[0] > 0.0 and lam[1] < thin_ratio * lam[0]:
        along = (pts - centre) @ axes[:, 0]
        lo, hi = float(along.min()), float(along.max())
        if hi - lo > 0.0:
            side = area / (3.0 * (hi - lo))                  # lateral area 3 * side * length
            circ = side / math.sqrt(3.0)                     # circumradius of the cross-section
            ring = [circ * (math.cos(a) * axes[:, 1] + math.sin(a) * axes[:, 2])
                    for a in (0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0)]
            ends = [centre + lo * axes[:, 0], centre + hi * axes[:, 0]]
            corners = np.array([ends[e] + ring[j] for e in (0, 1) for j in range(3)])
            faces = []
            for j in range(3):
                a, b = j, (j + 1) % 3
                faces += [(a, b, b + 3), (a, b + 3, a + 3)]
            faces = np.array(faces, dtype=np.int64)
            nrm = np.cross(corners[faces[:, 1]] - corners[faces[:, 0]],
                           corners[faces[:, 2]] - corners[faces[:, 0]])
            mid = corners[faces].mean(axis=1)
            radial = (mid - centre) - np.outer((mid - centre) @ axes[:, 0], axes[:, 0])
            outward = np.einsum("ij,ij->i", nrm, radial) > 0.0
            proxy = corners, np.where(outward[:, None], faces, faces[:, ::-1])
            off_axis = (pts - centre) - np.outer(along, axes[:, 0])
            error_m = 2.0 * float(np.linalg.norm(off_axis, axis=1).max()) + circ
    elif lam[0] > 0.0:
        _, twin = _pair_reversed_faces(part_faces)
        two_sided = np.count_nonzero(twin >= 0) * 2 == len(part_faces)
        if lam[2] < flat_ratio * lam[1]:
            if two_sided:
                one_sided = 0.5 * hull_area if hull_area > 0.0 else 0.5 * area
                k = math.sqrt(one_sided / (4.0 * math.sqrt(lam[0] * lam[1])))
                a0, a1 = k * math.sqrt(lam[0]) * axes[:, 0], k * math.sqrt(lam[1]) * axes[:, 1]
                corners = np.array([centre - a0 - a1, centre + a0 - a1, centre + a0 + a1, centre - a0 + a1])
                quad = np.array([(0, 1, 2), (0, 2, 3)], dtype=np.int64)
                proxy = corners, np.concatenate([quad, quad[:, ::-1]])
        elif lam[2] > 0.0:
            surface = hull_area if hull_area > 0.0 else area
            k = math.sqrt(surface / (4.0 * math.sqrt(lam[0] * lam[1] + lam[1] * lam[2] + lam[0] * lam[2])))
            half = [k * math.sqrt(lam[a]) * axes[:, a] for a in range(3)]
            corners = np.array([centre + half[0], centre - half[0], centre + half[1], centre - half[1],
                                centre + half[2], centre - half[2]])
            proxy = _wind_outward(corners, _octahedron_faces(), centre)
        if proxy is not None:
            error_m = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    return proxy, error_m


def proxy_model_arrays(v: np.ndarray, f: np.ndarray, sem: np.ndarray, rgb: np.ndarray,
                       flat_ratio: float = 0.05, thin_ratio: float = 0.1
                       ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Far level of detail of one model: each small part replaced by a few triangles of the same area.

    Parts are the connected components of the mesh (a leaf, a bract, a
    boll, a branch tube). With lambda1 >= lambda2 >= lambda3 the variances
    of a part's vertices along its principal axes:

    * flat parts (lambda3 < flat_ratio * lambda2, e.g. leaves, bracts)
      drawn from both sides (every face has a reverse-wound twin) become a
      two-sided rectangle in the principal plane, aspect sqrt(lambda1 /
      lambda2), whose area is half the surface area of the part's convex
      hull (the one-sided area if the part is exactly planar);
    * solid parts (the rest that are not thin, e.g. bolls) become an
      outward-facing octahedron along the principal axes whose surface
      area is that of the part's convex hull.
      By Cauchy's formula a body's silhouette, averaged over all view
      directions, is a quarter of its convex hull's surface area, so both
      proxies keep the part's mean silhouette (the lumps of a boll add
      surface but no silhouette, which matching the mesh area would miss);
    * thin parts (lambda2 < thin_ratio * lambda1: stems, branches, stalks)
      become an open three-sided prism along the principal axis over the
      part's extent, of the same lateral area (the mean silhouette width
      of a long prism or tube is proportional to its perimeter);
    * anything else (a part that is not drawn from both sides but flat,
      or degenerate) stays as it is.

    A part keeps its semantic class and base colour, so bolls stay white
    and leaves green; shading follows the proxy's own normals. Returns the
    same five arrays as ``_model_arrays`` (vertices, faces int32, face
    semantic, face rgb, face unit normal) and ``error_m``, a bound on how
    far the proxy's outline may stray from the part's [m]: the largest
    bounding-box diagonal of a replaced flat or solid part, and for a thin
    part twice the largest distance of its vertices from its axis plus the
    prism's circumradius.
    """
    if len(f) == 0:
        return v, f, sem, rgb, np.zeros((0, 3)), 0.0
    error_m = 0.0
    parts = []
    for fi, pts, pf, area in _split_parts(v, f):
        proxy, part_error_m = _part_proxy(pts, pf, area, flat_ratio, thin_ratio)
        if proxy is None:                                 # keep the part as it is
            proxy = pts, pf
        else:
            error_m = max(error_m, part_error_m)
        parts.append((*proxy, fi[0]))
    return (*_assemble_parts(parts, sem, rgb), error_m)


def _with_normals(v: np.ndarray, f: np.ndarray, sem: np.ndarray, rgb: np.ndarray) -> Tuple[np.ndarray, ...]:
    """(vertices, faces int32, semantic, rgb, unit face normals) of a mesh."""
    nrm = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.where(length > 0.0, nrm / np.maximum(length, 1e-300), 0.0)
    return v, f.astype(np.int32), sem, rgb, nrm


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
def _point_mesh_distance(points, tri):  # pragma: no cover - compiled
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


def _surface_distance(va: np.ndarray, fa: np.ndarray, vb: np.ndarray, fb: np.ndarray) -> float:
    """Symmetric Hausdorff distance of two small meshes [m], estimated on a grid of 10 points per face.

    If every point of one surface is within d of the other and back, their
    outlines seen from any camera are within d too (d f / z pixels at depth z).
    """
    ta = np.ascontiguousarray(va[fa], dtype=np.float64)
    tb = np.ascontiguousarray(vb[fb], dtype=np.float64)
    return float(max(_directed_surface_distance(ta, tb), _directed_surface_distance(tb, ta)))


def _fan_outline(faces: np.ndarray) -> Optional[Tuple[int, List[int], bool]]:
    """(hub, outline vertices in order, closed) if the faces form a fan around one hub vertex, else None.

    A leaf blade or a bract of ``farm.plant_model`` is such a fan: triangles
    (hub, b_i, b_i+1) over an open (leaf) or closed (star) outline, each
    drawn from both sides.
    """
    common = set(faces[0].tolist())
    for tri in faces[1:]:
        common &= set(tri.tolist())
    if len(common) != 1:
        return None
    hub = common.pop()
    nxt: Dict[int, int] = {}
    for tri in faces.tolist():
        k = tri.index(hub)
        a, b = tri[(k + 1) % 3], tri[(k + 2) % 3]
        if a in nxt:
            return None
        nxt[a] = b
    starts = set(nxt) - set(nxt.values())
    if len(starts) > 1:
        return None
    closed = not starts
    first = starts.pop() if starts else faces[0].tolist()[(faces[0].tolist().index(hub) + 1) % 3]
    ring = [first]
    while ring[-1] in nxt and len(ring) <= len(faces):
        ring.append(nxt[ring[-1]])
    if closed:
        if ring[-1] != first:
            return None
        ring.pop()
    if len(ring) != (len(faces) if closed else len(faces) + 1):
        return None
    return hub, ring, closed


def _fan_decimations(pts: np.ndarray, faces: np.ndarray, max_step_m: float) -> List[Tuple[np.ndarray, np.ndarray]]:
    """Ever coarser versions of a two-sided fan part, each of the part's one-sided area.

    Outline vertices are removed one at a time, always the one nearest the
    segment joining its neighbours (the ends of an open outline stay), as
    long as that one is within ``max_step_m`` of the segment [m]; the kept
    outline is then scaled about the hub so that the fan keeps its area
    (its mean silhouette). Returns (vertices, two-sided faces) per step,
    finest first; [] if the part is not a two-sided fan.
    """
    first, twin = _pair_reversed_faces(faces)
    if len(first) * 2 != len(faces) or np.any(twin < 0):
        return []
    one = faces[first]
    fan = _fan_outline(one)
    if fan is None:
        return []
    hub, ring, closed = fan

    def fan_faces(count: int, closed_: bool) -> np.ndarray:
        j = np.arange(count if closed_ else count - 1)
        return np.stack([np.zeros_like(j), 1 + j, 1 + (j + 1) % count], axis=1)

    def fan_area(outline: np.ndarray) -> float:
        a = outline - pts[hub]
        b = np.roll(a, -1, axis=0)
        if not closed:
            a, b = a[:-1], b[:-1]
        cx = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
        cy = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
        cz = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        return 0.5 * float(np.sqrt(cx * cx + cy * cy + cz * cz).sum())

    target = fan_area(pts[ring])
    out = []
    keep = list(ring)
    min_count = 3
    while len(keep) > min_count:
        cands = np.arange(len(keep)) if closed else np.arange(1, len(keep) - 1)
        idx = np.array(keep)
        a, p, b = pts[idx[cands - 1]], pts[idx[cands]], pts[idx[(cands + 1) % len(keep)]]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
        d = np.linalg.norm(p - (a + t[:, None] * ab), axis=1)
        best = int(np.argmin(d))
        if d[best] > max_step_m:
            break
        keep.pop(int(cands[best]))
        outline = pts[keep]
        area = fan_area(outline)
        if not area > 0.0:
            break
        outline = pts[hub] + math.sqrt(target / area) * (outline - pts[hub])
        ff = fan_faces(len(keep), closed)
        out.append((np.vstack([pts[hub], outline]), np.concatenate([ff, ff[:, ::-1]])))
    return out


def _ellipsoid_proxy(pts: np.ndarray, surface_m2: float, n_lon: int = 6, n_lat: int = 3
                     ) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """A low-poly ellipsoid (n_lon x n_lat UV sphere) along a solid part's principal axes, of its surface area.

    The middle levels' stand-in for a boll: round from every side, unlike the
    far level's octahedron, whose silhouette is ~15 % larger than the
    boll's when seen along one of its corners (the side views of a camera
    on the robot). Outward faces; None if the part is flat in some direction.
    """
    centre = pts.mean(axis=0)
    lam, axes = np.linalg.eigh(np.cov((pts - centre).T))
    if not (lam.min() > 0.0 and surface_m2 > 0.0):
        return None
    lon = np.arange(n_lon) * (2.0 * math.pi / n_lon)
    lat = np.arange(1, n_lat) * (math.pi / n_lat)
    unit = [(0.0, 0.0, 1.0)] + [(math.sin(a) * math.cos(b), math.sin(a) * math.sin(b), math.cos(a))
                                 for a in lat for b in lon] + [(0.0, 0.0, -1.0)]
    local = np.array(unit) * np.sqrt(lam)[None, :]
    faces = [(0, 1 + j, 1 + (j + 1) % n_lon) for j in range(n_lon)]
    for i in range(n_lat - 2):
        for j in range(n_lon):
            a, b = 1 + i * n_lon + j, 1 + i * n_lon + (j + 1) % n_lon
            faces += [(a, a + n_lon, b + n_lon), (a, b + n_lon, b)]
    last, base = len(unit) - 1, 1 + (n_lat - 2) * n_lon
    faces += [(last, base + (j + 1) % n_lon, base + j) for j in range(n_lon)]
    faces = np.array(faces, dtype=np.int64)
    area = 0.5 * float(np.linalg.norm(np.cross(local[faces[:, 1]] - local[faces[:, 0]],
                                               local[faces[:, 2]] - local[faces[:, 0]]), axis=1).sum())
    corners = centre + (math.sqrt(surface_m2 / area) * local) @ axes.T
    return _wind_outward(corners, faces, centre)


def part_levels(v: np.ndarray, f: np.ndarray, max_error_m: float, flat_ratio: float = 0.05,
                thin_ratio: float = 0.1) -> List[Tuple[int, List[Tuple[int, float, np.ndarray, np.ndarray]]]]:
    """Per part of a model (connected component): (its first face, its versions).

    A version is (drawn faces, error [m], vertices, faces). The first is the
    part itself (error 0); then, for a two-sided fan (leaf, bract), the
    ``_fan_decimations`` (outline steps up to ``max_error_m``); for any
    other part its far proxy (``proxy_model_arrays``), for a solid part
    (boll) an ``_ellipsoid_proxy`` instead of the octahedron. error is the
    ``_surface_distance`` of the version from the part, a bound on how far
    its outline strays seen from anywhere. Drawn faces count a two-sided
    pair once, as the rasteriser draws it.
    """
    out = []
    for fi, pts, pf, area in _split_parts(v, f):
        first, twin = _pair_reversed_faces(pf)
        versions = [(len(first), 0.0, pts, pf)]
        two_sided = len(first) * 2 == len(pf) and np.all(twin >= 0)
        alternatives = _fan_decimations(pts, pf, max_error_m) if two_sided else []
        if not alternatives:
            # (a fan's rectangle proxy is left out: it has the area of the blade's convex hull, more than the
            # lobed blade's own, which the decimated fans keep)
            proxy, _ = _part_proxy(pts, pf, area, flat_ratio, thin_ratio)
            if proxy is not None and len(proxy[1]) == 8:        # a solid part's octahedron: a round one instead
                proxy = _ellipsoid_proxy(pts, _hull_area(pts))
            if proxy is not None and len(proxy[1]) < len(pf):
                alternatives.append(proxy)
        for av, af in alternatives:
            # the fans and the flat proxies are two-sided (pairs drawn once), the other proxies one-sided
            drawn = len(af) // 2 if two_sided else len(af)
            versions.append((drawn, _surface_distance(pts, pf, av, af), av, af))
        out.append((fi[0], versions))
    return out


_PART_LEVELS_CACHE: "collections.OrderedDict[bytes, list]" = collections.OrderedDict()
_PART_LEVELS_CACHE_SIZE = 64          # models (~100 kB each)
_PART_LEVELS_LOCK = threading.Lock()


def _cached_part_levels(v: np.ndarray, f: np.ndarray, max_error_m: float) -> list:
    """``part_levels`` remembered by the model's bytes: a process that builds several scenes of the same
    farm (tests, benchmarks, a simulator reset) pays the ~0.5 s per plant model once."""
    key = hashlib.sha1(np.ascontiguousarray(v).tobytes() + np.ascontiguousarray(f).tobytes()
                       + np.float64(max_error_m).tobytes()).digest()
    with _PART_LEVELS_LOCK:                       # scenes may be built in several threads
        if key in _PART_LEVELS_CACHE:
            _PART_LEVELS_CACHE.move_to_end(key)
            return _PART_LEVELS_CACHE[key]
    levels = part_levels(v, f, max_error_m)
    with _PART_LEVELS_LOCK:
        _PART_LEVELS_CACHE[key] = levels
        while len(_PART_LEVELS_CACHE) > _PART_LEVELS_CACHE_SIZE:
            _PART_LEVELS_CACHE.popitem(last=False)
    return levels


def simplified_model_arrays(v: np.ndarray, f: np.ndarray, sem: np.ndarray, rgb: np.ndarray, tolerance_m: float,
                            levels: Optional[list] = None) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                                    np.ndarray, float]:
    """A middle level of detail: every part drawn with its fewest-face version within ``tolerance_m``.

    The versions are ``part_levels``'s (pass ``levels`` to reuse them for
    several tolerances); a part keeps its semantic class and base colour.
    Returns the five arrays of ``_model_arrays`` and the level's error
    bound [m]: the largest ``_surface_distance`` of a chosen version.
    """
    if len(f) == 0:
        return v, f, sem, rgb, np.zeros((0, 3)), 0.0
    if levels is None:
        levels = part_levels(v, f, tolerance_m)
    parts, error_m = [], 0.0
    for face0, versions in levels:
        drawn, err, pv, pf = min((x for x in versions if x[1] <= tolerance_m), key=lambda x: (x[0], x[1]))
        error_m = max(error_m, err)
        parts.append((pv, pf, face0))
    return (*_assemble_parts(parts, sem, rgb), error_m)


def _pair_reversed_faces(faces: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Faces to draw and, per drawn face, the index of its reverse-wound twin (-1 if none)."""
    if len(faces) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    # a cyclic rotation that starts at the smallest index identifies a winding; its reverse is the twin
    rot = np.argmin(faces, axis=1)
    idx = np.arange(len(faces))
    fwd = np.stack([faces[idx, rot], faces[idx, (rot + 1) % 3], faces[idx, (rot + 2) % 3]], axis=1)
    rev = fwd[:, [0, 2, 1]]
    lookup = {tuple(f): i for i, f in enumerate(fwd.tolist())}
    first, twin, used = [], [], np.zeros(len(faces), bool)
    for i in range(len(faces)):
        if used[i]:
            continue
        j = lookup.get(tuple(rev[i].tolist()), -1)
        if j >= 0 and (used[j] or j == i):
            j = -1
        used[i] = True
        if j >= 0:
            used[j] = True
        first.append(i)
        twin.append(j)
    return np.array(first, np.int64), np.array(twin, np.int64)
