#!/usr/bin/env python3
"""Replay a drive of our simulator through AMCL (the amcl node's policy, offline) and print the error per config.

Record: the simulator (default farm, test/rostest/nav_ci.yaml's sensors) drives a route in the map frame
(Home = the spawn pose) with a simple heading controller on the ground truth; every /scan_360 is stored
with the EKF odometry (odom -> base_link, what the node reads from TF) and the true pose in the Home frame.
Replay: each scan goes through ``LocalizationSupervisor.step`` (AMCL + localised signal + kidnap handling,
as the amcl node) with one of the shipped configurations (amcl.yaml, then the overrides file) on the
shipped SLAM map (config/maps/farm_slam.yaml); the error is the estimate's distance to the truth after
each filter update.

Run:  source scripts/env.sh
      python benchmarks/amcl_replay.py record FILE.npz [--route=lanes|short] [--seed=N]
      python benchmarks/amcl_replay.py replay FILE.npz [CONFIG.yaml ...] [--seeds=N] [key=value ...]
          CONFIG: an overrides file (default: amcl.yaml alone, then amcl_farm.yaml); key=value: parameter
          overrides (ROS names of config/amcl.yaml, e.g. free_space_mode=off).
Results: docs/benchmarks.md, "Localisation and mapping".
"""
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for pkg in ("cottonsim_navigation", "cottonsim_world", "cottonsim_common"):
    sys.path.insert(0, str(ROOT / "src" / pkg / "src"))

from cottonsim_common.config.yaml_files import load_yaml_file  # noqa: E402
from cottonsim_navigation.core.grid import GridSpec  # noqa: E402
from cottonsim_navigation.localization.amcl import Amcl, AmclConfig  # noqa: E402
from cottonsim_navigation.localization.free_space_model import FreeSpaceConfig  # noqa: E402
from cottonsim_navigation.localization.quality import LocalizationQualityConfig  # noqa: E402
from cottonsim_navigation.localization.sensor_models import Scan  # noqa: E402
from cottonsim_navigation.localization.supervisor import LocalizationSupervisor, SupervisorConfig  # noqa: E402
from cottonsim_common.ros.params import config_from_params  # noqa: E402

NAV = ROOT / "src/cottonsim_navigation"
SPEED_M_S = 0.5
# routes in the map frame (Home); lanes at y = -0.97 (in front of Home, 3.95 m ahead), 0.83, 2.63, 4.43
ROUTES = {
    "short": [(3.95, -0.97), (12.0, -0.97)],
    "lanes": [(3.95, -0.97), (25.25, -0.97), (27.0, -0.07), (25.25, 0.83), (3.95, 0.83), (2.2, 1.73),
              (3.95, 2.63), (25.25, 2.63), (27.0, 3.53), (25.25, 4.43), (3.95, 4.43)],
}


def record(path, route="lanes", seed=0):
    """Drive ``route`` in the simulator; save scans, odometry and truth to ``path`` (npz)."""
    from cottonsim_world.config_io import simulator_config_from_dict
    from cottonsim_world.farm.export import world_to_frame
    from cottonsim_world.readings import LidarReading, OdometryReading
    from cottonsim_world.robot.urdf_model import UrdfModel
    from cottonsim_world.simulator import Simulator

    settings = load_yaml_file(NAV / "test/rostest/nav_ci.yaml")
    settings["seed"] = seed
    sim = Simulator(simulator_config_from_dict(settings),
                    UrdfModel.from_file(ROOT / "src/cottonsim_description/urdf/cottonsim_robot.urdf"))
    home = sim.farm.spawn
    bl = sim.base_T_sensor["velodyne"]
    laser = (float(bl[0, 3]), float(bl[1, 3]), math.atan2(bl[1, 0], bl[0, 0]))
    out = dict(t=[], ranges=[], odom=[], truth=[])
    odom = None
    goals = list(ROUTES[route])
    scan_config = None
    while goals and sim.time_s < 600.0:
        tb = sim.world_T_base()
        truth = world_to_frame(home, tb[0, 3], tb[1, 3], math.atan2(tb[1, 0], tb[0, 0]))
        gx, gy = goals[0]
        dist = math.hypot(gx - truth[0], gy - truth[1])
        if dist < 0.3:
            goals.pop(0)
            continue
        err = math.atan2(math.sin(math.atan2(gy - truth[1], gx - truth[0]) - truth[2]),
                         math.cos(math.atan2(gy - truth[1], gx - truth[0]) - truth[2]))
        sim.command_velocity(SPEED_M_S * max(0.0, math.cos(err)) ** 4, max(-0.8, min(0.8, 1.5 * err)))
        for r in sim.step():
            if isinstance(r, OdometryReading):
                odom = (r.filtered.x_m, r.filtered.y_m, r.filtered.yaw_rad)
            elif isinstance(r, LidarReading) and odom is not None:
                scan_config = r.scan_360_config
                out["t"].append(r.stamp_s)
                out["ranges"].append(np.asarray(r.scan_360_ranges, np.float32))
                out["odom"].append(odom)
                out["truth"].append(truth)
    sim.close()
    c = scan_config
    np.savez_compressed(path, t=np.array(out["t"]), ranges=np.array(out["ranges"], np.float16),
                        odom=np.array(out["odom"]), truth=np.array(out["truth"]), laser_pose=np.array(laser),
                        scan=np.array([c.angle_min_rad, c.angle_increment_rad, max(c.range_min_m, 0.0),
                                       c.range_max_m]))
    print(f"{path}: {len(out['t'])} scans, {out['t'][-1]:.1f} s of sim time, route {route!r} "
          f"({'done' if not goals else 'NOT finished'})")


def load_recording(path):
    """npz of :func:`record` -> (stamps, list of Scan, odometry (N, 3), truth (N, 3))."""
    d = np.load(path)
    angle_min, increment, range_min, range_max = (float(v) for v in d["scan"])
    laser = tuple(float(v) for v in d["laser_pose"])
    scans = [Scan.from_laserscan(np.asarray(r, float), angle_min, increment, laser, range_min, range_max)
             for r in d["ranges"]]
    return d["t"], scans, d["odom"], d["truth"]


def shipped_params(*overrides_files, **overrides):
    """config/amcl.yaml, then each overrides file, then ``overrides``: {"~name": value}."""
    params = dict(load_yaml_file(NAV / "config/amcl.yaml", default={}))
    for f in overrides_files:
        params.update(load_yaml_file(Path(f), default={}) or {})
    params.update(overrides)
    return {"~" + k: v for k, v in params.items()}


def supervisor_from_params(params, seed):
    """The amcl node's cores from its parameters (the node's own parameter names and prefixes)."""
    def get(cls, prefix, **extra):
        return config_from_params(cls, prefix=prefix, get_param=lambda n, d=None: params.get(n, d),
                                  has_param=lambda n: n in params, overrides=extra or None)

    extra = {"initial_pose": tuple(float(params.get("~initial_pose_" + k, 0.0)) for k in "xya")}
    for name, field in (("xx", "initial_cov_xx_m2"), ("yy", "initial_cov_yy_m2"), ("aa", "initial_cov_aa_rad2")):
        if "~initial_cov_" + name in params:                 # the node's names for these fields
            extra[field] = float(params["~initial_cov_" + name])
    amcl = Amcl(get(AmclConfig, "~", **extra), np.random.default_rng(seed))
    config = SupervisorConfig(params.get("~free_space_mode", "relocalizing"),
                              get(FreeSpaceConfig, "~free_space_"), get(LocalizationQualityConfig, "~localized_"))
    return LocalizationSupervisor(amcl, config)


def replay(recording, grid, spec, params, seed):
    """Errors [m] after each filter update, the kidnaps and the first 'localised' time of one replay."""
    stamps, scans, odom, truth = recording
    sup = supervisor_from_params(params, seed)
    sup.set_map(grid, spec)
    errors, localized_at = [], None
    for t, scan, o, tr in zip(stamps, scans, odom, truth):
        step = sup.step(float(t), o, scan)
        if step.updated:
            p = step.result.pose
            errors.append(math.hypot(p.x_m - tr[0], p.y_m - tr[1]))
            if step.localized and localized_at is None:
                localized_at = float(t - stamps[0])
    return np.array(errors), sup.kidnaps, localized_at


def load_map():
    from cottonsim_world.farm.export import load_map_yaml
    grid, resolution, origin = load_map_yaml(str(NAV / "config/maps/farm_slam.yaml"))
    return grid, GridSpec(resolution, grid.shape[1], grid.shape[0], origin[0], origin[1])


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--") and "=" not in a]
    opts = dict(a[2:].split("=", 1) for a in sys.argv[1:] if a.startswith("--"))
    if len(args) < 2 or args[0] not in ("record", "replay"):
        raise SystemExit(__doc__)
    if args[0] == "record":
        record(args[1], opts.get("route", "lanes"), int(opts.get("seed", 0)))
        return
    overrides = {}
    for a in sys.argv[2:]:
        if "=" in a and not a.startswith("--"):
            k, v = a.split("=", 1)
            overrides[k] = load_yaml_value(v)
    recording = load_recording(args[1])
    grid, spec = load_map()
    configs = [[]] + [[NAV / "config/amcl_farm.yaml"]] if len(args) == 2 else [[a] for a in args[2:]]
    print(f"{args[1]}: {len(recording[1])} scans, {recording[0][-1] - recording[0][0]:.0f} s; "
          f"overrides {overrides or 'none'}")
    for files in configs:
        name = "amcl.yaml" + "".join(" + " + Path(f).name for f in files)
        params = shipped_params(*files, **overrides)
        for seed in range(int(opts.get("seeds", 2))):
            t0 = time.monotonic()
            errors, kidnaps, localized_at = replay(recording, grid, spec, params, seed)
            print(f"{name:28s} seed {seed}: error mean {errors.mean():6.3f} m, first {errors[0]:5.2f} m, "
                  f"final {errors[-1]:6.3f} m, max after 20 updates {errors[20:].max():6.2f} m; "
                  f"localised at {'never' if localized_at is None else f'{localized_at:.1f} s'}, "
                  f"kidnaps {kidnaps}; {len(errors)} updates, {time.monotonic() - t0:.0f} s", flush=True)


def load_yaml_value(text):
    """'1' -> 1, '0.5' -> 0.5, 'true'/'false' -> bool, anything else the string ('off' stays 'off')."""
    for convert in (int, float):
        try:
            return convert(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


if __name__ == "__main__":
    main()
