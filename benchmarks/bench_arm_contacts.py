#!/usr/bin/env python3
"""Cost of counting the arm's contacts with the plants (robot/arm_contacts.py) per physics step.

Run:  source scripts/env.sh && OMP_NUM_THREADS=1 python benchmarks/bench_arm_contacts.py
Two measures on the default farm (9 x 20 plants):
* the counter alone: one check (link capsules from FK through SimulatedArm, broad phase, narrow phase)
  with the robot in the middle of lane 1 and the arm (a) stowed over the base, (b) reaching into
  the plants beside the lane (random joints that put the nozzle among them);
* the simulator core without cameras and LiDAR (physics, IMU, GPS, odometry, arm) driving along
  the lane, counter on against off, alternated (A/B) over several pairs: CPU per sim second.
Prints medians, the machine, its load average and the commit.

On a shared machine CPU time is noisy; instruction counts are not. --callgrind on|off runs one
simulator run (counter on or off) with callgrind's instrumentation on for the timed loop only:
  valgrind --tool=callgrind --instr-atstart=no python benchmarks/bench_arm_contacts.py \
      --callgrind on --seconds 1        # "Collected : N" = instructions
"""
import argparse
import os
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np

from bench_manipulation import machine  # noqa: E402  (this folder: the machine, load and commit line)

ROOT = Path(__file__).resolve().parents[1]
URDF = ROOT / "src/cottonsim_description/urdf/cottonsim_robot.urdf"


def bench_counter(repeats):
    from cottonsim_common.pose import Pose2D
    from cottonsim_common.transforms import pose_matrix
    from cottonsim_world.farm.config import FarmConfig
    from cottonsim_world.farm.generator import generate_farm
    from cottonsim_world.farm.plant_obstacles import PlantObstacles
    from cottonsim_world.robot.arm_contacts import ArmContactConfig, ArmContactCounter
    from cottonsim_world.robot.arm_tracker import ArmControllerConfig
    from cottonsim_world.robot.boll_store import BollFieldStore
    from cottonsim_world.robot.sim_arm import SimulatedArm
    from cottonsim_world.robot.urdf_model import UrdfModel
    from cottonsim_world.robot.vacuum import VacuumConfig

    farm = generate_farm(FarmConfig())
    obstacles = PlantObstacles.from_farm(farm)
    print(f"farm: {len(farm.plants)} plants, {len(obstacles.woody_radius_m)} woody capsules, "
          f"{len(obstacles.leaf_radius_m)} leaf spheres")
    lane = farm.lanes[1]
    pose = Pose2D(lane.x_m, 0.5 * (lane.y_start_m + lane.y_end_m), np.pi / 2)
    world_T_base = pose_matrix((pose.x_m, pose.y_m, 0.13228), (0.0, 0.0, np.sin(pose.yaw_rad / 2),
                                                                np.cos(pose.yaw_rad / 2)))
    urdf = UrdfModel.from_file(URDF)
    rng = np.random.default_rng(0)
    stow = [0.0, -2.2, 2.4, -1.77, -1.57, 0.0]
    reaching = []
    probe = SimulatedArm(urdf, "ur5e_", stow, ArmControllerConfig(), VacuumConfig(), BollFieldStore.of_plants([]))
    while len(reaching) < 50:
        q = rng.uniform([-np.pi, -2.5, -2.5, -np.pi, -np.pi, -np.pi], [np.pi, -0.3, 2.5, np.pi, np.pi, np.pi])
        probe.arm._positions = q
        tip = probe.tip_pose(world_T_base)[:3, 3]
        if abs(abs(tip[0] - lane.x_m) - 0.7) < 0.25 and 0.2 < tip[2] < 0.9:
            reaching.append(q)
    for name, configs in (("stowed", [stow]), ("reaching into the plants", reaching)):
        counter = ArmContactCounter(obstacles, ArmContactConfig())
        arm = SimulatedArm(urdf, "ur5e_", stow, ArmControllerConfig(), VacuumConfig(), BollFieldStore.of_plants([]),
                           "base_link", counter)
        wall, cpu = [], []
        for k in range(repeats):
            arm.arm._positions = np.asarray(configs[k % len(configs)], dtype=float)
            t, c = time.perf_counter(), time.process_time()
            counter.update(0.2 * k, *arm.link_capsules(world_T_base))
            cpu.append((time.process_time() - c) * 1e6)
            wall.append((time.perf_counter() - t) * 1e6)
        print(f"one check, arm {name}: {statistics.median(wall):.0f} us wall (p95 {np.percentile(wall, 95):.0f}), "
              f"{statistics.median(cpu):.0f} us CPU; contact events {counter.totals}")


def _callgrind(switch):
    """Turn callgrind's instrumentation of this process on or off (no-op outside valgrind)."""
    subprocess.run(["callgrind_control", "-i", switch, str(os.getpid())], stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, check=False)


def simulator_run(enabled, seconds, callgrind=False):
    """CPU ms per sim second of the simulator without cameras and LiDAR driving along, counter on or off."""
    import dataclasses

    from cottonsim_world.robot.arm_contacts import ArmContactConfig
    from cottonsim_world.robot.urdf_model import UrdfModel
    from cottonsim_world.simulator import Simulator, SimulatorConfig

    config = dataclasses.replace(SimulatorConfig(), cameras=(), lidar_enabled=False,
                                 arm_contacts=ArmContactConfig(enabled=enabled))
    sim = Simulator(config, UrdfModel.from_file(URDF))
    sim.command_velocity(0.5, 0.0)
    sim.step_for(0.5)
    if callgrind:
        _callgrind("on")
    c = time.process_time()
    sim.step_for(seconds)
    cpu_ms = (time.process_time() - c) / seconds * 1e3
    if callgrind:
        _callgrind("off")
    sim.close()
    return cpu_ms


def bench_simulator(pairs, seconds):
    results = {True: [], False: []}
    for _ in range(pairs):
        for enabled in (False, True):
            results[enabled].append(simulator_run(enabled, seconds))
    off, on = statistics.median(results[False]), statistics.median(results[True])
    print(f"simulator without cameras and LiDAR, driving: {off:.0f} ms CPU per sim s with the counter off, "
          f"{on:.0f} with it on (+{on - off:.0f} ms, {100 * (on - off) / off:.0f} %); pairs "
          f"{[round(v) for v in results[False]]} / {[round(v) for v in results[True]]}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=400, help="checks timed per arm pose set (default 400)")
    parser.add_argument("--pairs", type=int, default=3, help="A/B pairs of the simulator runs (default 3)")
    parser.add_argument("--seconds", type=float, default=4.0, help="sim seconds per simulator run (default 4)")
    parser.add_argument("--callgrind", choices=("on", "off"),
                        help="only one simulator run, counter on / off, instrumented by callgrind (see above)")
    args = parser.parse_args()
    print(f"machine: {machine()}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}")
    if args.callgrind:
        print(f"{simulator_run(args.callgrind == 'on', args.seconds, callgrind=True):.0f} ms CPU per sim s")
        return
    bench_counter(args.repeats)
    bench_simulator(args.pairs, args.seconds)


if __name__ == "__main__":
    main()
