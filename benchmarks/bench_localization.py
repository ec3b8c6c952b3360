#!/usr/bin/env python3
"""Speed of the localisation / mapping cores: one AMCL update (2000 particles, 60 beams), one SLAM update (30 particles).

Also AMCL's worst case while re-localising after a kidnap: 2000 particles re-spread (2 m along, 0.5 m across
the heading), 60 beams of a 360 deg scan (5.7 m usable range), the free-space check of the beams on
(localization/free_space_model.py), in front of the rows and inside a lane; wall and CPU (process) time.

Run:  source scripts/env.sh && OMP_NUM_THREADS=1 python benchmarks/bench_localization.py
Targets: AMCL <= 20 ms, SLAM <= 100 ms. Prints medians in ms (JIT-compiling first calls excluded).
"""
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src/cottonsim_navigation/src"))

from cottonsim_navigation.core.grid import GridSpec, disc_occupancy  # noqa: E402
from cottonsim_navigation.localization.amcl import Amcl, AmclConfig  # noqa: E402
from cottonsim_navigation.localization.free_space_model import FreeSpaceCheckedField  # noqa: E402
from cottonsim_navigation.localization.sensor_models import simulate_scan  # noqa: E402
from cottonsim_navigation.mapping.slam import RbpfSlam, SlamConfig  # noqa: E402


def farm_map():
    """9 rows x 20 plants (0.6 m discs), rows along +y 1.8 m apart, 0.05 m cells."""
    spec = GridSpec(0.05, 600, 600, -20.0, -5.0)
    stems = [(-2.35 - 1.8 * r, 9.0 + 0.7 * i) for r in range(9) for i in range(20)]
    return spec, disc_occupancy(spec, stems, 0.3)


def timed_lane_updates(occ, spec, rng, start_xy, angles, steps: int, warmup: int, update):
    """Drive north from start_xy in 0.3 m steps, scanning ``angles`` at each, and time ``update(k, scan)``
    from step ``warmup`` on; (times [ms], the last update's result)."""
    truth = np.array([start_xy[0], start_xy[1], math.pi / 2])
    times, result = [], None
    for k in range(steps):
        truth = truth + [0.0, 0.3, 0.0]
        scan = simulate_scan(occ, spec, truth, angles, range_max_m=20.0, noise_sd_m=0.01, rng=rng)
        t = time.perf_counter()
        result = update(k, scan)
        if k >= warmup:
            times.append((time.perf_counter() - t) * 1000)
    return times, result


def main():
    spec, occ = farm_map()
    rng = np.random.default_rng(0)
    sector = np.arange(-math.pi / 4, math.pi / 4, 0.0087)          # the simulator's /scan sector
    full = np.linspace(-math.pi, math.pi, 720, endpoint=False)
    print("machine: 2 shared CPU cores (loaded by other users); OMP_NUM_THREADS=1")
    amcl = Amcl(AmclConfig(), rng=rng)
    amcl.set_map(occ, spec)
    amcl.initialise((-3.25, 10.0, math.pi / 2), np.diag([0.25, 0.25, 0.07]))
    times, res = timed_lane_updates(occ, spec, rng, (-3.25, 10.0), sector, 25, 1,
                                    lambda k, scan: amcl.update((0.3 * (k + 1), 0.0, 0.0), scan))
    print(f"AMCL update (2000 -> {res.n_particles} particles, 60 beams): median {statistics.median(times):6.2f} ms, "
          f"max {max(times):6.2f} ms   [target <= 20 ms]")
    bench_relocalizing(spec, occ, rng)
    for name, angles in (("+/-45 deg sector, 181 beams", sector), ("360 deg, 720 beams", full)):
        slam = RbpfSlam(SlamConfig(particles=30), rng=np.random.default_rng(1))
        times, _ = timed_lane_updates(occ, spec, rng, (-3.25, 7.0), angles, 30, 2,
                                      lambda k, scan: slam.update((0.3 * (k + 1) * 1.01, 0.0, 0.0), scan, float(k)))
        print(f"SLAM update (30 particles, {name}): median {statistics.median(times):6.1f} ms, "
              f"max {max(times):6.1f} ms, maps {slam.memory_bytes() / 1e6:.1f} MB   [target <= 100 ms]")


def bench_relocalizing(spec, occ, rng):
    """One AMCL update right after a kidnap's re-spread (2000 particles), free-space check on."""
    full = np.linspace(-math.pi, math.pi, 720, endpoint=False)
    for where, truth in (("before the rows", (-3.25, 6.0, math.pi / 2)), ("in a lane", (-3.25, 12.0, math.pi / 2))):
        for check in (False, True):
            amcl = Amcl(AmclConfig(laser_model_type="likelihood_field_prob"), rng=rng)
            amcl.set_map(occ, spec)
            if check:
                amcl.field = FreeSpaceCheckedField(amcl.field)
            truth = np.array(truth)
            c, s = math.cos(truth[2]), math.sin(truth[2])
            rot = np.array([[c, -s], [s, c]])
            cov = np.zeros((3, 3))
            cov[:2, :2] = rot @ np.diag([2.0 ** 2, 0.5 ** 2]) @ rot.T
            cov[2, 2] = 0.3 ** 2
            wall, cpu = [], []
            for k in range(12):
                scan = simulate_scan(occ, spec, truth, full, range_max_m=5.7, noise_sd_m=0.01, rng=rng)
                amcl.initialise(truth + [0.0, 1.0, 0.0], cov)     # the re-spread around a 1 m wrong estimate
                n = amcl.filter.n
                t, p = time.perf_counter(), time.process_time()
                amcl.update((0.0, 0.0, 0.0), scan)
                if k > 0:
                    wall.append((time.perf_counter() - t) * 1000)
                    cpu.append((time.process_time() - p) * 1000)
            print(f"AMCL update re-localising {where} ({n} particles, 60 beams of 360 deg), "
                  f"free-space check {'on ' if check else 'off'}: median wall {statistics.median(wall):6.2f} ms, "
                  f"CPU {statistics.median(cpu):6.2f} ms   [target <= 20 ms]")


if __name__ == "__main__":
    main()
