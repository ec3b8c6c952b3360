#!/usr/bin/env python3
"""Benchmark of the ODE physics alone: ms per step and real-time factor.

Builds the default farm layout (9 rows x 20 plants, rows along world +y,
1.8 m apart, plants 0.7 m apart) from simple primitives -- a stem cylinder
and three canopy boxes per plant, 720 static geoms (independent of
farm/generator.py so the physics cost is measured on its own). Drives the
Husky down a lane (free driving) and into a row (plant contacts) and prints
the cost of one physics step (collision + quickStep + bookkeeping) for each
requested step size.

Each step size runs with merged wheel contacts (one joint per wheel, the
default) and, with --per-point, also with one joint per ODE rim point (the
model before merging), so the two can be compared.

--accuracy prints, instead of timings, what each step size and contact
model does to the motion: straight driving, a spin in place, an arc and a
fast slalom (docs/benchmarks.md compares them).

Usage: python benchmarks/bench_physics.py [--steps-s 0.002 0.005] [--sim-s 5] [--per-point] [--accuracy]
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


def run(step_s: float, sim_s: float, plants, merge: bool = True) -> None:
    world = OdeWorld(PhysicsConfig(step_s=step_s, merge_wheel_contacts=merge))
    t0 = time.perf_counter()
    geoms = world.add_plants(plants)
    build_ms = (time.perf_counter() - t0) * 1e3
    # lane between row 0 (x -2.35) and row 1 (x -4.15): centre x = -3.25
    world.spawn_robot(Pose2D(-3.25, 7.0, math.pi / 2))
    n = int(round(sim_s / step_s))
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(n):
        world.set_command(0.5, 0.0)
        world.step()
    free_ms = (time.perf_counter() - t0) * 1e3 / n
    free_cpu_ms_per_sim_s = (time.process_time() - c0) * 1e3 / sim_s
    # turn towards row 0 and push into the plants
    world.spawn_robot(Pose2D(-3.25, 12.0, 0.0))
    t0 = time.perf_counter()
    for _ in range(n):
        world.set_command(0.5, 0.0)
        world.step()
    contact_ms = (time.perf_counter() - t0) * 1e3 / n
    s = world.robot_state()
    print(f"step {step_s * 1e3:.1f} ms, {'merged' if merge else 'per-point'} wheel contacts | "
          f"{len(plants)} plants, {geoms} geoms (build {build_ms:.0f} ms) | "
          f"free driving {free_ms:.3f} ms/step, RTF {step_s * 1e3 / free_ms:.1f}, "
          f"{free_cpu_ms_per_sim_s:.0f} cpu-ms per sim s | "
          f"pushing into a row {contact_ms:.3f} ms/step, RTF {step_s * 1e3 / contact_ms:.1f}, "
          f"plants touched {len(world.plants_touched)}, robot x {s.position_m[0]:.2f} m")


def accuracy(step_s: float, merge: bool) -> None:
    """Motion figures of one configuration (no timing)."""
    cfg = PhysicsConfig(step_s=step_s, merge_wheel_contacts=merge)

    def world_at(x, y, yaw):
        world = OdeWorld(cfg)
        world.spawn_robot(Pose2D(x, y, yaw))
        return world

    def drive(world, v, w, seconds):
        for _ in range(int(round(seconds / step_s))):
            world.set_command(v, w)
            world.step()

    w = world_at(2.0, -1.0, math.pi / 2)
    w.step_for(0.2)
    p0 = w.robot_state().position_m.copy()
    drive(w, 0.5, 0.0, 10.0)
    w.step_for(1.0)
    p1 = w.robot_state().position_m
    straight = f"straight 10 s at 0.5 m/s: {p1[1] - p0[1]:.4f} m, sideways {1e3 * (p1[0] - p0[0]):.2f} mm"
    w = world_at(0.0, 0.0, 0.0)
    w.step_for(0.2)
    drive(w, 0.0, 1.0, 1.5)
    rates = []
    for _ in range(int(round(1.5 / step_s))):
        drive(w, 0.0, 1.0, step_s)
        rates.append(w.robot_state().angular_velocity_world_rad_s[2])
    spin = (f"spin at 1 rad/s: {np.mean(rates):.4f} rad/s, "
            f"drift {1e3 * np.linalg.norm(w.robot_state().position_m[:2]):.2f} mm")
    w = world_at(1.0, 1.0, 0.3)
    w.step_for(0.5)
    zs = []
    for _ in range(int(round(0.5 / step_s))):
        w.step()
        zs.append(w.robot_state().position_m[2])
    w = world_at(-6.0, 1.0, math.pi / 2)
    drive(w, 0.5, 0.15, 10.0)
    s = w.robot_state()
    arc = f"arc 10 s (0.5 m/s, 0.15 rad/s): end ({s.position_m[0]:.4f}, {s.position_m[1]:.4f}), yaw {s.yaw_rad:.4f}"
    w = world_at(0.0, 0.0, 0.0)
    for k in range(8):
        drive(w, 1.0 if k % 4 != 3 else -1.0, 1.5 if k % 2 else -1.5, 1.0)
    s = w.robot_state()
    slalom = f"slalom 8 s (1 m/s, +/-1.5 rad/s, reversals): end ({s.position_m[0]:.4f}, {s.position_m[1]:.4f})"
    print(f"step {step_s * 1e3:.1f} ms, {'merged' if merge else 'per-point'} wheel contacts:\n  {straight}\n"
          f"  {spin}\n  rest z jitter {np.ptp(zs):.1e} m\n  {arc}\n  {slalom}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps-s", type=float, nargs="+", default=[0.002, 0.005])
    parser.add_argument("--sim-s", type=float, default=5.0, help="simulated seconds per phase")
    parser.add_argument("--per-point", action="store_true",
                        help="also run with one contact joint per ODE rim point (merge_wheel_contacts=False)")
    parser.add_argument("--accuracy", action="store_true", help="print motion figures instead of timings")
    args = parser.parse_args()
    if args.accuracy:
        for step_s in args.steps_s:
            for merge in ((True, False) if args.per_point else (True,)):
                accuracy(step_s, merge)
        return
    print(f"load average {os.getloadavg()[0]:.1f}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}")
    plants = simple_farm()
    for step_s in args.steps_s:
        for merge in ((True, False) if args.per_point else (True,)):
            run(step_s, args.sim_s, plants, merge)


if __name__ == "__main__":
    main()
