#!/usr/bin/env python3
"""Benchmark of the pybullet sensors: ms per camera render, VLP-16 scan, LaserScan.

Usage (from the repo root, venv active):
    OMP_NUM_THREADS=1 python benchmarks/bench_sensors.py [--repeats 5] [--standin]

Uses the default farm from farm.generator when it exists (unless --standin),
otherwise the stand-in farm of sensors.scene (9 x 20 cylinder-canopy plants).
Poses: front camera in lane 1 at 0.55 m looking north, 5 deg down; side
camera at 0.5 m looking west at the next row; VLP-16 at 0.62 m in lane 1.
Prints a table; nothing is asserted.
"""
import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src", "cottonsim_world", "src"))

from cottonsim_world.sensors.camera import CameraConfig, CameraModel  # noqa: E402
from cottonsim_world.sensors.cloud_filters import (LaserScanConfig, cloud_to_laserscan,  # noqa: E402
                                                   original_passthrough_mask)
from cottonsim_world.sensors.lidar import LidarConfig, Vlp16Model  # noqa: E402
from cottonsim_world.sensors.scene import SceneConfig, SensorScene, standin_farm  # noqa: E402


def optical_pose(x, y, z, yaw, pitch_down=0.0):
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch_down), math.sin(pitch_down)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    t = np.eye(4)
    t[:3, :3] = rz @ ry @ np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], float)
    t[:3, 3] = (x, y, z)
    return t


def load_farm(standin, detail):
    if not standin:
        try:
            from cottonsim_world.farm.generator import FarmConfig, generate_farm  # type: ignore
            return generate_farm(FarmConfig(plant_detail=detail)), f"farm.generator farm, plant_detail={detail}"
        except Exception as exc:  # generator absent or different API
            print(f"(farm.generator not usable: {exc}; using the stand-in farm)")
    return standin_farm(), "stand-in farm (9 x 20 cylinder-canopy plants, ~270 triangles each)"


def timeit(fn, repeats):
    fn()
    t = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - t) / repeats * 1000.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--standin", action="store_true", help="use the stand-in farm even if the generator exists")
    ap.add_argument("--plant-detail", default="high", choices=("high", "low"))
    ap.add_argument("--collision", default="meshes", choices=("meshes", "primitives"))
    ap.add_argument("--cull", default="8,25,inf", help="comma-separated cull distances [m]")
    args = ap.parse_args()
    farm, label = load_farm(args.standin, args.plant_detail)
    t = time.perf_counter()
    scene = SensorScene(farm, SceneConfig(collision_source=args.collision))
    print(f"farm: {label}; {len(farm.plants)} plants; scene build {1000 * (time.perf_counter() - t):.0f} ms")
    tris = sum(int(m.triangle_count) for p in farm.plants for m in p.model.meshes.values())
    print(f"triangles in the farm: {tris}")
    lane = farm.lanes[1] if len(farm.lanes) > 1 else farm.lanes[0]
    y0 = lane.y_start_m - 3.0
    poses = {
        "front (lane entry)": optical_pose(lane.x_m, y0, 0.55, math.pi / 2, math.radians(5)),
        "front (mid-lane)": optical_pose(lane.x_m, 0.5 * (lane.y_start_m + lane.y_end_m), 0.55, math.pi / 2,
                                         math.radians(5)),
        "side (at a plant)": optical_pose(lane.x_m + 0.3, 0.5 * (lane.y_start_m + lane.y_end_m), 0.5, math.pi,
                                          math.radians(15)),
    }
    print("\ncamera render [ms per frame] (TinyRenderer; ground/sky composited; frustum culling)")
    print(f"{'view':22s} {'size':8s} {'cull_m':>6s} {'plants':>6s} {'render':>7s} {'+cloud':>7s}")
    for (w, h) in ((640, 480), (320, 240)):
        for cull in [float(c) for c in args.cull.split(",")]:
            cam = CameraModel(scene, CameraConfig(width=w, height=h, cull_distance_m=cull))
            for name, pose in poses.items():
                ms = timeit(lambda: cam.render(pose), args.repeats)
                frame = cam.render(pose)
                ms_cloud = timeit(lambda: cam.point_cloud(frame), args.repeats)
                print(f"{name:22s} {w}x{h:<4d} {cull:6.0f} {cam.last_render_stats['plants']:6d} {ms:7.1f} "
                      f"{ms_cloud:7.1f}")
    # cost of a moving camera (bodies added/removed as the view slides along the lane)
    cam = CameraModel(scene, CameraConfig(width=320, height=240))
    ys = np.linspace(lane.y_start_m - 3.0, lane.y_end_m, 40)
    cam.render(optical_pose(lane.x_m, ys[0], 0.55, math.pi / 2, math.radians(5)))
    t = time.perf_counter()
    for y in ys:
        cam.render(optical_pose(lane.x_m, y, 0.55, math.pi / 2, math.radians(5)))
    print(f"front 320x240 driving along the lane (40 poses): {1000 * (time.perf_counter() - t) / 40:.1f} ms/frame")

    print(f"\nVLP-16 scan [ms] (rayTestBatch, 2 threads, collision from {args.collision})")
    pose = np.eye(4)
    pose[:3, 3] = (lane.x_m, 0.5 * (lane.y_start_m + lane.y_end_m), 0.62)
    scan = None
    for n in (440, 900, 1800):
        lidar = Vlp16Model(scene, LidarConfig(samples_per_ring=n))
        ms = timeit(lambda: lidar.scan(pose), args.repeats)
        scan = lidar.scan(pose)
        print(f"samples/ring {n:5d}: {lidar.ray_count:6d} rays {ms:7.1f} ms, {len(scan.points)} returns")
    ms_pt = timeit(lambda: original_passthrough_mask(scan.points), args.repeats * 4)
    ms_ls = timeit(lambda: cloud_to_laserscan(scan.points, LaserScanConfig()), args.repeats * 4)
    print(f"passthrough (y, z) on {len(scan.points)} points: {ms_pt:.2f} ms")
    print(f"cloud_to_laserscan on {len(scan.points)} points: {ms_ls:.2f} ms")
    scene.close()


if __name__ == "__main__":
    main()
