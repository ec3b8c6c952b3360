#!/usr/bin/env python3
"""Speed of the navigation cores: navfn across the farm map, one DWA cycle, costmap updates.

Run:  source scripts/env.sh && OMP_NUM_THREADS=1 python benchmarks/bench_navigation.py
Prints the median of several runs in ms, wall and (in brackets) CPU time of this process
(the first, JIT-compiling call is excluded).
"""
import dataclasses
import math
import os
import statistics
import sys
from pathlib import Path

import numpy as np

for _pkg in ("cottonsim_navigation", "cottonsim_common"):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src" / _pkg / "src"))

from cottonsim_common.config.yaml_files import load_yaml_file  # noqa: E402

from cottonsim_common.pose import Pose2D  # noqa: E402
from cottonsim_navigation.core.grid import GridSpec, disc_occupancy  # noqa: E402
from cottonsim_navigation.planning.costmap import make_global_costmap, make_local_costmap  # noqa: E402
from cottonsim_navigation.planning.global_planners.navfn import NavfnPlanner  # noqa: E402
from cottonsim_navigation.planning.local_planners.dwa import DWAConfig, DWAPlanner  # noqa: E402
from timing import wall_and_cpu_ms  # noqa: E402

CONFIG_DIR = Path(__file__).resolve().parents[1] / "src/cottonsim_navigation/config"


class Timing(float):
    """Median wall ms (the float value) with the median CPU ms of this process alongside."""

    cpu_ms = 0.0

    def __format__(self, spec):
        return f"{float(self):{spec}} (cpu {self.cpu_ms:{spec}})"


def timed(fn, repeats=7):
    """Median wall and CPU (time.process_time) milliseconds; CPU time is the figure to trust on a
    shared machine, where other jobs stretch the wall clock."""
    wall, cpu = wall_and_cpu_ms(fn, repeats)
    out = Timing(statistics.median(wall))
    out.cpu_ms = statistics.median(cpu)
    return out


def farm_map():
    """40 x 40 m at 0.05 m: 9 rows x 20 plants (0.7 m wide discs) along +y, 1.8 m apart."""
    spec = GridSpec(0.05, 800, 800, -30.0, -10.0)
    stems = [(-2.35 - 1.8 * r, 9.0 + 0.7 * i) for r in range(9) for i in range(20)]
    return spec, disc_occupancy(spec, stems, 0.3)


def vlp16_cloud(n_rings=16, n_az=1800):
    """A VLP-16-sized cloud (~29k points): rings hitting a ground plane / walls 2-8 m away."""
    az = np.linspace(-math.pi, math.pi, n_az, endpoint=False)
    el = np.radians(np.linspace(-15, 15, n_rings))
    A, E = np.meshgrid(az, el)
    r = 2.0 + 6.0 * (0.5 + 0.5 * np.sin(3 * A))
    return np.column_stack([(r * np.cos(A)).ravel(), (r * np.sin(A)).ravel(), (0.7 + r * np.sin(E)).ravel()])


def main():
    spec, occ = farm_map()
    print(f"machine: 2 shared CPU cores; load average {os.getloadavg()[0]:.1f}; OMP_NUM_THREADS=1")
    t_global = timed(lambda: make_global_costmap(occ, spec), repeats=5)
    gcm = make_global_costmap(occ, spec)
    print(f"global costmap (800x800, static + inflation) build: {t_global:7.2f} ms")
    planner = NavfnPlanner()
    start, goal = Pose2D(-6.0, 1.0, math.pi / 2), Pose2D(-17.95, 27.0, 0.0)
    plan = planner.make_plan(gcm, start, goal)
    t_plan = timed(lambda: planner.make_plan(gcm, start, goal))
    print(f"navfn Home -> far lane end ({plan.length_m():.1f} m, {len(plan)} poses): {t_plan:7.2f} ms")
    corner = (Pose2D(-29.9, -9.9), Pose2D(9.9, 29.9))
    t_corner = timed(lambda: planner.make_plan(gcm, *corner), repeats=15)
    print(f"navfn corner -> corner across the rows:            {t_corner:7.2f} ms")

    cloud = vlp16_cloud()
    lcm = make_local_costmap()
    pose = Pose2D(0.0, 0.0, 0.0)

    def local_update():
        lcm.obstacle_layer.add_observation(cloud, (0.0, 0.0, 0.7))
        lcm.update_map(pose)
    t_local = timed(local_update)
    print(f"local costmap update (5x5 m, {len(cloud)} points mark+clear + inflation): {t_local:7.2f} ms")

    path = np.column_stack([np.linspace(0, 4, 81), 0.3 * np.sin(np.linspace(0, 3, 81))])
    lcm2 = make_local_costmap()
    lcm2.obstacle_layer.add_observation(np.array([[1.5, 0.8, 0.3], [1.5, -0.8, 0.3]]), (0, 0, 0.5))
    lcm2.update_map(pose)
    # the DWA as move_base loads it: config/dwa.yaml, then the GPS experiment's overrides on top
    for label, files in (("move_base default", ("dwa.yaml",)),
                         ("GPS experiment", ("dwa.yaml", "gps_navigation_move_base.yaml"))):
        dwa = DWAPlanner(dwa_config_from_yaml(*files))

        def dwa_cycle():
            dwa.set_plan(path)
            dwa.compute_velocity(pose, (0.3, 0.0), lcm2)
        t_dwa = timed(dwa_cycle, repeats=21)
        print(f"DWA cycle, {label} ({dwa.config.vx_samples}x{dwa.config.vth_samples} samples, sim_time "
              f"{dwa.config.sim_time} s, <= {dwa.config.max_vel_x} m/s): {t_dwa:7.2f} ms")


def dwa_config_from_yaml(*names: str) -> DWAConfig:
    """DWAConfig from the DWAPlannerROS sections of config files (later files override earlier ones)."""
    fields = {f.name for f in dataclasses.fields(DWAConfig)}
    values = {}
    for name in names:
        section = load_yaml_file(CONFIG_DIR / name, default={}).get("DWAPlannerROS", {}) or {}
        values.update({k: v for k, v in section.items() if k in fields})
    return DWAConfig(**values)

if __name__ == "__main__":
    main()
