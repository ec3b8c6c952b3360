#!/usr/bin/env python3
"""Do the GPS global costmap's lanes stay open and its rows shut? Offline, on the default farm.

Drives the default farm's GPS route (ground-truth poses, straight legs between the waypoints, one
global-costmap update every --step-m), casts the VLP-16 at each pose, keeps the PassThrough band (or,
with --band, a height band of the full cloud), moves the returns into the map frame through a
believed pose = truth + a localisation error (a Gauss-Markov wander of --noise-xy-m and
--noise-yaw-rad, 1 sigma, correlation time --correlation-s at 0.5 m/s), and feeds them to an obstacle
layer + inflation configured as config/global_costmap_obstacles.yaml, once per lethal radius given.
At the end it prints, per lane, the narrowest width of the cells a plan may use (cost < 253) across
the lane where it has plants on both sides, and, per row, the length of navfn's plan between the
middles of the two lanes beside it (about 16 m around the row's end; a few metres = through the row).

  source scripts/env.sh && python benchmarks/gps_global_costmap_lanes.py --lethal-radius inscribed 0.25 0.20 \\
      [--noise-xy-m 0.06 --noise-yaw-rad 0.025] [--band -0.10 0.0]
"""
import argparse
import math

import numpy as np

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.core.grid import INSCRIBED_INFLATED_OBSTACLE, GridSpec
from cottonsim_navigation.planning.costmap import (Costmap2D, CostmapConfig, InflationLayer, InflationLayerConfig,
                                                   StaticLayer)
from cottonsim_navigation.planning.global_planners.navfn import NavfnConfig, NavfnPlanner
from cottonsim_navigation.planning.obstacle_layer import ObstacleLayer, ObstacleLayerConfig
from cottonsim_world.farm.generator import FarmConfig, default_route, generate_farm
from cottonsim_world.sensors.cloud_filters import PassThroughConfig, original_passthrough_mask
from cottonsim_world.sensors.lidar import LidarConfig, Vlp16Model
from cottonsim_world.sensors.scene import SceneConfig, SensorScene

BASE_LINK_HEIGHT_M = 0.13228             # base_link above the ground: the odom / map frames' z = 0
VELODYNE_HEIGHT_M = 0.38                 # the 'velodyne' frame above the ground
VELODYNE_IN_BASE_XY_M = (0.43, -0.125)   # the 'velodyne' frame in base_link (yawed +90 deg)
SPEED_M_S = 0.5


def velodyne_pose(x_m, y_m, yaw_rad):
    """world_T_velodyne for the robot at (x, y, yaw)."""
    sx, sy = VELODYNE_IN_BASE_XY_M
    c, s = math.cos(yaw_rad + math.pi / 2), math.sin(yaw_rad + math.pi / 2)
    pose = np.eye(4)
    pose[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    pose[:3, 3] = (x_m + sx * math.cos(yaw_rad) - sy * math.sin(yaw_rad),
                   y_m + sx * math.sin(yaw_rad) + sy * math.cos(yaw_rad), VELODYNE_HEIGHT_M)
    return pose


def route_poses(route, step_m):
    """Ground-truth poses every step_m along straight legs from Home through the waypoints."""
    corners = [(-6.0, 1.0)] + [(p.x_m, p.y_m) for p in route]
    poses = []
    for (x0, y0), (x1, y1) in zip(corners[:-1], corners[1:]):
        n = max(1, int(math.hypot(x1 - x0, y1 - y0) / step_m))
        yaw = math.atan2(y1 - y0, x1 - x0)
        poses += [(x0 + (x1 - x0) * i / n, y0 + (y1 - y0) * i / n, yaw) for i in range(n)]
    return poses


def lane_widths_m(costmap, route, lanes, y_from_m, y_to_m):
    """Per lane: the narrowest run of usable cells through the lane's centre line between y_from and y_to."""
    spec, widths = costmap.spec, []
    for k in range(lanes):
        x_m, narrowest = route[3 * k].x_m, math.inf
        for y_m in np.arange(y_from_m, y_to_m, 0.1):
            cx, cy = (int(v) for v in spec.world_to_map(x_m, y_m))
            usable = costmap.costs[cy] < INSCRIBED_INFLATED_OBSTACLE
            if not usable[cx]:
                narrowest = 0.0
                break
            left = cx - int(np.argmin(usable[cx::-1])) + 1 if not usable[:cx + 1].all() else 0
            right = cx + int(np.argmin(usable[cx:])) - 1 if not usable[cx:].all() else spec.width - 1
            narrowest = min(narrowest, (right - left + 1) * spec.resolution_m)
        widths.append(round(narrowest, 2))
    return widths


def measure(args, lidar, route, farm_config, lethal_radius_m):
    spec = GridSpec(0.05, 600, 720, -24.0, -3.0)
    band = args.band or (-100.0, 100.0)
    obstacles = ObstacleLayer(ObstacleLayerConfig(clearing_miss_count=5, min_obstacle_height=band[0],
                                                  max_obstacle_height=band[1]))
    costmap = Costmap2D(CostmapConfig(track_unknown_space=True),
                        [StaticLayer(), obstacles, InflationLayer(InflationLayerConfig(lethal_radius_m=lethal_radius_m))])
    costmap.resize(spec)
    costmap.static_layer.set_map(np.zeros(spec.shape, np.int8), spec)
    rng = np.random.default_rng(args.seed)
    sigma = np.array([args.noise_xy_m, args.noise_xy_m, args.noise_yaw_rad])
    keep = math.exp(-args.step_m / SPEED_M_S / args.correlation_s)
    error = np.zeros(3)
    for x_m, y_m, yaw_rad in route_poses(route, args.step_m):
        error = keep * error + math.sqrt(1 - keep * keep) * rng.normal(0.0, 1.0, 3) * sigma
        pose = velodyne_pose(x_m, y_m, yaw_rad)
        scan = lidar.scan(pose)
        points = scan.points if args.band else scan.points[original_passthrough_mask(scan.points, PassThroughConfig())]
        world = points.astype(float) @ pose[:3, :3].T + pose[:3, 3]
        c, s = math.cos(error[2]), math.sin(error[2])
        believed = lambda xy: np.column_stack([x_m + error[0] + c * (xy[:, 0] - x_m) - s * (xy[:, 1] - y_m),  # noqa: E731
                                               y_m + error[1] + s * (xy[:, 0] - x_m) + c * (xy[:, 1] - y_m)])
        cloud = np.column_stack([believed(world[:, :2]), world[:, 2] - BASE_LINK_HEIGHT_M])
        origin = np.r_[believed(pose[None, :2, 3])[0], VELODYNE_HEIGHT_M - BASE_LINK_HEIGHT_M]
        obstacles.add_observation(cloud, origin)
        costmap.update_map(Pose2D(x_m + error[0], y_m + error[1], yaw_rad + error[2]), 14.0)
    lanes = farm_config.lane_count
    widths = lane_widths_m(costmap, route, lanes, farm_config.first_plant_y_m, farm_config.last_plant_y_m)
    middle_y_m = 0.5 * (farm_config.first_plant_y_m + farm_config.last_plant_y_m)
    planner = NavfnPlanner(NavfnConfig())
    crossings = []
    for k in range(lanes - 1):
        plan = planner.make_plan(costmap, Pose2D(route[3 * k].x_m, middle_y_m, 0.0),
                                 Pose2D(route[3 * k + 3].x_m, middle_y_m, 0.0))
        crossings.append(round(plan.length_m(), 1) if plan.ok else None)
    return widths, crossings


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--lethal-radius", nargs="+", default=["inscribed", "0.25"],
                        help="lethal radii to compare [m]; 'inscribed' = the footprint's (0.365 m)")
    parser.add_argument("--noise-xy-m", type=float, default=0.01)
    parser.add_argument("--noise-yaw-rad", type=float, default=0.003)
    parser.add_argument("--correlation-s", type=float, default=20.0)
    parser.add_argument("--step-m", type=float, default=0.3, help="robot travel between global updates [m]")
    parser.add_argument("--band", nargs=2, type=float, metavar=("MIN_Z", "MAX_Z"),
                        help="mark from the full cloud in this z band of the map frame [m] (default: PassThrough)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    farm_config = FarmConfig()
    lidar = Vlp16Model(SensorScene(generate_farm(farm_config), SceneConfig()), LidarConfig())
    route = default_route(farm_config)[0]
    print(f"noise {args.noise_xy_m} m / {args.noise_yaw_rad} rad (1 sigma), seed {args.seed}, "
          f"band {args.band or 'PassThrough'}")
    for name in args.lethal_radius:
        radius = None if name == "inscribed" else float(name)
        widths, crossings = measure(args, lidar, route, farm_config, radius)
        print(f"lethal radius {name}: usable lane width, narrowest, lanes 1-{len(widths) - 2} [m] {widths[1:-1]}; "
              f"plan between neighbouring lanes [m] {crossings}", flush=True)


if __name__ == "__main__":
    main()
