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

import math
from dataclasses import dataclass
from typing import Dict, Iterable, List, Sequence, Tuple

import numpy as np

from cottonsim_common.capsules import CapsuleSet

STEM, BRANCH = 0, 1
GRID_CELL_M = 0.5           # the broad phase's grid of stem feet
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
    Each plant's capsules and leaves are contiguous: plant k (in plant_ids order) owns woody
    rows woody_offset[k]:woody_offset[k + 1] and leaf rows leaf_offset[k]:leaf_offset[k + 1].
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
    woody_offset: np.ndarray
    leaf_offset: np.ndarray

    def __post_init__(self) -> None:
        grid: Dict[Tuple[int, int], List[int]] = {}
        for k, (x, y) in enumerate(self.plant_xy_m.tolist()):
            grid.setdefault((math.floor(x / GRID_CELL_M), math.floor(y / GRID_CELL_M)), []).append(k)
        object.__setattr__(self, "_grid", grid)
        object.__setattr__(self, "_plants", list(zip(self.plant_xy_m[:, 0].tolist(), self.plant_xy_m[:, 1].tolist(),
                                                     self.plant_reach_m.tolist(), self.plant_height_m.tolist())))
        object.__setattr__(self, "_max_reach_m", float(self.plant_reach_m.max()) if len(self.plant_reach_m) else 0.0)

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

        woody_counts = [len(wr[2 * k]) + len(wr[2 * k + 1]) for k in range(len(ids))]
        return cls(cat(ws, (0, 3)), cat(we, (0, 3)), cat(wr, (0,)), cat(wp, (0,), np.int64), cat(wk, (0,), np.int8),
                   cat(lc, (0, 3)), cat(lr, (0,)), cat(lp, (0,), np.int64), np.array(ids, dtype=np.int64),
                   np.array(xy, dtype=float).reshape(-1, 2), np.array(reach, dtype=float), np.array(top, dtype=float),
                   np.concatenate([[0], np.cumsum(woody_counts)]).astype(np.int64),
                   np.concatenate([[0], np.cumsum([len(r) for r in lr])]).astype(np.int64))

    def plants_near(self, point_m: Sequence[float], distance_m: float) -> np.ndarray:
        """Ids of the plants whose skeleton may come within distance_m of point_m (world [m])."""
        return self.plant_ids[self.plant_rows_near(point_m, distance_m)]

    def plant_rows_near(self, point_m: Sequence[float], distance_m: float) -> np.ndarray:
        """Like plants_near, but the plants' positions k in plant_ids (for the offsets)."""
        p = np.asarray(point_m, dtype=float).reshape(-1)
        if p.shape not in ((2,), (3,)) or not np.all(np.isfinite(p)) or not distance_m >= 0.0:
            raise ValueError(f"plants_near needs a finite point (x, y[, z]) and a distance >= 0, got {point_m!r}, "
                             f"{distance_m!r}")
        return np.array(self.rows_near(p, float(distance_m)), dtype=np.int64)

    def rows_near(self, point_m: Sequence[float], distance_m: float) -> List[int]:
        """plant_rows_near without the checks of its input (finite (x, y[, z]), a distance >= 0), as a list:
        the stem feet are on a grid of GRID_CELL_M, only the cells within reach are looked at."""
        x, y = float(point_m[0]), float(point_m[1])
        z = float(point_m[2]) if len(point_m) == 3 else -math.inf
        span = distance_m + self._max_reach_m
        rows = []
        grid, plants = self._grid, self._plants
        for i in range(math.floor((x - span) / GRID_CELL_M), math.floor((x + span) / GRID_CELL_M) + 1):
            for j in range(math.floor((y - span) / GRID_CELL_M), math.floor((y + span) / GRID_CELL_M) + 1):
                for k in grid.get((i, j), ()):
                    px, py, reach, height = plants[k]
                    bound = reach + distance_m
                    if (px - x) ** 2 + (py - y) ** 2 <= bound * bound and z <= height + distance_m:
                        rows.append(k)
        return sorted(rows)

    def rows_of(self, plant_rows: Sequence[int]):
        """The woody and leaf row indices (two int arrays) of the plants at positions plant_rows."""
        def gather(offset):
            parts = [np.arange(offset[k], offset[k + 1]) for k in plant_rows]
            return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)

        return gather(self.woody_offset), gather(self.leaf_offset)

    def woody_capsules(self, plant_ids: Sequence[int]) -> CapsuleSet:
        """The stems and branches of the given plants as a CapsuleSet named '<kind>/<plant id>' (world)."""
        sel = np.isin(self.woody_plant, np.asarray(plant_ids, dtype=np.int64))
        names = tuple(f"{WOODY_KIND_NAMES[k]}/{p}" for k, p in zip(self.woody_kind[sel], self.woody_plant[sel]))
        return CapsuleSet(self.woody_start_m[sel], self.woody_end_m[sel], self.woody_radius_m[sel], names)
