#!/usr/bin/env python3
"""Benchmark of the sensors per backend: ms per camera render, VLP-16 scan, LaserScan.

Usage (from the repo root, venv active):
    OMP_NUM_THREADS=1 python benchmarks/bench_sensors.py [--repeats 5] [--standin]
        [--renderers numba,tiny] [--lidar-backends numba,pybullet] [--write-doc]

--write-doc replaces the "Sensors" section of docs/benchmarks.md with the
printed table (machine, command, load average, numbers).

Uses the default farm from farm.generator when it exists (unless --standin),
otherwise the stand-in farm of sensors.scene (9 x 20 cylinder-canopy plants).
Poses: front camera in lane 1 at 0.55 m looking north, 5 deg down; side
camera at 0.5 m looking west at the next row; VLP-16 at 0.62 m in lane 1.
Prints median wall-clock ms and median process CPU ms (all threads) per
call; nothing is asserted.
"""
import argparse
import io
import math
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src", "cottonsim_world", "src"))

from cottonsim_world.sensors.camera import CameraConfig, CameraModel  # noqa: E402
from cottonsim_world.sensors.cloud_filters import (LaserScanConfig, cloud_to_laserscan,  # noqa: E402
                                                   original_passthrough_mask)
from cottonsim_world.sensors.lidar import LidarConfig, Vlp16Model  # noqa: E402
from cottonsim_world.sensors.scene import SceneConfig, SensorScene  # noqa: E402
from cottonsim_world.sensors.standin_plants import standin_farm  # noqa: E402


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


CPU_MS = []   # process CPU time of the last timeit call [ms per call], all threads together


def timeit(fn, repeats):
    """Median wall-clock ms per call; the median process CPU ms goes to CPU_MS[-1].

    On a shared, loaded machine the wall time includes waiting for a core;
    the CPU time (summed over this process's threads) is closer to the cost.
    """
    fn()
    wall, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    CPU_MS.append(float(np.median(cpu)) * 1000.0)
    return float(np.median(wall)) * 1000.0


class Tee(io.StringIO):
    """Prints and keeps a copy for docs/benchmarks.md."""

    def emit(self, text=""):
        print(text)
        self.write(text + "\n")


def write_doc(text, argv):
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    path = os.path.join(root, "docs", "benchmarks.md")
    old = open(path).read() if os.path.exists(path) else "# Benchmarks\n"
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(line.split(":", 1)[1].strip() for line in fh if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    section = ("## Sensors\n\n"
               f"Machine: {platform.node()}, {os.cpu_count()} cores ({cpu}), Python {platform.python_version()}; "
               f"load average at the start {os.getloadavg()[0]:.1f} (the machine is shared: numbers are noisy "
               "and pessimistic).\n\n"
               f"Command: `OMP_NUM_THREADS=1 python benchmarks/bench_sensors.py {' '.join(argv)}`\n\n"
               "```\n" + text + "```\n")
    start = old.find("## Sensors")
    if start < 0:
        new = old.rstrip("\n") + "\n\n" + section
    else:
        end = old.find("\n## ", start + 1)
        new = old[:start] + section + (old[end + 1:] if end >= 0 else "")
    with open(path, "w") as fh:
        fh.write(new)
    print(f"wrote the Sensors section of {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--standin", action="store_true", help="use the stand-in farm even if the generator exists")
    ap.add_argument("--plant-detail", default="high", choices=("high", "low"))
    ap.add_argument("--collision", default="meshes", choices=("meshes", "primitives"))
    ap.add_argument("--cull", default="25", help="comma-separated cull distances [m]")
    ap.add_argument("--renderers", default="numba,tiny", help="camera renderers to time")
    ap.add_argument("--lidar-backends", default="numba,pybullet", help="LiDAR backends to time")
    ap.add_argument("--write-doc", action="store_true", help="write the results into docs/benchmarks.md")
    args = ap.parse_args()
    out = Tee()
    print_ = out.emit
    farm, label = load_farm(args.standin, args.plant_detail)
    t = time.perf_counter()
    scene = SensorScene(farm, SceneConfig(collision_source=args.collision))
    print_(f"farm: {label}; {len(farm.plants)} plants; scene build {1000 * (time.perf_counter() - t):.0f} ms")
    tris = sum(int(m.triangle_count) for p in farm.plants for m in p.model.meshes.values())
    print_(f"triangles in the farm: {tris}")
    lane = farm.lanes[1] if len(farm.lanes) > 1 else farm.lanes[0]
    y0 = lane.y_start_m - 3.0
    poses = {
        "front (lane entry)": optical_pose(lane.x_m, y0, 0.55, math.pi / 2, math.radians(5)),
        "front (mid-lane)": optical_pose(lane.x_m, 0.5 * (lane.y_start_m + lane.y_end_m), 0.55, math.pi / 2,
                                         math.radians(5)),
        "side (at a plant)": optical_pose(lane.x_m + 0.3, 0.5 * (lane.y_start_m + lane.y_end_m), 0.5, math.pi,
                                          math.radians(15)),
    }
    for renderer in args.renderers.split(","):
        print_(f"\ncamera render [ms per frame], renderer '{renderer}' (ground/sky composited; frustum culling)")
        print_(f"{'view':22s} {'size':8s} {'cull_m':>6s} {'plants':>6s} {'render':>7s} {'cpu':>7s} {'+cloud':>7s}")
        for (w, h) in ((640, 480), (320, 240)):
            for cull in [float(c) for c in args.cull.split(",")]:
                t = time.perf_counter()
                cam = CameraModel(scene, CameraConfig(width=w, height=h, cull_distance_m=cull, renderer=renderer))
                setup_ms = 1000 * (time.perf_counter() - t)
                for name, pose in poses.items():
                    ms = timeit(lambda: cam.render(pose), args.repeats)
                    cpu_ms = CPU_MS[-1]
                    frame = cam.render(pose)
                    ms_cloud = timeit(lambda: cam.point_cloud(frame), args.repeats)
                    print_(f"{name:22s} {w}x{h:<4d} {cull:6.0f} {cam.last_render_stats['plants']:6d} {ms:7.1f} "
                           f"{cpu_ms:7.1f} {ms_cloud:7.1f}")
                print_(f"  (camera construction incl. warm-up frame / kernel compile or cache load: {setup_ms:.0f} ms)")
        # cost of a moving camera (bodies added/removed as the view slides along the lane)
        cam = CameraModel(scene, CameraConfig(width=320, height=240, renderer=renderer))
        ys = np.linspace(lane.y_start_m - 3.0, lane.y_end_m, 40)
        cam.render(optical_pose(lane.x_m, ys[0], 0.55, math.pi / 2, math.radians(5)))
        t = time.perf_counter()
        for y in ys:
            cam.render(optical_pose(lane.x_m, y, 0.55, math.pi / 2, math.radians(5)))
        print_(f"front 320x240 driving along the lane (40 poses): {1000 * (time.perf_counter() - t) / 40:.1f} ms/frame")

    pose = np.eye(4)
    pose[:3, 3] = (lane.x_m, 0.5 * (lane.y_start_m + lane.y_end_m), 0.62)
    scan = None
    for backend in args.lidar_backends.split(","):
        extra = f", collision from {args.collision}" if backend == "pybullet" else ""
        print_(f"\nVLP-16 scan [ms], backend '{backend}' (2 threads{extra})")
        for n in (440, 900, 1800):
            t = time.perf_counter()
            lidar = Vlp16Model(scene, LidarConfig(samples_per_ring=n, backend=backend))
            setup_ms = 1000 * (time.perf_counter() - t)
            ms = timeit(lambda: lidar.scan(pose), args.repeats)
            scan = lidar.scan(pose)
            print_(f"samples/ring {n:5d}: {lidar.ray_count:6d} rays {ms:7.1f} ms (cpu {CPU_MS[-1]:.1f} ms), "
                   f"{len(scan.points)} returns "
                   f"(construction incl. first-use build/compile: {setup_ms:.0f} ms)")
    ms_pt = timeit(lambda: original_passthrough_mask(scan.points), args.repeats * 4)
    ms_ls = timeit(lambda: cloud_to_laserscan(scan.points, LaserScanConfig()), args.repeats * 4)
    print_(f"passthrough (y, z) on {len(scan.points)} points: {ms_pt:.2f} ms")
    print_(f"cloud_to_laserscan on {len(scan.points)} points: {ms_ls:.2f} ms")
    scene.close()
    if args.write_doc:
        write_doc(out.getvalue(), sys.argv[1:])


if __name__ == "__main__":
    main()
