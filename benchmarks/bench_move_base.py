#!/usr/bin/env python3
"""Cost of one move_base controller cycle: local costmap update from a VLP-16-sized cloud + DWA.

This is what the move_base node does every cycle (the cloud transform aside):
obstacle-layer ray tracing and marking of one cloud, inflation of the rolling
5 x 5 m window, then MoveBase.step (plan hand-over + one DWA evaluation).
Also prints the cost of the first global plan across the farm map.

Run:  source scripts/env.sh && OMP_NUM_THREADS=1 python benchmarks/bench_move_base.py
Prints medians in ms (the first, JIT-compiling call is excluded).
"""
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src/cottonsim_navigation/src"))

from cottonsim_common.pose import Pose2D  # noqa: E402
from cottonsim_navigation.core.grid import GridSpec, disc_occupancy  # noqa: E402
from cottonsim_navigation.move_base.config import MoveBaseConfig  # noqa: E402
from cottonsim_navigation.move_base.state_machine import MoveBase  # noqa: E402
from cottonsim_navigation.planning.costmap import make_global_costmap, make_local_costmap  # noqa: E402


def farm_map():
    """The default farm's layout as an occupancy map (rows along +x here: the robot drives along +x)."""
    spec = GridSpec(0.05, 700, 400, -5.0, -10.0)
    stems = [(3.0 + 0.7 * i, -0.9 - 1.8 * r + 1.8 * 4) for r in range(9) for i in range(20)]
    return spec, disc_occupancy(spec, stems, 0.3)


def vlp16_cloud(pose, n_rings=16, n_az=1800, sensor_z=0.6):
    """~29k points in the odom frame: ground hits, and walls of plants 0.9 m to each side of the robot."""
    az = np.linspace(-math.pi, math.pi, n_az, endpoint=False)
    el = np.radians(np.linspace(-15, 15, n_rings))
    A, E = np.meshgrid(az, el)
    dx, dy, dz = np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)
    r_ground = np.where(dz < -1e-3, sensor_z / np.maximum(-dz, 1e-3), np.inf)
    r_wall = np.where(np.abs(dy) > 1e-3, 0.9 / np.maximum(np.abs(dy), 1e-3), np.inf)
    r = np.minimum(np.minimum(r_ground, r_wall), 100.0)
    pts = np.stack([r * dx, r * dy, sensor_z + r * dz], axis=-1).reshape(-1, 3)
    pts = pts[r.ravel() < 100.0]
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    out = pts.copy()
    out[:, 0] = pose.x_m + c * pts[:, 0] - s * pts[:, 1]
    out[:, 1] = pose.y_m + s * pts[:, 0] + c * pts[:, 1]
    return out, np.array([pose.x_m, pose.y_m, sensor_z])


def median_ms(samples):
    return statistics.median(samples) * 1000.0


def main():
    spec, occ = farm_map()
    glob = make_global_costmap(occ, spec)
    local = make_local_costmap()
    mb = MoveBase(MoveBaseConfig(), glob, local)
    pose = Pose2D(2.0, 0.0, 0.0)
    cloud, origin = vlp16_cloud(pose)
    local.obstacle_layer.add_observation(cloud, origin)
    local.update_map(pose)
    goal = Pose2D(16.0, 0.0, 0.0)

    t = time.perf_counter()
    mb.set_goal(goal, 0.0)
    mb.step(0.0, pose, pose, (0.3, 0.0))            # first call: plans (navfn) and compiles
    first_ms = (time.perf_counter() - t) * 1000.0
    plan_t = []
    for _ in range(5):
        t = time.perf_counter()
        mb.make_plan(pose, goal)
        plan_t.append(time.perf_counter() - t)

    cm_t, step_t, total_t = [], [], []
    now = 0.2
    for k in range(25):
        p = Pose2D(pose.x_m + 0.02 * k, 0.0, 0.0)
        cloud, origin = vlp16_cloud(p)
        t0 = time.perf_counter()
        local.obstacle_layer.add_observation(cloud, origin)
        local.update_map(p)
        t1 = time.perf_counter()
        r = mb.step(now, p, p, (0.3, 0.0))
        t2 = time.perf_counter()
        now += 0.2
        if k:
            cm_t.append(t1 - t0)
            step_t.append(t2 - t1)
            total_t.append(t2 - t0)
    print(f"cloud: {len(cloud)} points (VLP-16 sized), local costmap 5 x 5 m at 0.05 m, "
          f"global map {spec.width} x {spec.height} cells")
    print(f"first step (navfn plan across the farm + JIT): {first_ms:8.1f} ms")
    print(f"make_plan across the farm (14 m):              {median_ms(plan_t):8.1f} ms")
    print(f"local costmap update (raytrace+mark+inflate):  {median_ms(cm_t):8.1f} ms")
    print(f"MoveBase.step (DWA cycle):                     {median_ms(step_t):8.1f} ms")
    print(f"one controller cycle (costmap + step):         {median_ms(total_t):8.1f} ms "
          f"(budget at controller_frequency 5 Hz: 200 ms); last command v {r.v_mps:.2f} w {r.w_radps:.2f}")


if __name__ == "__main__":
    main()
