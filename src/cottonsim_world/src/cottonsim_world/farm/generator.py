"""Seeded cotton-farm generator: plants in rows, lanes, spawn and default route.

Why: the physics engine, the sensors, the exports and the navigation tests
all need the same farm, reproducibly. ``generate_farm(config)`` is a pure
function of the ``FarmConfig``: the same config (seed included) always gives
an identical farm.

Layout (see ``farm.config``): rows along world +y, numbered east to west;
row r at ``x = first_lane_x_m - row_spacing_m * (r + 0.5)``, lane k at
``x = first_lane_x_m - row_spacing_m * k``. Plant ids are
``row * plants_per_row + index_in_row`` also when some plants are missing.

To save memory and let renderers share meshes, the farm holds only
``plant_variants`` distinct plant models (0 = one per plant); every plant
picks one variant and a random yaw.

Default route: serpentine over the lanes, three waypoints per lane (entry
before the rows, the middle of the rows, exit after the rows); lane 0 is
driven north (+y, yaw +pi/2), lane 1 south (yaw -pi/2), and so on. Labels
follow the original: "<lane>-<k>" on northbound lanes and "O<lane>-<k>" on
southbound (return) lanes, lanes counted from 1 (the original's "010-k" is
written "O10-k" here).
"""
from __future__ import annotations

import math
from typing import List, Tuple

import numpy as np

from cottonsim_common.validation import require_instance
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.model import Farm, Lane, Plant, PlantModel, Pose2D
from cottonsim_world.farm.plant_model import CottonPlantConfig, build_cotton_plant


def generate_farm(config: FarmConfig = FarmConfig()) -> Farm:
    """Build the farm described by ``config`` (deterministic per config)."""
    require_instance("config", config, FarmConfig)
    # Independent random streams, so that e.g. changing missing_plant_fraction
    # does not change the plant shapes.
    layout_ss, models_ss = np.random.SeedSequence(config.seed).spawn(2)
    layout_rng = np.random.default_rng(layout_ss)

    n_total = config.rows * config.plants_per_row
    n_variants = config.plant_variants if config.plant_variants > 0 else n_total
    variants = build_plant_variants(config, n_variants, models_ss)

    # Draw every random quantity for every position (also missing ones), so a
    # plant's draw does not depend on whether an earlier plant is missing.
    jitter = layout_rng.uniform(-config.position_jitter_m, config.position_jitter_m, size=(n_total, 2))
    yaw = layout_rng.uniform(-math.pi, math.pi, size=n_total)
    missing = layout_rng.random(n_total) < config.missing_plant_fraction
    if config.plant_variants > 0:
        choice = layout_rng.integers(0, n_variants, size=n_total)
    else:
        choice = np.arange(n_total)

    plants: List[Plant] = []
    for row in range(config.rows):
        x_row = config.row_x_m(row)
        for i in range(config.plants_per_row):
            pid = row * config.plants_per_row + i
            if missing[pid]:
                continue
            plants.append(Plant(
                plant_id=pid, row=row, index_in_row=i,
                x_m=float(x_row + jitter[pid, 0]),
                y_m=float(config.first_plant_y_m + config.plant_spacing_m * i + jitter[pid, 1]),
                yaw_rad=float(yaw[pid]), model=variants[int(choice[pid])]))

    half_w = 0.5 * config.plant_width_m
    lanes = [Lane(index=k, x_m=config.lane_x_m(k),
                  y_start_m=config.first_plant_y_m - half_w,
                  y_end_m=config.last_plant_y_m + half_w)
             for k in range(config.lane_count)]
    route, labels = default_route(config)
    spawn = Pose2D(config.spawn_x_m, config.spawn_y_m, config.spawn_yaw_rad)
    return Farm(config=config, plants=plants, lanes=lanes, spawn=spawn, route=route, route_labels=labels)


def build_plant_variants(config: FarmConfig, count: int, seed_seq: np.random.SeedSequence) -> List[PlantModel]:
    """``count`` plant models, each from its own child seed of ``seed_seq``.

    Height (with ``height_jitter_fraction``) and boll count are drawn per
    variant; shape details come from the variant's own generator.
    """
    models = []
    for child in seed_seq.spawn(count):
        rng = np.random.default_rng(child)
        f = config.height_jitter_fraction
        height = config.plant_height_m * (1.0 + rng.uniform(-f, f)) if f > 0 else config.plant_height_m
        lo, hi = config.bolls_per_plant
        bolls = int(rng.integers(lo, hi + 1))
        plant_cfg = CottonPlantConfig(
            height_m=height, width_m=config.plant_width_m, boll_count=bolls,
            growth_stage=config.growth_stage, detail=config.plant_detail,
            canopy_base_m=min(0.15, 0.3 * height))
        models.append(build_cotton_plant(plant_cfg, rng))
    return models


def default_route(config: FarmConfig) -> Tuple[List[Pose2D], List[str]]:
    """Serpentine route: 3 waypoints per lane, world frame, with labels."""
    south_stem, north_stem = config.first_plant_y_m, config.last_plant_y_m
    middle = 0.5 * (south_stem + north_stem)
    route: List[Pose2D] = []
    labels: List[str] = []
    for k in range(config.lane_count):
        x = config.lane_x_m(k)
        if k % 2 == 0:     # northbound
            ys = (south_stem - config.route_entry_distance_m, middle, north_stem + config.route_exit_distance_m)
            yaw, prefix = math.pi / 2.0, ""
        else:              # southbound return pass
            ys = (north_stem + config.route_entry_distance_m, middle, south_stem - config.route_exit_distance_m)
            yaw, prefix = -math.pi / 2.0, "O"
        for j, y in enumerate(ys):
            route.append(Pose2D(float(x), float(y), yaw))
            labels.append(f"{prefix}{k + 1}-{j + 1}")
    return route, labels
