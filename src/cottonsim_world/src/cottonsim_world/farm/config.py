"""Configuration of the procedural cotton farm (``FarmConfig``).

Why: the farm generator, the exports and the CLI all need one validated,
immutable description of the farm. The defaults reproduce the CottonSim
paper's farm (9 rows x 20 plants, 1.8 m row spacing, 0.7 m plant spacing,
1.0 m tall and 0.7 m wide plants) placed where the original Gazebo world had
it: the lane positions are fitted to the original's GPS waypoints (see
``test_farm_generator.py::test_default_lanes_fit_original_waypoints``).

World layout (all lengths in metres, angles in radians):

* rows run along world +y; lanes and rows are numbered from east (largest
  world x) to west;
* lane k centre line: ``x = first_lane_x_m - row_spacing_m * k``
  (``rows + 1`` lanes: two outer lanes and one between each pair of rows);
* row r centre line: ``x = first_lane_x_m - row_spacing_m * (r + 0.5)``;
* plant i of a row stands at ``y = first_plant_y_m + plant_spacing_m * i``.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any, Dict, Mapping, Tuple

from cottonsim_common.validation import require_bool

GROWTH_STAGES = ("cutout", "defoliated")
PLANT_DETAILS = ("high", "low")


@dataclass(frozen=True)
class FarmConfig:
    """Every parameter of a generated farm; defaults = the paper's farm.

    Geometry
        rows, plants_per_row: counts (>= 1).
        row_spacing_m: distance between neighbouring row centre lines [m].
        plant_spacing_m: distance between neighbouring stems in a row [m].
        plant_height_m, plant_width_m: nominal plant size [m] (canopy
            diameter = width).
        first_lane_x_m: world x of lane 0's centre line (the east-most lane)
            [m]; fitted to the original's GPS waypoints.
        first_plant_y_m: world y of the south-most stems [m]; the default
            makes the stems span 8.95 .. 22.25 m like the original.
    Randomness (all drawn from ``seed``)
        position_jitter_m: each stem is moved by a uniform offset in
            [-jitter, +jitter] along x and along y [m].
        height_jitter_fraction: plant height = nominal * (1 + u),
            u uniform in [-f, +f] (drawn per plant model variant).
        missing_plant_fraction: probability that a plant position is empty.
        bolls_per_plant: (min, max) open bolls per plant, inclusive.
        growth_stage: 'cutout' (leafy, bolls open) or 'defoliated' (no green
            leaves, a few dead ones, bolls fully exposed).
        plant_detail: 'high' (~1,500-4,000 triangles per plant) or 'low'
            (a few hundred triangles, for far plants / fast renderers).
        plant_variants: number of distinct plant models shared by the farm
            (each plant picks one with a random yaw); 0 = one model per plant.
        seed: seed of every random draw; same config -> identical farm.
    Robot and route
        robot_width_m: width of the robot that must fit in a lane [m].
        lane_clearance_margin_m: extra free width required in a lane beyond
            the robot's width (both sides together) [m].
        require_lane_fit: refuse a farm whose lanes are narrower than
            robot_width_m + lane_clearance_margin_m (default). Studies of
            narrow spacings (the paper's Fig. 3a row-spacing test) switch it
            off to build farms the robot is expected to fail in.
        spawn_x_m, spawn_y_m, spawn_yaw_rad: the robot's 'Home' pose, world.
        route_entry_distance_m: how far before the first stem of a lane (in
            the direction of travel) a lane's first waypoint lies [m].
        route_exit_distance_m: how far beyond the last stem of a lane its
            last waypoint lies [m].
    """

    rows: int = 9
    plants_per_row: int = 20
    row_spacing_m: float = 1.8
    plant_spacing_m: float = 0.7
    plant_height_m: float = 1.0
    plant_width_m: float = 0.7
    first_lane_x_m: float = -1.43
    first_plant_y_m: float = 8.95
    position_jitter_m: float = 0.0
    height_jitter_fraction: float = 0.0
    missing_plant_fraction: float = 0.0
    bolls_per_plant: Tuple[int, int] = (8, 16)
    growth_stage: str = "cutout"
    plant_detail: str = "high"
    plant_variants: int = 8
    robot_width_m: float = 0.67
    lane_clearance_margin_m: float = 0.1
    require_lane_fit: bool = True
    seed: int = 0
    spawn_x_m: float = -6.0
    spawn_y_m: float = 1.0
    spawn_yaw_rad: float = math.pi / 2.0
    route_entry_distance_m: float = 4.0
    route_exit_distance_m: float = 4.0

    def __post_init__(self) -> None:
        # bolls_per_plant may arrive as a list from YAML: normalise first.
        bolls = self.bolls_per_plant
        if not isinstance(bolls, (tuple, list)) or len(bolls) != 2:
            raise ValueError(f"bolls_per_plant must be a pair (min, max), got {bolls!r}")
        if any(isinstance(b, bool) or not _is_int(b) for b in bolls):
            raise ValueError(f"bolls_per_plant must hold integers, got {bolls!r}")
        object.__setattr__(self, "bolls_per_plant", (int(bolls[0]), int(bolls[1])))

        require_bool("require_lane_fit", self.require_lane_fit)
        for name in ("rows", "plants_per_row", "plant_variants", "seed"):
            value = getattr(self, name)
            if isinstance(value, bool) or not _is_int(value):
                raise ValueError(f"{name} must be an integer, got {value!r}")
            object.__setattr__(self, name, int(value))
        for f in fields(self):
            if f.name in ("rows", "plants_per_row", "plant_variants", "seed",
                          "bolls_per_plant", "growth_stage", "plant_detail", "require_lane_fit"):
                continue
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{f.name} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"{f.name} must be finite, got {value!r}")
            object.__setattr__(self, f.name, float(value))

        if self.rows < 1:
            raise ValueError(f"rows must be >= 1, got {self.rows}")
        if self.plants_per_row < 1:
            raise ValueError(f"plants_per_row must be >= 1, got {self.plants_per_row}")
        if self.plant_variants < 0:
            raise ValueError(f"plant_variants must be >= 0 (0 = one model per plant), got {self.plant_variants}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")
        for name in ("row_spacing_m", "plant_spacing_m", "plant_height_m", "plant_width_m",
                     "robot_width_m"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.plant_height_m > 5.0:
            raise ValueError(f"plant_height_m must be <= 5 m (a cotton plant), got {self.plant_height_m}")
        if self.plant_width_m > 3.0:
            raise ValueError(f"plant_width_m must be <= 3 m, got {self.plant_width_m}")
        if self.lane_clearance_margin_m < 0.0:
            raise ValueError(f"lane_clearance_margin_m must be >= 0, got {self.lane_clearance_margin_m}")
        if self.position_jitter_m < 0.0:
            raise ValueError(f"position_jitter_m must be >= 0, got {self.position_jitter_m}")
        if self.position_jitter_m > 0.25 * self.plant_spacing_m:
            raise ValueError(
                f"position_jitter_m={self.position_jitter_m} is too large: at most a quarter of "
                f"plant_spacing_m ({0.25 * self.plant_spacing_m:.3f} m) keeps plants in order")
        if not 0.0 <= self.height_jitter_fraction <= 0.5:
            raise ValueError(f"height_jitter_fraction must be in [0, 0.5], got {self.height_jitter_fraction}")
        if not 0.0 <= self.missing_plant_fraction < 1.0:
            raise ValueError(f"missing_plant_fraction must be in [0, 1), got {self.missing_plant_fraction}")
        lo, hi = self.bolls_per_plant
        if lo < 0 or hi < lo or hi > 60:
            raise ValueError(f"bolls_per_plant must satisfy 0 <= min <= max <= 60, got {self.bolls_per_plant}")
        if self.growth_stage not in GROWTH_STAGES:
            raise ValueError(f"growth_stage must be one of {GROWTH_STAGES}, got {self.growth_stage!r}")
        if self.plant_detail not in PLANT_DETAILS:
            raise ValueError(f"plant_detail must be one of {PLANT_DETAILS}, got {self.plant_detail!r}")
        if self.route_entry_distance_m <= 0.0:
            raise ValueError(f"route_entry_distance_m must be > 0, got {self.route_entry_distance_m}")
        if self.route_exit_distance_m <= 0.0:
            raise ValueError(f"route_exit_distance_m must be > 0, got {self.route_exit_distance_m}")

        # Lane clearance: the free strip between two canopies (shrunk by the
        # position jitter on both sides) must take the robot plus a margin.
        free = self.free_lane_width_m
        needed = self.robot_width_m + self.lane_clearance_margin_m
        if self.require_lane_fit and free < needed:
            raise ValueError(
                f"row_spacing_m={self.row_spacing_m} leaves a free lane of {free:.3f} m "
                f"(row_spacing_m - plant_width_m - 2 * position_jitter_m), narrower than "
                f"robot_width_m + lane_clearance_margin_m = {needed:.3f} m")

    # ------------------------------------------------------------------ derived
    @property
    def free_lane_width_m(self) -> float:
        """Worst-case free width of a lane between two canopies [m]."""
        return self.row_spacing_m - self.plant_width_m - 2.0 * self.position_jitter_m

    @property
    def lane_count(self) -> int:
        """Number of driving lanes: two outer lanes and one between rows."""
        return self.rows + 1

    def lane_x_m(self, lane: int) -> float:
        """World x of lane ``lane``'s centre line [m] (lane 0 = east-most)."""
        return self.first_lane_x_m - self.row_spacing_m * lane

    def row_x_m(self, row: int) -> float:
        """World x of row ``row``'s centre line [m] (row 0 = east-most)."""
        return self.first_lane_x_m - self.row_spacing_m * (row + 0.5)

    @property
    def last_plant_y_m(self) -> float:
        """World y of the north-most stems [m]."""
        return self.first_plant_y_m + self.plant_spacing_m * (self.plants_per_row - 1)

    # --------------------------------------------------------------- (de)serial
    def to_dict(self) -> Dict[str, Any]:
        """Plain dict (YAML / JSON friendly: tuples become lists)."""
        out = asdict(self)
        out["bolls_per_plant"] = list(self.bolls_per_plant)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "FarmConfig":
        """Build from a mapping (e.g. loaded YAML); unknown keys raise ValueError.

        A top-level ``farm:`` section is accepted as well as a flat mapping.
        Missing keys keep their defaults.
        """
        if data is None:
            return cls()
        if not isinstance(data, Mapping):
            raise ValueError(f"farm config must be a mapping, got {type(data).__name__}")
        if set(data.keys()) == {"farm"} and isinstance(data["farm"], Mapping):
            data = data["farm"]
        known = {f.name for f in fields(cls)}
        unknown = sorted(str(k) for k in data.keys() if k not in known)
        if unknown:
            raise ValueError(f"unknown farm config key(s): {', '.join(unknown)}; known keys: {', '.join(sorted(known))}")
        return cls(**dict(data))


def _is_int(value: Any) -> bool:
    if isinstance(value, int):
        return True
    if isinstance(value, float) and value.is_integer():
        return True
    try:
        import numpy as np
        return isinstance(value, np.integer)
    except ImportError:  # pragma: no cover
        return False
