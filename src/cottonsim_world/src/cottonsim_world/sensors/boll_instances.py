"""The farm as the sensors draw it: plants without their bolls, and every boll an instance of its own.

Why: a boll that leaves its plant must vanish from the camera images, the
depth clouds, the LiDAR and the ground-truth masks at once, while the farm
shares a few plant models between many plants (one model's boll mesh is
every plant's of that variant). So each plant model is split once into

* the plant without its boll meshes (stem, leaves, bracts, ...), and
* one small model per boll: the connected parts of the model's boll meshes
  nearest to that boll's centre (``PlantModel.boll_centres``),

and the scene draws and ray casts *instances*: ``SplitFarm.instances`` is
every plant (stripped), in ``farm.plants`` order, then every boll, in the
id order of ``farm.bolls.BollField`` (plants in order, a plant's bolls in
model order). A boll instance carries its plant's id, position and yaw,
so its triangles keep the plant id and the renderers need no new
transform. Hiding a boll is leaving its instance out.

A model whose boll meshes have no boll centres keeps them (they cannot be
told apart, so they are drawn with the plant and never hidden).
"""
from __future__ import annotations

import dataclasses
from typing import Dict, List, Sequence, Tuple

import numpy as np

from cottonsim_world.farm.model import Plant, PlantModel, SemanticClass, TriangleMesh
from cottonsim_world.sensors.fast.mesh_arrays import mesh_components


def _boll_part_meshes(model: PlantModel) -> List[Dict[str, TriangleMesh]]:
    """Per boll of ``model`` (boll_centres order) its meshes: name -> the parts of that boll mesh nearest it."""
    centres = np.asarray(model.boll_centres, dtype=float).reshape(-1, 3)
    out: List[Dict[str, TriangleMesh]] = [{} for _ in range(len(centres))]
    for name, mesh in model.meshes.items():
        if mesh.semantic != SemanticClass.BOLL or len(mesh.faces) == 0:
            continue
        v = np.asarray(mesh.vertices, dtype=float)
        f = np.asarray(mesh.faces, dtype=np.int64)
        n_parts, face_part = mesh_components(v, f)
        owner = np.zeros(n_parts, dtype=np.int64)
        for part in range(n_parts):
            corners = v[f[face_part == part]].reshape(-1, 3)
            if len(corners):
                owner[part] = int(np.argmin(np.linalg.norm(centres - corners.mean(axis=0), axis=1)))
        face_owner = owner[face_part]
        for k in range(len(centres)):
            faces = f[face_owner == k]
            if len(faces) == 0:
                continue
            used, local = np.unique(faces, return_inverse=True)
            out[k][name] = TriangleMesh(vertices=np.ascontiguousarray(v[used], dtype=np.float32),
                                        faces=local.reshape(-1, 3).astype(np.int32), rgba=mesh.rgba,
                                        semantic=SemanticClass.BOLL)
    return out


def split_model(model: PlantModel) -> Tuple[PlantModel, List[PlantModel]]:
    """(the model without its boll meshes, one model per boll holding only that boll's parts).

    A boll model keeps the plant's frame (plant-local coordinates), its one
    boll centre and radius, and no collision primitives.
    """
    centres = np.asarray(model.boll_centres, dtype=float).reshape(-1, 3)
    radii = np.asarray(model.boll_radii, dtype=float).reshape(-1)
    if len(centres) == 0:
        return model, []
    kept = {name: m for name, m in model.meshes.items() if m.semantic != SemanticClass.BOLL}
    plant = dataclasses.replace(model, meshes=kept)
    bolls = [PlantModel(meshes=meshes, collision=[], boll_centres=centres[k:k + 1], boll_radii=radii[k:k + 1],
                        height_m=model.height_m, width_m=model.width_m)
             for k, meshes in enumerate(_boll_part_meshes(model))]
    return plant, bolls


class SplitFarm:
    """Plants and bolls as separate instances (see the module docstring).

    instances: the P stripped plants, then the B bolls; boll j is instance
    ``plant_count + j``. boll_first / boll_count (P,) int64: plant i's
    bolls are ids boll_first[i] .. boll_first[i] + boll_count[i] - 1.
    boll_plant_index (B,) int64: the index in ``farm.plants`` of each
    boll's plant. Plants sharing a model share its split models.
    """

    def __init__(self, plants: Sequence[Plant]) -> None:
        cache: Dict[int, Tuple[PlantModel, List[PlantModel]]] = {}
        stripped: List[Plant] = []
        bolls: List[Plant] = []
        counts = np.zeros(len(plants), dtype=np.int64)
        plant_index: List[int] = []
        for i, plant in enumerate(plants):
            key = id(plant.model)
            if key not in cache:
                cache[key] = split_model(plant.model)
            plant_model, boll_models = cache[key]
            stripped.append(dataclasses.replace(plant, model=plant_model))
            bolls.extend(dataclasses.replace(plant, model=m) for m in boll_models)
            counts[i] = len(boll_models)
            plant_index.extend([i] * len(boll_models))
        self.plant_count = len(plants)
        self.boll_total = len(bolls)
        self.instances: List[Plant] = stripped + bolls
        self.boll_count = counts
        self.boll_first = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64) if len(counts) \
            else np.zeros(0, np.int64)
        self.boll_plant_index = np.array(plant_index, dtype=np.int64)

    def bolls_of(self, plant_indices: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """The boll ids of the plants ``plant_indices`` (n,) and, per boll, its position in that array."""
        plant_indices = np.asarray(plant_indices, dtype=np.int64)
        counts = self.boll_count[plant_indices]
        total = int(counts.sum())
        if total == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        owner = np.repeat(np.arange(len(plant_indices)), counts)
        offset = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        return self.boll_first[plant_indices][owner] + offset, owner
