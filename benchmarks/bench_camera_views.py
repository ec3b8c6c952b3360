#!/usr/bin/env python3
"""CPU cost of each camera alone, in the headland and in a lane: ms per frame and, under callgrind, instructions.

The robot drives bench_sim's routes (--places: *headland*, the arc from the
spawn pose; *lane*, straight along lane 3 between two hedges) for --seconds
sim seconds; every camera's world_T_optical is recorded at 10 Hz. Then a
fresh numba camera per (camera, --widths) renders every --every-th pose of
that camera (with its point cloud unless --no-cloud), timed with process
CPU time, best of --repeats. Run it with NUMBA_NUM_THREADS=1 so that CPU
time is the work; --threads reports the CPU / wall ratio of the default
thread count instead.

  NUMBA_NUM_THREADS=1 python benchmarks/bench_camera_views.py --widths 320,640
  NUMBA_NUM_THREADS=1 valgrind --tool=callgrind --instr-atstart=no \\
      python benchmarks/bench_camera_views.py --widths 640 --repeats 1 --callgrind

With --callgrind the instrumentation is on for the first timed pass of
every (place, camera, width) only, and the counts are dumped after each
(callgrind.out.PID.1, .2, ... in the printed order; read each file's
"totals:" line: its "summary:" line can be wrong after the counters were
switched off and on), so the total is the sum of those frames.
--png DIR writes each camera's first frame (rgb | semantic) to DIR.
"""
import argparse
import os
import pathlib
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bench_sim  # noqa: E402
from bench_sim import _callgrind  # noqa: E402

from cottonsim_world.config_io import simulator_config_from_dict  # noqa: E402
from cottonsim_world.robot.urdf_model import UrdfModel  # noqa: E402
from cottonsim_world.sensors.camera import CameraConfig, CameraModel  # noqa: E402
from cottonsim_world.simulator import Simulator  # noqa: E402
from cottonsim_world.simulator_config import CAMERA_NAMES  # noqa: E402

SHORT = {"realsense_p": "front", "realsense_secondary": "side L", "realsense_tertiary": "side R"}


def _callgrind_dump() -> None:
    """Write callgrind's counts so far to the next numbered dump file and zero them (no-op outside valgrind)."""
    subprocess.run(["callgrind_control", "-d", str(os.getpid())], stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, check=False)


def record_poses(place: str, seconds: float):
    """Per camera the world_T_optical poses at 10 Hz along the place's route, and the simulator."""
    profile = {"cameras": {c: {"width": 64, "height": 48, "rate_hz": 1.0} for c in CAMERA_NAMES},
               "lidar_enabled": False}
    config = simulator_config_from_dict(profile)
    farm, (v_m_s, w_rad_s) = bench_sim._place(config, place)
    sim = Simulator(config, UrdfModel.from_file(bench_sim.URDF), farm=farm)
    sim.step_for(0.2)
    poses = {c: [] for c in CAMERA_NAMES}
    t0, next_s = sim.time_s, sim.time_s
    while sim.time_s - t0 < seconds - 1e-9:
        sim.command_velocity(v_m_s, w_rad_s)
        sim.step()
        if sim.time_s >= next_s - 1e-9:
            for c in CAMERA_NAMES:
                poses[c].append(sim.world_T_base() @ sim.base_T_sensor[c])
            next_s += 0.1
    return poses, sim


def _semantic_png(sem: np.ndarray) -> np.ndarray:
    palette = np.array([[40, 160, 40], [120, 90, 60], [130, 180, 250], [255, 255, 255]] + [[255, 0, 255]] * 252,
                       np.uint8)
    return palette[sem]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--places", default="headland,lane")
    parser.add_argument("--cameras", default=",".join(CAMERA_NAMES))
    parser.add_argument("--widths", default="320,640", help="image widths [px] (height = 3/4 width)")
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--every", type=int, default=3, help="use every n-th recorded pose")
    parser.add_argument("--no-cloud", action="store_true", help="render only, no point cloud")
    parser.add_argument("--lod", type=float, default=None, help="lod_max_error_px (default: CameraConfig's)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--callgrind", action="store_true")
    parser.add_argument("--png", default="", help="folder for each camera's first frame")
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f}; NUMBA_NUM_THREADS="
          f"{os.environ.get('NUMBA_NUM_THREADS', 'unset')}; cloud {'no' if args.no_cloud else 'yes'}")
    extra = {} if args.lod is None else {"lod_max_error_px": args.lod}
    for place in args.places.split(","):
        poses, sim = record_poses(place, args.seconds)
        for name in args.cameras.split(","):
            for width in (int(w) for w in args.widths.split(",")):
                cam = CameraModel(sim.sensor_scene, CameraConfig(width=width, height=width * 3 // 4, **extra))
                views = poses[name][::args.every]
                for pose in views[:2]:
                    cam.point_cloud(cam.render(pose))
                best, best_wall = np.inf, np.inf
                for rep in range(args.repeats):
                    if args.callgrind and rep == 0:
                        _callgrind("on")
                    c, w = time.process_time(), time.perf_counter()
                    for pose in views:
                        frame = cam.render(pose)
                        if not args.no_cloud:
                            cam.point_cloud_xyzrgb(frame)
                    best = min(best, time.process_time() - c)
                    best_wall = min(best_wall, time.perf_counter() - w)
                    if args.callgrind and rep == 0:
                        _callgrind_dump()
                        _callgrind("off")
                stats = cam.last_render_stats
                print(f"{place:8s} {SHORT.get(name, name):7s} {width}x{width * 3 // 4}: "
                      f"{1e3 * best / len(views):6.2f} ms cpu, {1e3 * best_wall / len(views):6.2f} ms wall per frame "
                      f"({len(views)} frames; last: {stats.get('plants', 0)} plants, "
                      f"{stats.get('middle', 0)} middle, {stats.get('simplified', 0)} far)")
                if args.png:
                    import cv2
                    frame = cam.render(views[0])
                    out = pathlib.Path(args.png)
                    out.mkdir(parents=True, exist_ok=True)
                    both = np.concatenate([frame.rgb, _semantic_png(frame.semantic)], axis=1)
                    cv2.imwrite(str(out / f"{place}_{name}_{width}.png"), both[..., ::-1])
        sim.close()


if __name__ == "__main__":
    main()
