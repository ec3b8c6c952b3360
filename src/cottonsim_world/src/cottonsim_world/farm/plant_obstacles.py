"""Every plant's stems, branches and leaves in the world frame: what the arm can touch.

``PlantObstacles.from_farm`` places each plant's skeleton (``farm.model.PlantSkeleton``,
plant-local) in the world: woody capsules (the main stem's segments and the
main branches', kind STEM or BRANCH) and leaf spheres, each with its plant's
id. ``plants_near`` is the broad phase: the plants whose skeleton can come
within a distance of a point (a plant's bound is a vertical cylinder round
its stem foot). The arm-plant contact counter (robot/arm_contacts.py) and
the harvest evaluation's reachability (cottonsim_experiments) read it.
World frame: z up, ground at z = 0 [m].
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from cottonsim_common.capsules import CapsuleSet

STEM, BRANCH = 0, 1
WOODY_KIND_NAMES = ("stem", "branch")


def _rotate_about_z(points: np.ndarray, yaw_rad: float, x_m: float, y_m: float) -> np.ndarray:
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    out = np.empty_like(points, dtype=float)
    out[:, 0] = x_m + c * points[:, 0] - s * points[:, 1]
    out[:, 1] = y_m + s * points[:, 0] + c * points[:, 1]
    out[:, 2] = points[:, 2]
    return out


@dataclass(frozen=True)
class PlantObstacles:
    """Woody capsules and leaf spheres of a farm's plants, world frame [m] (see the module docstring).

    woody_start_m, woody_end_m (N, 3), woody_radius_m (N,), woody_plant (N,) plant ids,
    woody_kind (N,) STEM or BRANCH; leaf_centre_m (L, 3), leaf_radius_m (L,), leaf_plant (L,);
    plant_ids (P,), plant_xy_m (P, 2) stem feet, plant_reach_m (P,) horizontal bound of each
    plant's skeleton round its stem foot, plant_height_m (P,) the top of its skeleton.
    """

    woody_start_m: np.ndarray
    woody_end_m: np.ndarray
    woody_radius_m: np.ndarray
    woody_plant: np.ndarray
    woody_kind: np.ndarray
    leaf_centre_m: np.ndarray
    leaf_radius_m: np.ndarray
    leaf_plant: np.ndarray
    plant_ids: np.ndarray
    plant_xy_m: np.ndarray
    plant_reach_m: np.ndarray
    plant_height_m: np.ndarray

    @classmethod
    def from_farm(cls, farm) -> "PlantObstacles":
        """From a ``farm.model.Farm`` (or any object with ``plants``); plants without a skeleton add nothing."""
        if not hasattr(farm, "plants"):
            raise ValueError("farm must be a farm.model.Farm (it has no 'plants')")
        return cls.from_plants(farm.plants)

    @classmethod
    def from_plants(cls, plants: Iterable) -> "PlantObstacles":
        ws, we, wr, wp, wk, lc, lr, lp, ids, xy, reach, top = ([] for _ in range(12))
        for plant in plants:
            sk = plant.model.skeleton
            if sk is None:
                continue
            place = (plant.yaw_rad, plant.x_m, plant.y_m)
            for kind, (start, end, radius) in enumerate(((sk.stem_start_m, sk.stem_end_m, sk.stem_radius_m),
                                                         (sk.branch_start_m, sk.branch_end_m, sk.branch_radius_m))):
                ws.append(_rotate_about_z(np.asarray(start, float).reshape(-1, 3), *place))
                we.append(_rotate_about_z(np.asarray(end, float).reshape(-1, 3), *place))
                wr.append(np.asarray(radius, float).reshape(-1))
                wp.append(np.full(len(wr[-1]), plant.plant_id, dtype=np.int64))
                wk.append(np.full(len(wr[-1]), kind, dtype=np.int8))
            lc.append(_rotate_about_z(np.asarray(sk.leaf_centre_m, float).reshape(-1, 3), *place))
            lr.append(np.asarray(sk.leaf_radius_m, float).reshape(-1))
            lp.append(np.full(len(lr[-1]), plant.plant_id, dtype=np.int64))
            local = np.concatenate([sk.stem_start_m, sk.stem_end_m, sk.branch_start_m, sk.branch_end_m]).reshape(-1, 3)
            ext = np.concatenate([np.hypot(local[:, 0], local[:, 1]),
                                  np.hypot(sk.leaf_centre_m[:, 0], sk.leaf_centre_m[:, 1]) + sk.leaf_radius_m])
            ids.append(plant.plant_id)
            xy.append((plant.x_m, plant.y_m))
            reach.append(float(ext.max()) if len(ext) else 0.0)
            top.append(float(max(local[:, 2].max() if len(local) else 0.0,
                                 (sk.leaf_centre_m[:, 2] + sk.leaf_radius_m).max() if len(sk.leaf_radius_m) else 0.0)))

        def cat(parts, shape, dtype=float):
            return np.concatenate(parts).astype(dtype) if parts else np.zeros(shape, dtype)

        return cls(cat(ws, (0, 3)), cat(we, (0, 3)), cat(wr, (0,)), cat(wp, (0,), np.int64), cat(wk, (0,), np.int8),
                   cat(lc, (0, 3)), cat(lr, (0,)), cat(lp, (0,), np.int64), np.array(ids, dtype=np.int64),
                   np.array(xy, dtype=float).reshape(-1, 2), np.array(reach, dtype=float), np.array(top, dtype=float))

    def plants_near(self, point_m: Sequence[float], distance_m: float) -> np.ndarray:
        """Ids of the plants whose skeleton may come within distance_m of point_m (world [m])."""
        p = np.asarray(point_m, dtype=float).reshape(-1)
        if p.shape not in ((2,), (3,)) or not np.all(np.isfinite(p)) or not distance_m >= 0.0:
            raise ValueError(f"plants_near needs a finite point (x, y[, z]) and a distance >= 0, got {point_m!r}, "
                             f"{distance_m!r}")
        d = np.hypot(self.plant_xy_m[:, 0] - p[0], self.plant_xy_m[:, 1] - p[1])
        near = d <= self.plant_reach_m + distance_m
        if p.shape == (3,):
            near &= p[2] <= self.plant_height_m + distance_m
        return self.plant_ids[near]

    def woody_capsules(self, plant_ids: Sequence[int]) -> CapsuleSet:
        """The stems and branches of the given plants as a CapsuleSet named '<kind>/<plant id>' (world)."""
        sel = np.isin(self.woody_plant, np.asarray(plant_ids, dtype=np.int64))
        names = tuple(f"{WOODY_KIND_NAMES[k]}/{p}" for k, p in zip(self.woody_kind[sel], self.woody_plant[sel]))
        return CapsuleSet(self.woody_start_m[sel], self.woody_end_m[sel], self.woody_radius_m[sel], names)
