"""Flat arrays of the static farm for the numba camera and LiDAR kernels.

Why: compiled kernels want plain contiguous arrays, not dictionaries of
meshes. The plants are flattened once per scene:

``InstancedPlants`` (camera)
    The farm shares a few plant models between many plants (farm.generator
    makes 8 variants by default), so the model meshes are stored once, in
    plant-local coordinates, and each plant is an instance (model index,
    x, y, yaw). The rasteriser transforms a visible plant's vertices into
    the camera frame once per frame. Every (plant, face) pair has a *global
    triangle id* ``plant_gbase[p] + face``; per global id we keep the shaded
    colour (flat half-Lambert shading under the scene's sun, fixed because
    the farm is static), the SemanticClass and the plant id, so the rasteriser
    only stores triangle ids per pixel and colours at the end.

``InstancedPlants.world_triangles`` (LiDAR)
    All full-detail triangles in world coordinates with the same global
    ids, from which ``bvh.TriangleBVH`` builds the ray caster's tree.

Frames: world z up [m]; plant-local as in ``farm.model``.
"""
from __future__ import annotations

import math
from typing import Dict, List, Sequence, Tuple

import numpy as np

from cottonsim_world.farm.model import Plant, PlantModel


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
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if len(f) == 0:
        return v, f, sem, rgb, np.zeros((0, 3)), 0.0
    n = len(v)
    error_m = 0.0
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    n_parts, label = connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)),
                                          directed=False)
    face_part = label[f[:, 0]]
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    face_area = 0.5 * np.linalg.norm(cross, axis=1)
    out_v, out_f, out_sem, out_rgb = [], [], [], []
    count = 0
    for part in range(n_parts):
        fi = np.nonzero(face_part == part)[0]
        if len(fi) == 0:
            continue
        vi = np.unique(f[fi])
        pts = v[vi]
        centre = pts.mean(axis=0)
        lam, axes = np.linalg.eigh(np.cov((pts - centre).T) if len(pts) > 1 else np.zeros((3, 3)))
        lam = np.maximum(lam[::-1], 0.0)                  # descending
        axes = axes[:, ::-1]
        area = float(face_area[fi].sum())
        hull_area = _hull_area(pts)
        proxy = None
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
                error_m = max(error_m, 2.0 * float(np.linalg.norm(off_axis, axis=1).max()) + circ)
        elif lam[0] > 0.0:
            _, twin = _pair_reversed_faces(f[fi])
            two_sided = np.count_nonzero(twin >= 0) * 2 == len(fi)
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
                faces = _octahedron_faces()
                # wind every face counter-clockwise seen from outside
                nrm = np.cross(corners[faces[:, 1]] - corners[faces[:, 0]], corners[faces[:, 2]] - corners[faces[:, 0]])
                outward = np.einsum("ij,ij->i", nrm, corners[faces].mean(axis=1) - centre) > 0.0
                proxy = corners, np.where(outward[:, None], faces, faces[:, ::-1])
        if proxy is not None and not lam[1] < thin_ratio * lam[0]:
            error_m = max(error_m, float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))))
        if proxy is None:                                 # keep the part as it is
            remap = np.full(n, -1, dtype=np.int64)
            remap[vi] = np.arange(len(vi))
            proxy = pts, remap[f[fi]]
        pv, pf = proxy
        out_v.append(pv)
        out_f.append(pf + count)
        out_sem.append(np.full(len(pf), sem[fi[0]], dtype=np.uint8))
        out_rgb.append(np.tile(rgb[fi[0]], (len(pf), 1)))
        count += len(pv)
    pv, pf = np.concatenate(out_v), np.concatenate(out_f)
    nrm = np.cross(pv[pf[:, 1]] - pv[pf[:, 0]], pv[pf[:, 2]] - pv[pf[:, 0]])
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.where(length > 0.0, nrm / np.maximum(length, 1e-300), 0.0)
    return pv, pf.astype(np.int32), np.concatenate(out_sem), np.concatenate(out_rgb), nrm, error_m


class InstancedPlants:
    """Plant models stored once (plant-local) plus one instance per plant, in levels of detail.

    Level 0 is the full model; level 1 (``proxy_model_arrays``) replaces
    each leaf, bract, boll and tube by a few triangles of the same area,
    for plants far enough that a part is only a few pixels. A *slot*
    s = level * M + model indexes the per-model arrays.

    Arrays (M models, P plants, L = 2 levels, G = global triangle ids):
    model_verts (sum V, 3) float64 [m]; model_faces (sum F, 3) int32
    (indices into model_verts, already offset by the slot's vertex base);
    model_vbase/model_vcount/model_fbase/model_fcount (L * M,) int64;
    plant_model (P,) int64 level-0 slot = model index; plant_pose (P, 4)
    float64 = x [m], y [m], cos(yaw), sin(yaw); plant_gbase (P,) int64
    first global triangle id of the full model (ids 0 .. triangle_count - 1
    are the full-detail faces, the ones the LiDAR's grid also uses);
    level_gbase (L, P) int64 first global id of each level's copy;
    g_rgb (G, 3) uint8 shaded colour; g_semantic (G,) uint8; g_plant (G,)
    int32 plant id. Draw list (what the rasteriser loops over):
    draw_base/draw_count (L * M,) int64; draw_faces (sum, 3) int32 like
    model_faces; draw_local (sum,) int32 the face's index in its slot;
    draw_twin (sum,) int32 the index of its reverse-wound twin or -1.
    ``proxy_error_m`` (M,) bounds how far level 1's outlines stray from
    the full model's [m] (see ``proxy_model_arrays``).
    """

    LEVELS = 2

    def __init__(self, plants: Sequence[Plant], sun_direction: np.ndarray, ambient: float, diffuse: float,
                 light_rgb: Sequence[float]) -> None:
        index_of: Dict[int, int] = {}
        per_model: List[Tuple[np.ndarray, ...]] = []
        plant_model = np.zeros(len(plants), dtype=np.int64)
        for i, plant in enumerate(plants):
            key = id(plant.model)
            if key not in index_of:
                index_of[key] = len(per_model)
                per_model.append(_model_arrays(plant.model))
            plant_model[i] = index_of[key]
        m = len(per_model)
        self.model_count = m
        proxies = [proxy_model_arrays(*a[:4]) for a in per_model]
        per_slot = list(per_model) + [a[:5] for a in proxies]
        self.proxy_error_m = np.array([a[5] for a in proxies], dtype=np.float64)
        self.model_vcount = np.array([len(a[0]) for a in per_slot], dtype=np.int64)
        self.model_fcount = np.array([len(a[1]) for a in per_slot], dtype=np.int64)
        self.model_vbase = _starts(self.model_vcount)
        self.model_fbase = _starts(self.model_fcount)
        if m:
            self.model_verts = np.ascontiguousarray(np.concatenate([a[0] for a in per_slot]), dtype=np.float64)
            self.model_faces = np.ascontiguousarray(np.concatenate(
                [a[1] + self.model_vbase[k] for k, a in enumerate(per_slot)]), dtype=np.int32)
        else:
            self.model_verts = np.zeros((0, 3))
            self.model_faces = np.zeros((0, 3), np.int32)
        self.max_model_verts = int(self.model_vcount.max()) if m else 0
        # draw list: a face and its reverse-wound twin (two-sided leaves) are drawn as one triangle
        # that takes the twin's id when seen from behind; faces without a twin are culled from behind
        draw_faces, draw_local, draw_twin, draw_count = [], [], [], []
        for k, a in enumerate(per_slot):
            first, twin = _pair_reversed_faces(a[1])
            draw_faces.append(a[1][first] + self.model_vbase[k])
            draw_local.append(first)
            draw_twin.append(twin)
            draw_count.append(len(first))
        self.draw_count = np.array(draw_count, dtype=np.int64)
        self.draw_base = _starts(self.draw_count)
        self.draw_faces = np.ascontiguousarray(np.concatenate(draw_faces), dtype=np.int32) if m else \
            np.zeros((0, 3), np.int32)
        self.draw_local = np.concatenate(draw_local).astype(np.int32) if m else np.zeros(0, np.int32)
        self.draw_twin = np.concatenate(draw_twin).astype(np.int32) if m else np.zeros(0, np.int32)
        self.plant_model = plant_model
        self.plant_ids = np.array([p.plant_id for p in plants], dtype=np.int32)
        yaw = np.array([p.yaw_rad for p in plants], dtype=np.float64)
        self.plant_pose = np.ascontiguousarray(np.stack(
            [np.array([p.x_m for p in plants], float), np.array([p.y_m for p in plants], float),
             np.cos(yaw), np.sin(yaw)], axis=1).reshape(-1, 4))
        # global ids: all plants' full models first (the ids the LiDAR reports), then each further level
        self.level_gbase = np.zeros((self.LEVELS, len(plants)), dtype=np.int64)
        total = 0
        for level in range(self.LEVELS):
            fcount = self.model_fcount[level * m + plant_model] if len(plants) else np.zeros(0, np.int64)
            self.level_gbase[level] = total + _starts(fcount)
            if level == 0:
                self.triangle_count = int(fcount.sum())
            total += int(fcount.sum())
        self.plant_gbase = self.level_gbase[0].copy()
        self.g_rgb = np.zeros((total, 3), dtype=np.uint8)
        self.g_semantic = np.zeros(total, dtype=np.uint8)
        self.g_plant = np.zeros(total, dtype=np.int32)
        sun = np.asarray(sun_direction, dtype=np.float64)
        light = np.asarray(light_rgb, dtype=np.float64)
        for slot, (_, _, sem, rgb, nrm) in enumerate(per_slot):
            level, k = divmod(slot, max(m, 1))
            members = np.nonzero(plant_model == k)[0]
            if len(members) == 0 or len(sem) == 0:
                continue
            c, s = self.plant_pose[members, 2:3], self.plant_pose[members, 3:4]
            # n_world . sun with n_world = Rz(yaw) n_local
            lambert = nrm[None, :, 0] * (c * sun[0] + s * sun[1]) + nrm[None, :, 1] * (c * sun[1] - s * sun[0]) \
                + nrm[None, :, 2] * sun[2]
            # half-Lambert (0.5 + 0.5 n.l): soft light that also reaches faces turned from the sun,
            # closer to TinyRenderer's brightness than a hard max(0, n.l) cut-off
            intensity = ambient + diffuse * (0.5 + 0.5 * lambert)                       # (Pm, Fm)
            colour = np.clip(255.0 * rgb[None] * light[None, None] * intensity[..., None], 0.0, 255.0)
            nf = len(sem)
            for row, p in enumerate(members):
                sl = slice(self.level_gbase[level, p], self.level_gbase[level, p] + nf)
                self.g_rgb[sl] = colour[row].astype(np.uint8)
                self.g_semantic[sl] = sem
                self.g_plant[sl] = self.plant_ids[p]
        self._per_model_faces = [(a[0], a[1]) for a in per_model]

    def world_triangles(self, one_sided_duplicates: bool = True) -> Tuple[np.ndarray, np.ndarray]:
        """World-space triangle corners (N, 3, 3) float64 [m] and their global ids (N,) int32.

        With ``one_sided_duplicates`` a face that repeats another with the
        opposite winding (the back side of a two-sided leaf) is left out:
        a ray hits both at the same distance, so ray casting needs one.
        """
        tris, ids = [], []
        for k, (v, f) in enumerate(self._per_model_faces):
            members = np.nonzero(self.plant_model == k)[0]
            if len(members) == 0 or len(f) == 0:
                continue
            keep = _first_of_each_face(f) if one_sided_duplicates else np.arange(len(f))
            corners = v[f[keep]]                                                    # (F, 3, 3) local
            for p in members:
                x, y, c, s = self.plant_pose[p]
                out = np.empty_like(corners)
                out[..., 0] = x + c * corners[..., 0] - s * corners[..., 1]
                out[..., 1] = y + s * corners[..., 0] + c * corners[..., 1]
                out[..., 2] = corners[..., 2]
                tris.append(out)
                ids.append(self.plant_gbase[p] + keep)
        if not tris:
            return np.zeros((0, 3, 3)), np.zeros(0, np.int32)
        return np.concatenate(tris), np.concatenate(ids).astype(np.int32)


def _starts(counts: np.ndarray) -> np.ndarray:
    """Exclusive prefix sums: where each block of ``counts`` starts."""
    counts = np.asarray(counts, dtype=np.int64)
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64) if len(counts) else np.zeros(0, np.int64)


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


def _first_of_each_face(faces: np.ndarray) -> np.ndarray:
    """Indices of the faces whose vertex set has not appeared before (any winding)."""
    key = np.sort(faces, axis=1)
    _, first = np.unique(key, axis=0, return_index=True)
    return np.sort(first)
