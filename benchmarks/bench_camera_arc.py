#!/usr/bin/env python3
"""Cost of the front camera alone along bench_sim's arc: ms per frame and, under callgrind, instructions.

The robot drives bench_sim's arc through the headland (the whole farm 8-22 m
ahead) for --seconds sim seconds; the front camera's world_T_optical is
recorded at 10 Hz. Then a fresh numba camera (--width x 3/4 width) renders
every --every-th pose (and its point cloud with --cloud), timed with process
CPU time (best of --repeats). With --callgrind, callgrind's instrumentation is
on for the first timed pass only:

  NUMBA_NUM_THREADS=1 valgrind --tool=callgrind --instr-atstart=no \\
      python benchmarks/bench_camera_arc.py --width 320 --every 3 --repeats 1 --callgrind

  NUMBA_NUM_THREADS=1 python benchmarks/bench_camera_arc.py --width 640 --cloud --lod 0,3,4,6
"""
import argparse
import os
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bench_sim  # noqa: E402
from bench_sim import _callgrind  # noqa: E402

from cottonsim_world.config_io import simulator_config_from_dict  # noqa: E402
from cottonsim_world.robot.urdf_model import UrdfModel  # noqa: E402
from cottonsim_world.sensors.camera import CameraConfig, CameraModel  # noqa: E402
from cottonsim_world.simulator import Simulator  # noqa: E402


def arc_poses(seconds: float):
    sim = Simulator(simulator_config_from_dict(bench_sim.PROFILES["nav"]), UrdfModel.from_file(bench_sim.URDF))
    sim.step_for(0.2)
    poses, t0, next_s = [], sim.time_s, sim.time_s
    while sim.time_s - t0 < seconds - 1e-9:
        sim.command_velocity(0.5, 0.15)
        sim.step()
        if sim.time_s >= next_s - 1e-9:
            poses.append(sim.world_T_base() @ sim.base_T_sensor["realsense_p"])
            next_s += 0.1
    scene = sim.sensor_scene
    return poses, scene, sim


def main():
    import time
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--every", type=int, default=1, help="use every n-th recorded pose")
    parser.add_argument("--cloud", action="store_true", help="also build each frame's point cloud")
    parser.add_argument("--lod", default="default", help="comma-separated lod_max_error_px values, or 'default'")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--callgrind", action="store_true")
    args = parser.parse_args()
    poses, scene, sim = arc_poses(args.seconds)
    poses = poses[::args.every]
    print(f"load average {os.getloadavg()[0]:.1f}; {len(poses)} poses; {args.width}x{args.width * 3 // 4}"
          f"{' + cloud' if args.cloud else ''}")
    lods = [None] if args.lod == "default" else [float(v) for v in args.lod.split(",")]
    for lod in lods:
        extra = {} if lod is None else {"lod_max_error_px": lod}
        cam = CameraModel(scene, CameraConfig(width=args.width, height=args.width * 3 // 4, **extra))
        for pose in poses[:2]:
            cam.point_cloud(cam.render(pose))
        best = np.inf
        for rep in range(args.repeats):
            if args.callgrind and rep == 0:
                _callgrind("on")
            c = time.process_time()
            for pose in poses:
                frame = cam.render(pose)
                if args.cloud:
                    cam.point_cloud(frame)
            best = min(best, time.process_time() - c)
            if args.callgrind and rep == 0:
                _callgrind("off")
        label = "default" if lod is None else f"{lod:g} px"
        print(f"lod {label}: {1e3 * best / len(poses):.2f} ms cpu per frame")
    sim.close()


if __name__ == "__main__":
    main()
