"""Stand-in plants and farms of simple shapes, for sensor tests and benchmarks.

A stand-in plant is a stem cylinder, a canopy sphere and a few boll
spheres, with the collision primitives the real models have: cheap to build
and easy to reason about (where a ray must hit, what a pixel must show),
unlike the procedural cotton plants of ``farm.plant_model``.
"""
from __future__ import annotations

import math
from typing import Mapping, Optional, Sequence, Tuple

import numpy as np

from cottonsim_world.farm.model import Farm, Lane, Plant, PlantModel, Pose2D, Primitive, SemanticClass, TriangleMesh


def _cylinder_mesh(radius: float, z0: float, z1: float, segments: int = 12) -> Tuple[np.ndarray, np.ndarray]:
    ang = np.linspace(0.0, 2 * math.pi, segments, endpoint=False)
    ring = np.stack([radius * np.cos(ang), radius * np.sin(ang)], axis=1)
    verts = np.concatenate([np.c_[ring, np.full(segments, z0)], np.c_[ring, np.full(segments, z1)],
                            [[0.0, 0.0, z0], [0.0, 0.0, z1]]])
    faces = []
    for i in range(segments):
        j = (i + 1) % segments
        faces += [[i, j, segments + j], [i, segments + j, segments + i],
                  [2 * segments, j, i], [2 * segments + 1, segments + i, segments + j]]
    return verts, np.array(faces)


def _sphere_mesh(radius: float, centre: Sequence[float], rings: int = 5, segments: int = 8
                 ) -> Tuple[np.ndarray, np.ndarray]:
    verts = [[0.0, 0.0, radius]]
    for i in range(1, rings):
        th = math.pi * i / rings
        for j in range(segments):
            ph = 2 * math.pi * j / segments
            verts.append([radius * math.sin(th) * math.cos(ph), radius * math.sin(th) * math.sin(ph),
                          radius * math.cos(th)])
    verts.append([0.0, 0.0, -radius])
    faces = []
    for j in range(segments):
        faces.append([0, 1 + j, 1 + (j + 1) % segments])
    for i in range(rings - 2):
        a, b = 1 + i * segments, 1 + (i + 1) * segments
        for j in range(segments):
            k = (j + 1) % segments
            faces += [[a + j, b + j, b + k], [a + j, b + k, a + k]]
    last, a = len(verts) - 1, 1 + (rings - 2) * segments
    for j in range(segments):
        faces.append([a + j, last, a + (j + 1) % segments])
    return np.asarray(verts) + np.asarray(centre, float), np.array(faces)


def standin_plant_model(seed: int = 0, height_m: float = 1.0, width_m: float = 0.7,
                        bolls: int = 8) -> PlantModel:
    """A simple plant for tests and benchmarks when farm.plant_model is absent.

    A thin brown stem, a green cylindrical canopy from 0.25 m to the top and
    white spheres (bolls) on the canopy surface.
    """
    rng = np.random.default_rng(seed)
    sv, sf = _cylinder_mesh(0.015, 0.0, height_m, 6)
    cv_, cf = _cylinder_mesh(width_m / 2, 0.25 * height_m, height_m, 12)
    radii = np.full(bolls, 0.035)
    ang = rng.uniform(0, 2 * math.pi, bolls)
    zs = rng.uniform(0.35 * height_m, 0.95 * height_m, bolls)
    centres = np.stack([(width_m / 2 + 0.01) * np.cos(ang), (width_m / 2 + 0.01) * np.sin(ang), zs], axis=1)
    bv, bf = [], []
    for c in centres:
        v, f = _sphere_mesh(0.035, c)
        bf.append(f + sum(len(x) for x in bv))
        bv.append(v)
    meshes = {
        "stem": TriangleMesh(sv.astype(np.float32), sf.astype(np.int32), (0.42, 0.30, 0.18, 1.0), SemanticClass.PLANT),
        "leaf": TriangleMesh(cv_.astype(np.float32), cf.astype(np.int32), (0.20, 0.50, 0.16, 1.0), SemanticClass.PLANT),
    }
    if bolls:
        meshes["boll"] = TriangleMesh(np.concatenate(bv).astype(np.float32), np.concatenate(bf).astype(np.int32),
                                      (0.96, 0.96, 0.94, 1.0), SemanticClass.BOLL)
    collision = [Primitive("cylinder", (0.0, 0.0, 0.5 * height_m), (0.0, 0.0, 0.0, 1.0), (0.015, height_m), "stem"),
                 Primitive("cylinder", (0.0, 0.0, 0.625 * height_m), (0.0, 0.0, 0.0, 1.0),
                           (width_m / 2, 0.75 * height_m), "canopy")]
    return PlantModel(meshes=meshes, collision=collision, boll_centres=centres, boll_radii=radii,
                      height_m=height_m, width_m=width_m)


def standin_farm(rows: int = 9, plants_per_row: int = 20, row_spacing_m: float = 1.8,
                 plant_spacing_m: float = 0.7, first_row_x_m: float = -2.35, first_plant_y_m: float = 9.0,
                 models: Optional[Mapping[int, PlantModel]] = None) -> Farm:
    """A farm laid out like the default one (rows along +y, first row east-most).

    Uses ``standin_plant_model`` (4 variants) unless ``models`` maps plant
    ids to models. Lanes lie midway between rows and outside the outer rows.
    """
    variants = [standin_plant_model(seed=s) for s in range(4)]
    plants = []
    for r in range(rows):
        for i in range(plants_per_row):
            pid = r * plants_per_row + i
            model = models[pid] if models is not None and pid in models else variants[pid % 4]
            plants.append(Plant(pid, r, i, first_row_x_m - r * row_spacing_m, first_plant_y_m + i * plant_spacing_m,
                                (pid * 1.3) % (2 * math.pi), model))
    y_end = first_plant_y_m + (plants_per_row - 1) * plant_spacing_m
    lanes = [Lane(k, first_row_x_m + row_spacing_m / 2 - k * row_spacing_m, first_plant_y_m, y_end)
             for k in range(rows + 1)]
    return Farm(config=None, plants=plants, lanes=lanes, spawn=Pose2D(-6.0, 1.0, math.pi / 2))
