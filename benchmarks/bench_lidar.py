#!/usr/bin/env python3
"""CPU cost of one VLP-16 cast and of the simulator's whole LiDAR update, inside a lane and in the headland.

Casts from fixed poses of the default farm (no physics, no ROS), so the figures are repeatable:

  lane     - the 'velodyne' frame in lane 3 (world x = -6.83 m), y = 10.0 .. 10.75 m, 0.38 m up,
             robot facing +y (a hedge 0.9 m to each side): the expensive place;
  headland - at the spawn pose (world (-6.0, 1.0), facing the rows 8 m ahead), turned by 0 .. 0.45 rad.

Prints the build time of the LiDAR's scene structure, CPU ms per cast (time.process_time, summed
over threads: run with NUMBA_NUM_THREADS=1 for the work itself) and CPU ms per whole update
(scan with noise + PassThrough + the two LaserScans, as ``Simulator._lidar`` does).

  NUMBA_NUM_THREADS=1 python benchmarks/bench_lidar.py [--repeats 5] [--evict-mb 32] [--save out.npz | --compare ref.npz]

--save writes every pose's ranges [m] and hit ids (noise-free ``Vlp16Model`` internals); --compare
prints, per pose, whether a later tree misses the same rays, the largest range difference, the
rays whose range moved by more than 1 mm, and how many hit classes and plant ids differ (a change
that keeps every hit prints 0 m and 0, 0, 0; the float32 triangle tests against float64
ones: at most 5e-3 m, 1 ray over 1 mm per pose, 0 classes, 0 plant ids).
--evict-mb N streams through an N MB buffer before every timed cast and update: in the simulator
a camera render (and the physics) run between two LiDAR casts and push the tree out of the caches,
which a loop of back-to-back casts never does. 32 (the EPYC's L3) is a good value: the figures are
then per cast from cold caches (+0.8 ms median in the lane on the EPYC, within the VM's drift;
docs/benchmarks.md, "LiDAR (VLP-16)").
--callgrind (under ``valgrind --tool=callgrind --instr-atstart=no``) instruments the casts only
(one cast per pose): "Collected : N" is the instruction count of the 4 lane + 4 headland casts,
and --callgrind-place restricts them to one place.
"""
import argparse
import math
import os
import pathlib
import platform
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_sim import _callgrind  # noqa: E402

from cottonsim_world.farm.generator import FarmConfig, generate_farm  # noqa: E402
from cottonsim_world.farm.model import SemanticClass  # noqa: E402
from cottonsim_world.sensors.cloud_filters import (LaserScanConfig, PassThroughConfig,  # noqa: E402
                                                   cloud_to_laserscans, original_passthrough_mask)
from cottonsim_world.sensors.lidar import LidarConfig, Vlp16Model  # noqa: E402
from cottonsim_world.sensors.scene import SceneConfig, SensorScene  # noqa: E402

SENSOR_Z_M = 0.38
LANE_X_M = -6.83


def sensor_pose(x_m, y_m, robot_yaw_rad):
    """world_T_velodyne: the velodyne frame is yawed +90 deg on the robot."""
    yaw = robot_yaw_rad + math.pi / 2
    pose = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    pose[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    pose[:3, 3] = (x_m, y_m, SENSOR_Z_M)
    return pose


POSES = {
    "lane": [sensor_pose(LANE_X_M, 10.0 + 0.25 * k, math.pi / 2) for k in range(4)],
    "headland": [sensor_pose(-6.0, 1.0, math.pi / 2 + 0.15 * k) for k in range(4)],
}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5, help="casts per pose")
    parser.add_argument("--save", help="write every pose's ranges and hit ids to this .npz")
    parser.add_argument("--compare", help="compare every pose's ranges and hits with this .npz")
    parser.add_argument("--evict-mb", type=float, default=0.0,
                        help="stream through a buffer of this many MB before each timed cast (0: hot caches)")
    parser.add_argument("--callgrind", action="store_true")
    parser.add_argument("--callgrind-place", choices=sorted(POSES))
    args = parser.parse_args()
    if args.evict_mb < 0:
        parser.error("--evict-mb must be >= 0")
    evict_buffer = np.zeros(int(args.evict_mb * 1e6 / 8))

    def timed_ms(work) -> float:
        """Mean CPU ms of ``work()`` over --repeats calls, each after the cache sweep (if any)."""
        total = 0.0
        for _ in range(args.repeats):
            if evict_buffer.size:
                np.add(evict_buffer, 1.0, out=evict_buffer)    # reads and writes every line of the buffer
            c = time.process_time()
            work()
            total += time.process_time() - c
        return 1e3 * total / args.repeats

    def update(pose):
        scan = lidar.scan(pose)
        original_passthrough_mask(scan.points, PassThroughConfig())
        cloud_to_laserscans(scan.points, scan_configs)

    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS', 'unset')}; "
          f"{'caches hot' if not evict_buffer.size else f'caches swept by {args.evict_mb:g} MB before each cast'}")
    farm = generate_farm(FarmConfig())
    scene = SensorScene(farm, SceneConfig())
    t0 = time.process_time()
    _ = scene.fast_plants
    t1 = time.process_time()
    lidar = Vlp16Model(scene, LidarConfig())
    t2 = time.process_time()
    print(f"build: instanced plants {t1 - t0:.2f} s, LiDAR structure + warm-up cast {t2 - t1:.2f} s CPU")
    if args.callgrind:
        places = [args.callgrind_place] if args.callgrind_place else sorted(POSES)
        _callgrind("on")
        for place in places:
            for pose in POSES[place]:
                lidar.ranges(pose)
        _callgrind("off")
        print(f"callgrind: instrumented one cast per pose of {places}")
        return
    saved = {}
    scan_configs = (LaserScanConfig(), LaserScanConfig(min_height_m=-0.25, angle_min_rad=-math.pi,
                                                       angle_max_rad=math.pi))
    for place, poses in POSES.items():
        cast_ms, update_ms = [], []
        for k, pose in enumerate(poses):
            rng, sem, pid = lidar.ranges(pose)
            saved[f"{place}{k}_range"], saved[f"{place}{k}_sem"], saved[f"{place}{k}_pid"] = rng, sem, pid
            cast_ms.append(timed_ms(lambda: lidar.ranges(pose)))
            update_ms.append(timed_ms(lambda: update(pose)))
        hits = np.mean([np.mean(saved[f"{place}{k}_sem"] != int(SemanticClass.SKY)) for k in range(len(poses))])
        print(f"{place:9s}: cast {np.mean(cast_ms):6.2f} ms CPU (per pose {', '.join(f'{m:.2f}' for m in cast_ms)}); "
              f"scan + PassThrough + 2 LaserScans {np.mean(update_ms):6.2f} ms CPU; {hits:.0%} of rays hit")
    if args.save:
        np.savez_compressed(args.save, **saved)
    if args.compare:
        ref = np.load(args.compare)
        for key in sorted(k[:-6] for k in ref.files if k.endswith("_range")):
            r0, r1 = ref[key + "_range"], saved[key + "_range"]
            same_inf = np.array_equal(np.isinf(r0), np.isinf(r1))
            fin = np.isfinite(r0) & np.isfinite(r1)
            err = float(np.max(np.abs(r0[fin] - r1[fin]))) if fin.any() else 0.0
            sem_diff = int(np.count_nonzero(ref[key + "_sem"] != saved[key + "_sem"]))
            pid_diff = int(np.count_nonzero(ref[key + "_pid"] != saved[key + "_pid"]))
            moved = int(np.count_nonzero(np.abs(r0[fin] - r1[fin]) > 1e-3))
            print(f"compare {key}: same misses {same_inf}, max |dr| {err:.3g} m, rays moved > 1 mm {moved}, "
                  f"semantic differs {sem_diff}, plant id differs {pid_diff}")


if __name__ == "__main__":
    main()
