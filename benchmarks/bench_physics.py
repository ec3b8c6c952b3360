#!/usr/bin/env python3
"""Benchmark of the ODE physics alone: ms per step and real-time factor.

Builds the default farm layout (9 rows x 20 plants, rows along world +y,
1.8 m apart, plants 0.7 m apart) from simple primitives -- a stem cylinder
and three canopy boxes per plant, 720 static geoms (independent of
farm/generator.py so the physics cost is measured on its own). Drives the
Husky down a lane (free driving) and into a row (plant contacts) and prints
the cost of one physics step (collision + quickStep + bookkeeping) for each
requested step size.

Usage: python benchmarks/bench_physics.py [--steps-s 0.001 0.002 0.005] [--sim-s 10]
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "src", "cottonsim_world", "src"))

import numpy as np  # noqa: E402

from cottonsim_world.farm.model import Plant, PlantModel, Pose2D, Primitive  # noqa: E402
from cottonsim_world.physics.ode_world import OdeWorld, PhysicsConfig  # noqa: E402


def simple_farm(rows: int = 9, per_row: int = 20, row_spacing_m: float = 1.8, plant_spacing_m: float = 0.7):
    """Plants of the default layout with 4 collision primitives each."""
    identity = (0.0, 0.0, 0.0, 1.0)
    prims = [Primitive("cylinder", (0.0, 0.0, 0.5), identity, (0.02, 1.0), "stem")]
    for k, (dx, dy) in enumerate(((0.15, 0.0), (-0.1, 0.13), (-0.1, -0.13))):
        prims.append(Primitive("box", (dx, dy, 0.55), identity, (0.15, 0.15, 0.3), f"leaves_{k}"))
    model = PlantModel(meshes={}, collision=prims, boll_centres=np.zeros((0, 3)), boll_radii=np.zeros(0),
                       height_m=1.0, width_m=0.7)
    plants = []
    for r in range(rows):
        for i in range(per_row):
            plants.append(Plant(plant_id=r * per_row + i, row=r, index_in_row=i,
                                x_m=-2.35 - r * row_spacing_m, y_m=9.0 + i * plant_spacing_m,
                                yaw_rad=0.37 * (r * per_row + i), model=model))
    return plants


def run(step_s: float, sim_s: float, plants) -> None:
    world = OdeWorld(PhysicsConfig(step_s=step_s))
    t0 = time.perf_counter()
    geoms = world.add_plants(plants)
    build_ms = (time.perf_counter() - t0) * 1e3
    # lane between row 0 (x -2.35) and row 1 (x -4.15): centre x = -3.25
    world.spawn_robot(Pose2D(-3.25, 7.0, math.pi / 2))
    n = int(round(sim_s / step_s))
    t0 = time.perf_counter()
    for _ in range(n):
        world.set_command(0.5, 0.0)
        world.step()
    free_ms = (time.perf_counter() - t0) * 1e3 / n
    # turn towards row 0 and push into the plants
    world.spawn_robot(Pose2D(-3.25, 12.0, 0.0))
    t0 = time.perf_counter()
    for _ in range(n):
        world.set_command(0.5, 0.0)
        world.step()
    contact_ms = (time.perf_counter() - t0) * 1e3 / n
    s = world.robot_state()
    print(f"step {step_s * 1e3:.1f} ms | {len(plants)} plants, {geoms} geoms (build {build_ms:.0f} ms) | "
          f"free driving {free_ms:.3f} ms/step, RTF {step_s * 1e3 / free_ms:.1f} | "
          f"pushing into a row {contact_ms:.3f} ms/step, RTF {step_s * 1e3 / contact_ms:.1f}, "
          f"plants touched {len(world.plants_touched)}, robot x {s.position_m[0]:.2f} m")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps-s", type=float, nargs="+", default=[0.001, 0.002, 0.005])
    parser.add_argument("--sim-s", type=float, default=5.0, help="simulated seconds per phase")
    args = parser.parse_args()
    plants = simple_farm()
    for step_s in args.steps_s:
        run(step_s, args.sim_s, plants)


if __name__ == "__main__":
    main()
