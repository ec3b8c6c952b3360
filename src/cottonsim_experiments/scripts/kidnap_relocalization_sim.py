#!/usr/bin/env python3
"""AMCL's self re-localisation after the kidnap of map_navigation_kidnap_recover.test, offline, many times.

As in that rostest: the robot drives toward the rows at 0.5 m/s in the route's lane 1 (world x -1.43 m) and is
carried forward, landing at rest 1.95 m before the first stems, facing them; the navigator goes on
commanding 0.5 m/s for 0.6 s, then stops it; 1.0 s after the landing AMCL, having confirmed the kidnap,
re-spreads its particles as its node does around an estimate 2.3-3.3 m behind the truth. From then on
every /scan_360 of the simulator (pybullet VLP-16, nav_ci.yaml settings) goes through the node's policy,
``LocalizationSupervisor.step`` (config/amcl.yaml + config/amcl_farm.yaml; the shipped SLAM map; filter
updates after motion and, while re-localising, every 0.5 s with roughening; the free-space check on while
not localised) until it says "localised" (or 20 s of sim time). Odometry is perfect (the ground truth): only the filter is measured.
Prints, per seed, the error along / across the heading at that moment, and how often the pose the node
would report as localised is more than 0.25 m off (the rostest's CR radius) or more than 0.5 m (the set
settled on a wrong peak of the likelihood, e.g. further along the lane).

Run:  rosrun cottonsim_experiments kidnap_relocalization_sim.py [seeds] [key=value ...]
          [--traces=FILE]
      key=value: LocalizationQualityConfig fields to override (e.g. relocalize_particles=2000);
      --traces: go on with re-localising updates after "localised" (standing updates with roughening; the
          free-space check then follows free_space_mode) and write every update's error as JSON.
Results: docs/map_experiment.md, "Kidnap".
"""
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from cottonsim_common.config.yaml_files import load_yaml_file  # noqa: E402
from cottonsim_experiments.reproduce.packages import package_path  # noqa: E402
from cottonsim_navigation.core.grid import GridSpec  # noqa: E402
from cottonsim_navigation.localization.amcl import Amcl, AmclConfig  # noqa: E402
from cottonsim_navigation.localization.free_space_model import FreeSpaceConfig  # noqa: E402
from cottonsim_navigation.localization.quality import LocalizationQualityConfig  # noqa: E402
from cottonsim_navigation.localization.sensor_models import Scan  # noqa: E402
from cottonsim_navigation.localization.supervisor import LocalizationSupervisor, SupervisorConfig  # noqa: E402
from cottonsim_common.ros.params import config_from_params  # noqa: E402
from cottonsim_world.config_io import simulator_config_from_dict  # noqa: E402
from cottonsim_world.farm.config import FarmConfig  # noqa: E402
from cottonsim_world.farm.export import load_map_yaml, world_to_frame  # noqa: E402
from cottonsim_world.farm.generator import generate_farm  # noqa: E402
from cottonsim_world.robot.urdf_model import UrdfModel  # noqa: E402
from cottonsim_world.readings import LidarReading  # noqa: E402
from cottonsim_world.simulator import Simulator  # noqa: E402

NAV = Path(package_path("cottonsim_navigation"))
LANDING_WORLD = (-1.43, 7.0, math.pi / 2)      # lane 1's entry, 1.95 m before the first stems (y 8.95)
KIDNAP_M = 3.0                                 # AMCL's estimate is this far behind (the robot was carried forward)
NAVIGATOR_STOPS_AFTER_S = 0.6                 # sim time from the landing to the navigator's stop
RESPREAD_AFTER_S = 1.0                        # ... and to AMCL's re-spread
MAX_S = 20.0                                  # sim time allowed to re-localise
MAX_UPDATES = 40
CR_RADIUS_M = 0.25
WRONG_PEAK_M = 0.5                             # further off than this: the set settled on another peak


def amcl_params():
    params = {}
    for name in ("amcl.yaml", "amcl_farm.yaml"):
        params.update(load_yaml_file(NAV / "config" / name, default={}))
    return {"~" + k: v for k, v in params.items()}


def from_params(cls, params, prefix):
    return config_from_params(cls, prefix=prefix, get_param=lambda n, d=None: params.get(n, d),
                              has_param=lambda n: n in params)


def make_sim(seed):
    settings = load_yaml_file(NAV / "test/rostest/nav_ci.yaml")
    settings["seed"] = seed
    urdf = Path(package_path("cottonsim_description")) / "urdf/cottonsim_robot.urdf"
    return Simulator(simulator_config_from_dict(settings), UrdfModel.from_file(urdf))


def next_scan(sim, laser_pose):
    """Step the simulator until the next LiDAR reading; its /scan_360 as a core Scan."""
    for _ in range(1000):
        for r in sim.step():
            if isinstance(r, LidarReading):
                c = r.scan_360_config
                return Scan.from_laserscan(np.asarray(r.scan_360_ranges, float), c.angle_min_rad,
                                           c.angle_increment_rad, laser_pose, max(c.range_min_m, 0.0),
                                           c.range_max_m)
    raise RuntimeError("no LiDAR reading within 1000 steps")


def run(seed, sim, grid, spec, home, configs, keep_going=False):
    """configs: (AmclConfig, SupervisorConfig)."""
    config, supervisor_config = configs
    sup = LocalizationSupervisor(Amcl(config, np.random.default_rng(seed)), supervisor_config)
    sup.set_map(grid, spec)
    rng = np.random.default_rng(1000 + seed)
    bl = sim.base_T_sensor["velodyne"]
    laser = (float(bl[0, 3]), float(bl[1, 3]), math.atan2(bl[1, 0], bl[0, 0]))

    def truth_now():
        tb = sim.world_T_base()
        world = (tb[0, 3], tb[1, 3], math.atan2(tb[1, 0], tb[0, 0]))
        return np.array(world_to_frame(home, *world), float), np.array(world, float)

    # as in the rostest: the robot drives toward the rows, is carried forward (it lands at rest), the
    # navigator goes on commanding 0.5 m/s until AMCL says "not localised" (~0.6 s), then stops it; AMCL
    # confirms the kidnap and re-spreads ~1 s after the landing
    sim.teleport_robot(LANDING_WORLD[0] + rng.normal(0.0, 0.05), LANDING_WORLD[1] + rng.normal(0.0, 0.1),
                       LANDING_WORLD[2] + rng.normal(0.0, 0.03))
    t_kidnap = sim.time_s
    for _ in range(1000):
        sim.command_velocity(0.5 if sim.time_s < t_kidnap + NAVIGATOR_STOPS_AFTER_S else 0.0, 0.0)
        sim.step()
        if sim.time_s >= t_kidnap + RESPREAD_AFTER_S:
            break
    truth, _ = truth_now()
    behind_m = KIDNAP_M + rng.uniform(-0.7, 0.3)        # the robot drove on a little before AMCL noticed
    estimate = truth - behind_m * np.array([math.cos(truth[2]), math.sin(truth[2]), 0.0])
    sup.respread_after_kidnap(estimate)
    trace = []         # one entry per filter update: the error then and the monitor's numbers
    while sim.time_s < t_kidnap + RESPREAD_AFTER_S + MAX_S and len(trace) < MAX_UPDATES:
        sim.command_velocity(0.0, 0.0)
        scan = next_scan(sim, laser)
        truth, world = truth_now()
        if keep_going:
            sup.stationary.start_relocalizing()
        # perfect odometry (the ground truth in the world frame): only its increments matter to AMCL
        step = sup.step(sim.time_s, tuple(world), scan)
        if not step.updated:
            continue
        p, localized = step.result.pose, step.localized
        dx, dy = p.x_m - truth[0], p.y_m - truth[1]
        c, s = math.cos(truth[2]), math.sin(truth[2])
        trace.append(dict(along=c * dx + s * dy, across=-s * dx + c * dy, pose=(p.x_m, p.y_m, p.yaw_rad),
                          yaw=math.atan2(math.sin(p.yaw_rad - truth[2]), math.cos(p.yaw_rad - truth[2])),
                          fit=step.hit_fraction, spread=step.std_xy_m, spread_yaw=step.std_yaw_rad,
                          localized=localized, t=sim.time_s - t_kidnap))
        if localized and not keep_going:
            break
    return trace


def first_localized(trace):
    """The update at which the node would declare itself localised again (None: not within the trace)."""
    return next((i for i, u in enumerate(trace) if u["localized"]), None)


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    trace_file = next((a.split("=", 1)[1] for a in sys.argv[1:] if a.startswith("--traces=")), None)
    seeds = int(args[0]) if args else 20
    overrides = {}
    for arg in args[1:]:
        key, value = arg.split("=", 1)
        overrides[key] = type(getattr(LocalizationQualityConfig(), key))(value)
    grid, resolution, origin = load_map_yaml(str(NAV / "config/maps/farm_slam.yaml"))
    spec = GridSpec(resolution, grid.shape[1], grid.shape[0], origin[0], origin[1])
    home = generate_farm(FarmConfig()).spawn
    params = amcl_params()
    configs = (from_params(AmclConfig, params, "~"),
               SupervisorConfig(params.get("~free_space_mode", SupervisorConfig.free_space_mode),
                                from_params(FreeSpaceConfig, params, "~free_space_"),
                                dataclasses.replace(from_params(LocalizationQualityConfig, params, "~localized_"),
                                                    **overrides)))
    t0 = time.monotonic()
    sim = make_sim(0)
    traces = []
    for seed in range(seeds):
        trace = run(seed, sim, grid, spec, home, configs, keep_going=trace_file is not None)
        traces.append(trace)
        i = first_localized(trace)
        u = trace[-1 if i is None else i]
        off = math.hypot(u["along"], u["across"])
        state = "NOT localised" if i is None else "localised after %2d" % (i + 1)
        print(f"seed {seed:3d}: {state} updates ({u['t']:4.1f} s after the landing), "
              f"{u['along']:+.2f} m along {u['across']:+.2f} m across {u['yaw']:+.3f} rad, fit {u['fit']:.2f}, "
              f"spread {u['spread']:.3f} m{'   <-- off' if off > CR_RADIUS_M else ''}", flush=True)
    done = [t[first_localized(t)] for t in traces if first_localized(t) is not None]
    bad = [u for u in done if math.hypot(u["along"], u["across"]) > CR_RADIUS_M]
    errors = sorted(math.hypot(u["along"], u["across"]) for u in done)
    times = sorted(u["t"] for u in done)
    summary = (f"median error {errors[len(errors) // 2]:.3f} m, median time {times[len(times) // 2]:.1f} s, "
               f"max time {times[-1]:.1f} s") if done else ""
    wrong = [e for e in errors if e > WRONG_PEAK_M]
    print(f"{len(done)}/{seeds} localised by themselves; of these {len(bad)} more than {CR_RADIUS_M} m off, "
          f"{len(wrong)} more than {WRONG_PEAK_M} m (a wrong peak); "
          f"{summary}; overrides {overrides or 'none'}; {time.monotonic() - t0:.0f} s")
    if trace_file:
        Path(trace_file).write_text(json.dumps(traces))


if __name__ == "__main__":
    main()
