"""Data types shared by the farm generator, the physics engine and the sensors.

This module is the contract between farm generation (``farm.generator``,
``farm.plant_model``), dynamics (``physics``) and rendering / ray casting
(``sensors``). It holds plain data only: numpy arrays and frozen dataclasses,
no behaviour beyond small conveniences.

Frames and units
----------------
* world: ground truth frame, z up, ground plane at z = 0 [m]. Rows of the
  default farm run along world +y (REP-103 right-handed).
* plant-local: origin at the stem's foot on the ground, z up, x/y rotated by
  the plant's yaw about z.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from cottonsim_common.pose import Pose2D  # noqa: F401  (the farm's poses; imported from here by the simulator)


class SemanticClass(enum.IntEnum):
    """Per-pixel ground-truth classes.

    The first three follow the original CottonSim segmentation dataset
    (0 cotton plants, 1 ground, 2 sky); BOLL marks boll pixels, which belong
    to the 'cotton plants' class for scene segmentation and to the single
    detection class (0 cotton boll) for boll detection.
    """

    PLANT = 0
    GROUND = 1
    SKY = 2
    BOLL = 3


@dataclass(frozen=True)
class TriangleMesh:
    """An indexed triangle mesh with one colour.

    vertices: (N, 3) float32 [m]; faces: (M, 3) int32 vertex indices,
    counter-clockwise seen from outside.
    """

    vertices: np.ndarray
    faces: np.ndarray
    rgba: Tuple[float, float, float, float]
    semantic: SemanticClass

    @property
    def triangle_count(self) -> int:
        return int(self.faces.shape[0])


@dataclass(frozen=True)
class Primitive:
    """A simple collision shape in plant-local (or world) coordinates.

    shape: 'box' (size = half extents x, y, z), 'cylinder' (size = radius,
    length; axis along local z), 'capsule' (radius, length of the straight
    part; axis along z) or 'sphere' (size = (radius,)).
    position [m]; orientation as quaternion (x, y, z, w).
    """

    shape: str
    position: Tuple[float, float, float]
    orientation: Tuple[float, float, float, float]
    size: Tuple[float, ...]
    name: str = ""


@dataclass(frozen=True)
class PlantSkeleton:
    """What the arm may touch on a plant, in plant-local coordinates [m].

    Woody parts (collision geometry for the arm): the main stem's segments
    stem_start_m / stem_end_m (S, 3) with radii stem_radius_m (S,), and the
    main (fruiting) branches' segments branch_start_m / branch_end_m (B, 3)
    with branch_radius_m (B,). Soft parts: every leaf blade as a sphere
    leaf_centre_m (L, 3), leaf_radius_m (L,) round the blade.
    """

    stem_start_m: np.ndarray
    stem_end_m: np.ndarray
    stem_radius_m: np.ndarray
    branch_start_m: np.ndarray
    branch_end_m: np.ndarray
    branch_radius_m: np.ndarray
    leaf_centre_m: np.ndarray
    leaf_radius_m: np.ndarray


@dataclass(frozen=True)
class PlantModel:
    """Geometry of one cotton plant in plant-local coordinates.

    meshes: material name -> mesh ('stem', 'leaf', 'dead_leaf', 'boll', ...).
    collision: the parts the robot collides with (branches, leaves), as
    simple primitives; used by the physics engine and the LiDAR ray caster.
    boll_centres: (B, 3) float [m]; boll_radii: (B,) float [m].
    skeleton: stems, branches and leaves for the arm's contacts (None: a
    plant without one, e.g. a stand-in; the arm then touches nothing of it).
    """

    meshes: Dict[str, TriangleMesh]
    collision: List[Primitive]
    boll_centres: np.ndarray
    boll_radii: np.ndarray
    height_m: float
    width_m: float
    skeleton: Optional[PlantSkeleton] = None


@dataclass(frozen=True)
class Plant:
    """One plant placed in the farm."""

    plant_id: int          # row * plants_per_row + index_in_row
    row: int               # 0 = first row (east-most, nearest the spawn's lane order)
    index_in_row: int      # 0 = south end (smallest world y)
    x_m: float             # stem foot, world frame [m]
    y_m: float
    yaw_rad: float         # rotation of the plant model about z [rad]
    model: PlantModel

    def boll_centres_world(self) -> np.ndarray:
        """Boll centres in the world frame, (B, 3) [m]."""
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)
        local = self.model.boll_centres
        out = np.empty_like(local, dtype=float)
        out[:, 0] = self.x_m + c * local[:, 0] - s * local[:, 1]
        out[:, 1] = self.y_m + s * local[:, 0] + c * local[:, 1]
        out[:, 2] = local[:, 2]
        return out


@dataclass(frozen=True)
class Lane:
    """A driving lane between (or beside) two plant rows, along world y."""

    index: int             # 0 = first lane driven (east-most)
    x_m: float             # centre line, world x [m]
    y_start_m: float       # south end of the plants beside the lane [m]
    y_end_m: float         # north end [m]


@dataclass
class Farm:
    """A generated farm: plants, lanes, the robot's spawn pose and route."""

    config: object                          # the FarmConfig it was made from
    plants: List[Plant]
    lanes: List[Lane]
    spawn: Pose2D                           # robot 'Home' pose, world frame
    route: List[Pose2D] = field(default_factory=list)   # default waypoint route, world frame
    route_labels: List[str] = field(default_factory=list)

    def plant_positions(self) -> np.ndarray:
        """(P, 2) stem positions, world x/y [m]."""
        return np.array([[p.x_m, p.y_m] for p in self.plants], dtype=float).reshape(-1, 2)
