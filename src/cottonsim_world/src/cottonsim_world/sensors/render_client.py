"""One camera's pybullet render client, holding only the plants that camera can see.

Why: the TinyRenderer's cost grows with every triangle it is given, on
screen or not, so each camera keeps its own small client and adds or
removes plant bodies as its view moves (``SensorScene.new_render_client``).
The ground and sky are not rendered here (see ``sensors.scene``). Bolls are
bodies of their own (``sensors.boll_instances``): those of the plants in
view, less the hidden ones.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Dict, List, Set, Tuple

import numpy as np
import pybullet as pb

from cottonsim_common.transforms import yaw_to_quaternion

if TYPE_CHECKING:                       # pragma: no cover
    from cottonsim_world.sensors.scene import SensorScene


class RenderClient:
    """A pybullet DIRECT client holding only the plants one camera needs.

    Each plant becomes one multibody with no visual on its base and one link
    per material name known to the scene (same order for every plant; an
    empty visual where a plant lacks that material). With the segmentation
    flag OBJECT_AND_LINKINDEX a pixel value is ``body + ((link + 1) << 24)``,
    so ``link_semantic_lut[value >> 24]`` gives the SemanticClass and
    ``plant_of_body[value & 0xFFFFFF]`` the plant id. A boll is a body of
    the same build whose only visual is on the boll material's link.
    Bodies are keyed by instance index (``SensorScene.split.instances``:
    plants first, then bolls).
    """

    def __init__(self, scene: "SensorScene", renderer: str = "tiny") -> None:
        self.scene = scene
        self.client = pb.connect(pb.DIRECT)
        self.renderer_flag = pb.ER_TINY_RENDERER
        self.renderer = "tiny"
        if renderer == "egl":
            self._try_egl()
        self._visuals: Dict[int, List[int]] = {}        # id(plant model) -> visual id per material
        self._bodies: Dict[int, int] = {}               # instance index -> body id
        self.plant_of_body = np.full(1, -1, dtype=np.int32)

    def _try_egl(self) -> None:
        import pkgutil
        import warnings
        try:
            loader = pkgutil.get_loader("eglRenderer")
            if loader is None:
                raise RuntimeError("pybullet's eglRenderer module is not installed")
            plugin = pb.loadPlugin(loader.get_filename(), "_eglRendererPlugin", physicsClientId=self.client)
            if plugin < 0:
                raise RuntimeError("loadPlugin returned -1")
        except Exception as exc:  # any failure: keep TinyRenderer
            warnings.warn(f"EGL renderer unavailable ({exc}); falling back to TinyRenderer")
            return
        self.renderer_flag = pb.ER_BULLET_HARDWARE_OPENGL
        self.renderer = "egl"

    @property
    def loaded_plants(self) -> Set[int]:
        """Indices (into farm.plants) of the plants currently in this client."""
        return {i for i in self._bodies if i < self.scene.split.plant_count}

    def _visual_ids(self, idx: int) -> List[int]:
        plant = self.scene.split.instances[idx]
        key = id(plant.model)            # plants sharing a model variant share its visual shapes
        if key not in self._visuals:
            ids = []
            for name in self.scene.material_names:
                mesh = plant.model.meshes.get(name)
                if mesh is None or len(mesh.faces) == 0:
                    ids.append(-1)
                    continue
                ids.append(pb.createVisualShape(
                    pb.GEOM_MESH, vertices=np.asarray(mesh.vertices, float).tolist(),
                    indices=np.asarray(mesh.faces, np.int64).ravel().tolist(),
                    rgbaColor=list(mesh.rgba), specularColor=[0.05, 0.05, 0.05],
                    physicsClientId=self.client))
            self._visuals[key] = ids
        return self._visuals[key]

    def sync(self, wanted_plants: Set[int], hidden_bolls: np.ndarray) -> Tuple[int, int]:
        """Hold the plants in ``wanted_plants`` and their bolls not marked in ``hidden_bolls`` (B,) bool:
        add the bodies that are missing, remove the others.

        Returns (added, removed) counts of bodies.
        """
        split = self.scene.split
        plants = np.array(sorted(wanted_plants), dtype=np.int64)
        bolls, _ = self.scene.visible_bolls(plants, hidden_bolls)
        wanted = set(wanted_plants) | set((split.plant_count + bolls).tolist())
        current = set(self._bodies)
        remove, add = current - wanted, wanted - current
        for idx in remove:
            pb.removeBody(self._bodies.pop(idx), physicsClientId=self.client)
        for idx in sorted(add):
            plant = split.instances[idx]
            vis = self._visual_ids(idx)
            n = len(vis)
            body = pb.createMultiBody(
                baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
                basePosition=[plant.x_m, plant.y_m, 0.0], baseOrientation=yaw_to_quaternion(plant.yaw_rad),
                linkMasses=[0.0] * n, linkCollisionShapeIndices=[-1] * n, linkVisualShapeIndices=vis,
                linkPositions=[[0.0, 0.0, 0.0]] * n, linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
                linkInertialFramePositions=[[0.0, 0.0, 0.0]] * n,
                linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
                linkParentIndices=[0] * n, linkJointTypes=[pb.JOINT_FIXED] * n,
                linkJointAxis=[[0.0, 0.0, 1.0]] * n, physicsClientId=self.client)
            self._bodies[idx] = body
            if body >= len(self.plant_of_body):
                grown = np.full(max(2 * len(self.plant_of_body), body + 1), -1, dtype=np.int32)
                grown[:len(self.plant_of_body)] = self.plant_of_body
                self.plant_of_body = grown
            self.plant_of_body[body] = plant.plant_id
        return len(add), len(remove)

    def close(self) -> None:
        if self.client is not None and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self.client = None
