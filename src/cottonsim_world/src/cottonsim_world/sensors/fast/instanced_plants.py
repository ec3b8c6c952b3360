"""The static farm as flat arrays for the numba camera and LiDAR kernels: instanced plants.

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

from typing import Dict, List, Sequence, Tuple

import numpy as np

from cottonsim_world.farm.model import Plant
from cottonsim_world.sensors.fast.level_of_detail import (_cached_part_levels, proxy_model_arrays,
                                                           simplified_model_arrays)
from cottonsim_world.sensors.fast.mesh_arrays import model_arrays, pair_reversed_faces


class InstancedPlants:
    """Plant models stored once (plant-local) plus one instance per plant, in levels of detail.

    Level 0 is the full model. The middle levels 1 .. L - 2
    (``simplified_model_arrays``, one per ``MIDDLE_TOLERANCES_M``) draw
    every part with its fewest-face version whose surface stays within the
    tolerance: leaves with fewer outline points, a boll or a tube as its
    proxy where that is close enough, for plants at mid distances. The last
    level (``proxy_model_arrays``) replaces each leaf, bract, boll and tube
    by a few triangles of the same area, for plants far enough that a part
    is only a few pixels. A *slot* s = level * M + model indexes the
    per-model arrays.

    Arrays (M models, P plants, L = ``LEVELS`` levels, G = global triangle ids):
    model_verts (sum V, 3) float64 [m]; model_xyz (3, sum V) float64 the
    same vertices one coordinate per row (the rasteriser's vertex loop reads
    them with unit stride, so LLVM vectorises it); model_faces (sum F, 3)
    int32 (indices into model_verts, already offset by the slot's vertex base);
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
    ``level_error_m`` (L, M) bounds how far each level's outlines stray
    from the full model's [m] (0 for level 0); ``proxy_error_m`` (M,) is
    its last row, the far proxies' bound (see ``proxy_model_arrays``).
    """

    MIDDLE_TOLERANCES_M = (0.01, 0.025)     # surface distance allowed in the middle levels [m]
    LEVELS = 2 + len(MIDDLE_TOLERANCES_M)

    def __init__(self, plants: Sequence[Plant], sun_direction: np.ndarray, ambient: float, diffuse: float,
                 light_rgb: Sequence[float]) -> None:
        index_of: Dict[int, int] = {}
        per_model: List[Tuple[np.ndarray, ...]] = []
        plant_model = np.zeros(len(plants), dtype=np.int64)
        for i, plant in enumerate(plants):
            key = id(plant.model)
            if key not in index_of:
                index_of[key] = len(per_model)
                per_model.append(model_arrays(plant.model))
            plant_model[i] = index_of[key]
        m = len(per_model)
        self.model_count = m
        # levels 1 .. L-2: each part its fewest-face version within a tolerance; level L-1: the far proxies
        middle = []
        for a in per_model:
            versions = _cached_part_levels(a[0], a[1], max(self.MIDDLE_TOLERANCES_M)) if len(a[1]) else None
            middle.append([simplified_model_arrays(*a[:4], tol, versions) for tol in self.MIDDLE_TOLERANCES_M])
        proxies = [proxy_model_arrays(*a[:4]) for a in per_model]
        per_slot = list(per_model)
        for k in range(len(self.MIDDLE_TOLERANCES_M)):
            per_slot += [mid[k][:5] for mid in middle]
        per_slot += [a[:5] for a in proxies]
        self.proxy_error_m = np.array([a[5] for a in proxies], dtype=np.float64)
        self.level_error_m = np.zeros((self.LEVELS, m), dtype=np.float64)
        for k in range(len(self.MIDDLE_TOLERANCES_M)):
            self.level_error_m[1 + k] = [mid[k][5] for mid in middle]
        self.level_error_m[-1] = self.proxy_error_m
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
        self.model_xyz = np.ascontiguousarray(self.model_verts.T)
        self.max_model_verts = int(self.model_vcount.max()) if m else 0
        # draw list: a face and its reverse-wound twin (two-sided leaves) are drawn as one triangle
        # that takes the twin's id when seen from behind; faces without a twin are culled from behind
        draw_faces, draw_local, draw_twin, draw_count = [], [], [], []
        for k, a in enumerate(per_slot):
            first, twin = pair_reversed_faces(a[1])
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


def _first_of_each_face(faces: np.ndarray) -> np.ndarray:
    """Indices of the faces whose vertex set has not appeared before (any winding)."""
    key = np.sort(faces, axis=1)
    _, first = np.unique(key, axis=0, return_index=True)
    return np.sort(first)
