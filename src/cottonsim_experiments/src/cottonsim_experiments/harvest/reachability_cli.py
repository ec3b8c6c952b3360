"""``harvest_reachability``: the share of a farm's open bolls the arm can reach from the route.

Prints, for the farm of config/sim.yaml's defaults (or --seed / --rows), the open bolls, those on
the lane-facing halves of their plants, how many of each are reachable (harvest/reachability.py)
and why the others are not; --json writes every boll's verdict.
"""
from __future__ import annotations

import argparse
import collections
import dataclasses
import json
import math
import pathlib
import sys
import time
from typing import List, Optional

from cottonsim_experiments.harvest.reachability import (ReachabilityConfig, farm_reachability, lane_facing,
                                                        robot_geometry_from_urdf)
from cottonsim_manipulation.planning.approach import ApproachConfig


def default_urdf_path() -> pathlib.Path:
    import rospkg

    return pathlib.Path(rospkg.RosPack().get_path("cottonsim_description")) / "urdf" / "cottonsim_robot.urdf"


def route_headings(farm) -> dict:
    """Lane index -> the robot's yaw along it on the farm's route (north when the route does not say)."""
    headings = {}
    for lane in farm.lanes:
        yaws = [p.yaw_rad for p in farm.route if abs(p.x_m - lane.x_m) < 1e-6]
        headings[lane.index] = yaws[0] if yaws else 0.5 * math.pi
    return headings


def summarise(farm, verdicts) -> dict:
    """Counts over all open bolls and over those on lane-facing halves (the issue's >= 95 % target)."""
    plants = {p.plant_id: p for p in farm.plants}
    from cottonsim_world.farm.bolls import BollField

    field = BollField(farm)
    positions = field.positions_m()
    facing = [lane_facing(positions[v.boll_id], (plants[int(field.plant_id[v.boll_id])].x_m,
                                                 plants[int(field.plant_id[v.boll_id])].y_m), farm.lanes)
              for v in verdicts]
    out = {"open_bolls": len(verdicts), "reachable": sum(v.reachable for v in verdicts),
           "lane_facing": sum(facing), "lane_facing_reachable": sum(v.reachable for v, f in zip(verdicts, facing) if f),
           "reasons": dict(collections.Counter(v.reason for v in verdicts)),
           "lane_facing_reasons": dict(collections.Counter(v.reason for v, f in zip(verdicts, facing) if f))}
    out["reachable_percent"] = 100.0 * out["reachable"] / max(1, out["open_bolls"])
    out["lane_facing_reachable_percent"] = 100.0 * out["lane_facing_reachable"] / max(1, out["lane_facing"])
    return out


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="the farm's seed (default 0)")
    parser.add_argument("--rows", type=int, nargs="*", help="only the plants of these rows (default: all)")
    parser.add_argument("--urdf", type=pathlib.Path, help="robot description (default: cottonsim_description's)")
    parser.add_argument("--roll-samples", type=int, help="nozzle rolls tried (default: the planner's, "
                                                            "ApproachConfig.roll_samples)")
    parser.add_argument("--yaw-samples", type=float, nargs="+",
                        help="approach directions turned about the vertical by these [rad] (default: the "
                             "planner's, ApproachConfig.yaw_samples_rad; 0 for the outward direction's plane only)")
    parser.add_argument("--json", type=pathlib.Path, help="write the summary and every boll's verdict here")
    args = parser.parse_args(argv)
    from cottonsim_world.farm.config import FarmConfig
    from cottonsim_world.farm.generator import generate_farm

    farm = generate_farm(FarmConfig(seed=args.seed))
    if args.rows:
        farm.plants = [p for p in farm.plants if p.row in set(args.rows)]
    robot = robot_geometry_from_urdf((args.urdf or default_urdf_path()).read_text())
    approach = ApproachConfig()
    if args.roll_samples is not None:
        approach = dataclasses.replace(approach, roll_samples=args.roll_samples)
    if args.yaw_samples is not None:
        approach = dataclasses.replace(approach, yaw_samples_rad=tuple(args.yaw_samples))
    start = time.perf_counter()
    verdicts = farm_reachability(farm, farm.lanes, robot, ReachabilityConfig(approach=approach),
                                 route_headings(farm))
    summary = summarise(farm, verdicts)
    summary["wall_s"] = round(time.perf_counter() - start, 1)
    print(json.dumps(summary, indent=2))
    if args.json:
        summary["bolls"] = [{"boll_id": v.boll_id, "reason": v.reason,
                             "stop": None if v.stop is None else [v.stop.lane_index, v.stop.x_m, v.stop.y_m]}
                            for v in verdicts]
        args.json.write_text(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
