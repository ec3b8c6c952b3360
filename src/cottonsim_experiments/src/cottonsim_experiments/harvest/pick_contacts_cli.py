"""``harvest_pick_contacts``: how often the robot's planned picks touch the plants' stems and branches.

Plans the picks of the lane-facing bolls of some plants beside a lane as the harvest node would
(its planner and its stem estimates, ground-truth targets) and sweeps every motion against the
plants' true wood (harvest/pick_contacts.py); prints the counts as JSON. The planner's settings are
ApproachConfig's defaults, changed with the options below.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import pathlib
import sys
import time
from typing import List, Optional

from cottonsim_experiments.harvest.pick_contacts import PickContactsConfig, plan_picks, summarise
from cottonsim_experiments.harvest.reachability import robot_geometry_from_urdf
from cottonsim_experiments.harvest.reachability_cli import default_urdf_path


def main(argv: Optional[List[str]] = None) -> int:
    defaults = PickContactsConfig()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="the farm's seed (default 0)")
    parser.add_argument("--lane", type=int, default=defaults.lane_index, help="the robot's lane (default 1)")
    parser.add_argument("--first-plant", type=int, default=defaults.first_plant,
                        help=f"the first plant beside the lane studied (default {defaults.first_plant})")
    parser.add_argument("--plants", type=int, default=defaults.plants,
                        help=f"plants studied (default {defaults.plants})")
    parser.add_argument("--shoulder-offset", type=float, default=defaults.shoulder_offset_m,
                        help="the shoulder stands this far past each boll along the lane [m] (default 0)")
    parser.add_argument("--down-the-lane", action="store_true",
                        help="the robot heads down the lane (-y; the route's even lanes) instead of up it")
    parser.add_argument("--via-distance", type=float, help="ApproachConfig.via_distance_m [m]")
    parser.add_argument("--pregrasp-distance", type=float, help="ApproachConfig.pregrasp_distance_m [m]")
    parser.add_argument("--urdf", type=pathlib.Path, help="robot description (default: cottonsim_description's)")
    parser.add_argument("--json", type=pathlib.Path, help="also write the summary and every pick here")
    args = parser.parse_args(argv)
    from cottonsim_manipulation.harvest.harvester import Harvester, HarvestConfig
    from cottonsim_manipulation.harvest.pick_cycle import PickCycleConfig
    from cottonsim_manipulation.harvest.targets import TargetFusion, TargetFusionConfig
    from cottonsim_manipulation.planning.approach import ApproachConfig, plan_approach
    from cottonsim_manipulation.planning.trajectory import TrajectoryConfig
    from cottonsim_world.farm.config import FarmConfig
    from cottonsim_world.farm.generator import generate_farm

    try:
        config = PickContactsConfig(lane_index=args.lane, first_plant=args.first_plant, plants=args.plants,
                                    shoulder_offset_m=args.shoulder_offset,
                                    yaw_rad=-0.5 * math.pi if args.down_the_lane else 0.5 * math.pi)
        approach = ApproachConfig()
        if args.via_distance is not None:
            approach = dataclasses.replace(approach, via_distance_m=args.via_distance)
        if args.pregrasp_distance is not None:
            approach = dataclasses.replace(approach, pregrasp_distance_m=args.pregrasp_distance)
    except ValueError as exc:
        print(f"harvest_pick_contacts: {exc}", file=sys.stderr)
        return 2
    farm = generate_farm(FarmConfig(seed=args.seed))
    robot = robot_geometry_from_urdf((args.urdf or default_urdf_path()).read_text())
    trajectory = TrajectoryConfig()

    def harvester():
        return Harvester(lambda p, n, q, stems: plan_approach(p, n, q, robot.model, stems, approach, trajectory),
                         HarvestConfig(), TargetFusion(TargetFusionConfig(confirm_observations=1)),
                         approach_config=approach, trajectory_config=trajectory)

    start = time.perf_counter()
    try:
        picks = plan_picks(farm, robot, harvester, PickCycleConfig().bin_joints_rad, config)
    except ValueError as exc:
        print(f"harvest_pick_contacts: {exc}", file=sys.stderr)
        return 2
    summary = summarise(picks)
    summary["approach"] = {"via_distance_m": approach.via_distance_m,
                           "pregrasp_distance_m": approach.pregrasp_distance_m}
    summary["wall_s"] = round(time.perf_counter() - start, 1)
    print(json.dumps(summary, indent=2))
    if args.json:
        summary["picks"] = [dataclasses.asdict(p) for p in picks]
        args.json.write_text(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
