"""The pybullet ray-cast world of the reference LiDAR backend, with every boll a body of its own.

Why: ``rayTestBatch`` casts against collision bodies, and a boll that has
left its plant must no longer return rays. The world holds an infinite
ground plane, one body per plant for its parts (stem, leaves, ...) and one
body per boll (``sensors.boll_instances.SplitFarm``); ``sync(hidden)``
removes the bodies of hidden bolls and puts back those shown again.

Shapes follow ``SceneConfig.collision_source``: 'meshes' (the models'
triangle meshes as concave trimeshes) or 'primitives' (the plant's
collision primitives; a boll as a sphere of its radius at its centre).
Building takes seconds on the default farm; ``SensorScene.ray_client``
builds it on first use.
"""
from __future__ import annotations

from typing import Dict, Sequence, Tuple

import numpy as np
import pybullet as pb

from cottonsim_world.farm.model import Plant, PlantModel, SemanticClass, TriangleMesh
from cottonsim_world.sensors.boll_instances import SplitFarm
from cottonsim_common.transforms import yaw_to_quaternion


def merge_meshes(meshes: Sequence[TriangleMesh]) -> Tuple[np.ndarray, np.ndarray]:
    """Concatenate meshes into one (vertices, faces) pair."""
    verts, faces, offset = [], [], 0
    for m in meshes:
        verts.append(np.asarray(m.vertices, dtype=float))
        faces.append(np.asarray(m.faces, dtype=np.int64) + offset)
        offset += len(m.vertices)
    if not verts:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    return np.concatenate(verts), np.concatenate(faces)


class PybulletRayWorld:
    """Ground, plant bodies and boll bodies in a pybullet DIRECT client (see the module docstring).

    ``semantic_of_body`` / ``plant_of_body``: per body id its SemanticClass
    (SKY for ids that are no body) and plant id (-1 off the plants).
    """

    def __init__(self, split: SplitFarm, collision_source: str) -> None:
        self.client = pb.connect(pb.DIRECT)
        self._split = split
        self._use_meshes = collision_source == "meshes"
        self.semantic_of_body = np.full(1, int(SemanticClass.SKY), dtype=np.uint8)
        self.plant_of_body = np.full(1, -1, dtype=np.int32)
        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=self.client)
        self._register(pb.createMultiBody(0.0, plane, -1, [0.0, 0.0, 0.0], physicsClientId=self.client),
                       SemanticClass.GROUND, -1)
        shapes: Dict[int, int] = {}
        for plant in split.instances[:split.plant_count]:
            key = id(plant.model)
            if key not in shapes:
                shapes[key] = self._plant_shape(plant)
            self._add_body(shapes[key], plant, SemanticClass.PLANT)
        self._boll_shapes: Dict[int, int] = {}
        self._boll_body: Dict[int, int] = {}
        for j in range(split.boll_total):
            self._add_boll(j)
        self.hidden = np.zeros(split.boll_total, dtype=bool)

    def _register(self, body: int, sem: SemanticClass, plant_id: int) -> None:
        if body >= len(self.semantic_of_body):
            n = max(2 * len(self.semantic_of_body), body + 1)
            self.semantic_of_body = np.concatenate(
                [self.semantic_of_body, np.full(n - len(self.semantic_of_body), int(SemanticClass.SKY), np.uint8)])
            self.plant_of_body = np.concatenate([self.plant_of_body, np.full(n - len(self.plant_of_body), -1, np.int32)])
        self.semantic_of_body[body] = int(sem)
        self.plant_of_body[body] = plant_id

    def _add_body(self, shape: int, plant: Plant, sem: SemanticClass) -> int:
        if shape < 0:
            return -1
        body = pb.createMultiBody(0.0, shape, -1, [plant.x_m, plant.y_m, 0.0], yaw_to_quaternion(plant.yaw_rad),
                                  physicsClientId=self.client)
        self._register(body, sem, plant.plant_id)
        return body

    def _add_boll(self, j: int) -> None:
        plant = self._split.instances[self._split.plant_count + j]
        key = id(plant.model)
        if key not in self._boll_shapes:
            self._boll_shapes[key] = self._boll_shape(plant.model)
        body = self._add_body(self._boll_shapes[key], plant, SemanticClass.BOLL)
        if body >= 0:
            self._boll_body[j] = body

    def sync(self, hidden: np.ndarray) -> None:
        """Remove the bodies of the bolls ``hidden`` (B,) bool marks, put back the others."""
        for j in np.nonzero(hidden != self.hidden)[0]:
            j = int(j)
            if hidden[j]:
                body = self._boll_body.pop(j, None)
                if body is not None:
                    pb.removeBody(body, physicsClientId=self.client)
                    self.semantic_of_body[body] = int(SemanticClass.SKY)
                    self.plant_of_body[body] = -1
            else:
                self._add_boll(j)
        self.hidden = np.array(hidden, dtype=bool)

    def _mesh_shape(self, meshes: Sequence[TriangleMesh]) -> int:
        v, f = merge_meshes(meshes)
        if len(f) == 0:
            return -1
        return pb.createCollisionShape(pb.GEOM_MESH, vertices=v.tolist(), indices=f.ravel().tolist(),
                                       flags=pb.GEOM_FORCE_CONCAVE_TRIMESH, physicsClientId=self.client)

    def _boll_shape(self, model: PlantModel) -> int:
        if self._use_meshes:
            return self._mesh_shape(list(model.meshes.values()))
        centre = np.asarray(model.boll_centres, float).reshape(-1, 3)[0]
        return pb.createCollisionShape(pb.GEOM_SPHERE, radius=float(model.boll_radii[0]),
                                       collisionFramePosition=centre.tolist(), physicsClientId=self.client)

    def _plant_shape(self, plant: Plant) -> int:
        model = plant.model
        if self._use_meshes or not model.collision:
            # a model whose bolls could not be split keeps its boll meshes here
            return self._mesh_shape(list(model.meshes.values()))
        types, radii, half, lengths, pos, orn = [], [], [], [], [], []
        for prim in model.collision:
            s = prim.size
            if prim.shape == "box":
                types.append(pb.GEOM_BOX); half.append(list(s[:3])); radii.append(0.0); lengths.append(0.0)
            elif prim.shape in ("cylinder", "capsule"):
                types.append(pb.GEOM_CYLINDER if prim.shape == "cylinder" else pb.GEOM_CAPSULE)
                radii.append(float(s[0])); lengths.append(float(s[1])); half.append([0.0, 0.0, 0.0])
            elif prim.shape == "sphere":
                types.append(pb.GEOM_SPHERE); radii.append(float(s[0])); lengths.append(0.0); half.append([0.0, 0.0, 0.0])
            else:
                raise ValueError(f"plant {plant.plant_id}: unknown collision primitive shape {prim.shape!r}")
            pos.append(list(prim.position)); orn.append(list(prim.orientation))
        return pb.createCollisionShapeArray(shapeTypes=types, radii=radii, halfExtents=half, lengths=lengths,
                                            collisionFramePositions=pos, collisionFrameOrientations=orn,
                                            physicsClientId=self.client)

    def close(self) -> None:
        if self.client is not None and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self.client = None
