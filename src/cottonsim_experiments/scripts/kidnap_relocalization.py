#!/usr/bin/env python3
"""Which 3 m kidnaps can AMCL recover from? An offline experiment on the ground-truth farm map.

For each scenario the robot stands at the truth; AMCL's estimate was 3 m off (the kidnap). As the AMCL node
does after a detected kidnap, 10000 particles (relocalize_particles) are re-drawn around the wrong estimate
(2 m along the heading and ``across`` m across it, 0.3 rad), then 12 standing filter updates on the truth's
scan (360 deg, 60 beams, 5.7 m usable range, as /scan_360), each after roughening (0.03 m, 0.01 rad), with
the free-space check on.
Prints per scenario how many seeds end within 0.15 m of the truth, and the median error.

Run:  rosrun cottonsim_experiments kidnap_relocalization.py [seeds] [re-spread particles]
The map is the generator's ground truth (solid plant discs): the simulated scan sees no gaps between the
stems, so this is the optimistic case for the laser model; the rostest amcl_kidnap.test is the real one.
"""
import dataclasses
import math
import statistics
import sys

import numpy as np

from cottonsim_navigation.core.grid import GridSpec, disc_occupancy
from cottonsim_navigation.localization.amcl import Amcl, AmclConfig
from cottonsim_navigation.localization.free_space_model import FreeSpaceCheckedField
from cottonsim_navigation.localization.quality import LocalizationQualityConfig, respread_after_kidnap
from cottonsim_navigation.localization.sensor_models import simulate_scan


def farm_map():
    """The default farm: 9 rows x 20 plants (0.7 m discs), rows along +y at x = -2.33 - 1.8 k, y 8.95..22.25."""
    spec = GridSpec(0.05, 440, 640, -22.0, -4.0)
    stems = [(-2.33 - 1.8 * r, 8.95 + 0.7 * i) for r in range(9) for i in range(20)]
    return spec, disc_occupancy(spec, stems, 0.35)


UP = math.pi / 2
# (name, truth (x, y, yaw), the estimate's offset from the truth (dx, dy)); lane 2 is at x = -5.03
SCENARIOS = [
    ("toward the rows: 4.95 -> 1.95 m before them", (-5.03, 7.0, UP), (0.0, -3.0)),
    ("away from the rows: 2.95 -> 5.95 m before them", (-5.03, 3.0, UP), (0.0, 3.0)),
    ("along a lane, 3 m deeper in (mid-row)", (-5.03, 16.0, UP), (0.0, -3.0)),
    ("into a lane's entry from 3 m before it", (-5.03, 9.0, UP), (0.0, -3.0)),
    ("across the rows, 3 m sideways, 1.95 m before them", (-5.03, 7.0, UP), (3.0, 0.0)),
    ("across the rows at the farm's east edge (lane 0)", (-1.43, 7.0, UP), (-3.0, 0.0)),
]


def run(spec, occ, truth, offset, across_m, seed, round_fraction=0.0, n_particles=None):
    rng = np.random.default_rng(seed)
    amcl = Amcl(AmclConfig(laser_model_type="likelihood_field_prob"), rng=rng)
    amcl.set_map(occ, spec)
    amcl.field = FreeSpaceCheckedField(amcl.field)
    q = LocalizationQualityConfig(relocalize_std_across_m=across_m, relocalize_round_fraction=round_fraction)
    if n_particles is not None:
        q = dataclasses.replace(q, relocalize_particles=n_particles)
    truth = np.array(truth)
    estimate = truth + [offset[0], offset[1], 0.0]
    respread_after_kidnap(amcl, estimate, q)          # as the AMCL node
    angles = np.linspace(-math.pi, math.pi, 720, endpoint=False)
    res = None
    for _ in range(12):
        scan = simulate_scan(occ, spec, truth, angles, range_max_m=5.7, noise_sd_m=0.02, rng=rng)
        amcl.filter.roughen(q.roughen_std_xy_m, q.roughen_std_yaw_rad)
        amcl.request_update()
        res = amcl.update((0.0, 0.0, 0.0), scan)
    return math.hypot(res.pose.x_m - truth[0], res.pose.y_m - truth[1])


def main():
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    n_particles = int(sys.argv[2]) if len(sys.argv) > 2 else None
    spec, occ = farm_map()
    print(f"{seeds} seeds per row; re-spread 2 m along the heading, 0.5 m (farm) or 2 m (round) across it, "
          f"or half of each (mix); {n_particles or LocalizationQualityConfig.relocalize_particles} particles")
    for name, truth, offset in SCENARIOS:
        for label, across, frac in (("0.5 m", 0.5, 0.0), ("round", 0.0, 0.0), ("mix  ", 0.5, 0.5)):
            errs = [run(spec, occ, truth, offset, across, s, frac, n_particles) for s in range(seeds)]
            ok = sum(e <= 0.15 for e in errs)
            print(f"{name:52s} across {label}: {ok:2d}/{seeds} within 0.15 m, "
                  f"median error {statistics.median(errs):5.2f} m")


if __name__ == "__main__":
    main()
