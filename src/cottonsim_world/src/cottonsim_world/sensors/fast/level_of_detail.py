"""Levels of detail of a plant model for the numba camera: simplified and proxy meshes.

Why: a plant 20 m from the camera covers a few hundred pixels, but its full
model has thousands of triangles. ``instanced_plants.InstancedPlants`` draws
far plants with fewer triangles, made here from the full model:

``simplified_model_arrays``
    every part (a leaf, bract, boll or tube, found as a connected set of
    faces) in its fewest-face version whose surface stays within a
    tolerance of the full part (``part_levels``: fan decimations of leaf
    outlines and ellipsoid proxies, measured by a sampled two-sided surface
    distance, ``surface_distance``);
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

from cottonsim_world.sensors.fast.mesh_arrays import (assemble_parts, convex_hull_area, pair_reversed_faces,
                                                      split_parts, wind_outward)
from cottonsim_world.sensors.fast.surface_distance import surface_distance


def _octahedron_faces() -> np.ndarray:
    """Faces of an octahedron with vertices +a0, -a0, +a1, -a1, +a2, -a2 (indices 0..5)."""
    out = []
    for sx in (0, 1):
        for sy in (2, 3):
            for sz in (4, 5):
                out.append((sx, sy, sz))
    return np.array(out, dtype=np.int64)


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
    hull_area = convex_hull_area(pts)
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
        _, twin = pair_reversed_faces(part_faces)
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
            proxy = wind_outward(corners, _octahedron_faces(), centre)
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
    same five arrays as ``model_arrays`` (vertices, faces int32, face
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
    for fi, pts, pf, area in split_parts(v, f):
        proxy, part_error_m = _part_proxy(pts, pf, area, flat_ratio, thin_ratio)
        if proxy is None:                                 # keep the part as it is
            proxy = pts, pf
        else:
            error_m = max(error_m, part_error_m)
        parts.append((*proxy, fi[0]))
    return (*assemble_parts(parts, sem, rgb), error_m)


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
    first, twin = pair_reversed_faces(faces)
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
    return wind_outward(corners, faces, centre)


def part_levels(v: np.ndarray, f: np.ndarray, max_error_m: float, flat_ratio: float = 0.05,
                thin_ratio: float = 0.1) -> List[Tuple[int, List[Tuple[int, float, np.ndarray, np.ndarray]]]]:
    """Per part of a model (connected component): (its first face, its versions).

    A version is (drawn faces, error [m], vertices, faces). The first is the
    part itself (error 0); then, for a two-sided fan (leaf, bract), the
    ``_fan_decimations`` (outline steps up to ``max_error_m``); for any
    other part its far proxy (``proxy_model_arrays``), for a solid part
    (boll) an ``_ellipsoid_proxy`` instead of the octahedron. error is the
    ``surface_distance`` of the version from the part, a bound on how far
    its outline strays seen from anywhere. Drawn faces count a two-sided
    pair once, as the rasteriser draws it.
    """
    out = []
    for fi, pts, pf, area in split_parts(v, f):
        first, twin = pair_reversed_faces(pf)
        versions = [(len(first), 0.0, pts, pf)]
        two_sided = len(first) * 2 == len(pf) and np.all(twin >= 0)
        alternatives = _fan_decimations(pts, pf, max_error_m) if two_sided else []
        if not alternatives:
            # (a fan's rectangle proxy is left out: it has the area of the blade's convex hull, more than the
            # lobed blade's own, which the decimated fans keep)
            proxy, _ = _part_proxy(pts, pf, area, flat_ratio, thin_ratio)
            if proxy is not None and len(proxy[1]) == 8:        # a solid part's octahedron: a round one instead
                proxy = _ellipsoid_proxy(pts, convex_hull_area(pts))
            if proxy is not None and len(proxy[1]) < len(pf):
                alternatives.append(proxy)
        for av, af in alternatives:
            # the fans and the flat proxies are two-sided (pairs drawn once), the other proxies one-sided
            drawn = len(af) // 2 if two_sided else len(af)
            versions.append((drawn, surface_distance(pts, pf, av, af), av, af))
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
    Returns the five arrays of ``model_arrays`` and the level's error
    bound [m]: the largest ``surface_distance`` of a chosen version.
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
    return (*assemble_parts(parts, sem, rgb), error_m)


