"""Where the robot's planned picks touch the plants' stems and branches: an offline study, no ROS, no sim run.

The robot does not see stems and branches; its planner keeps clear of the stems it estimates
(cottonsim_manipulation.harvest.harvester). How often its motions still touch the plants' wood is
a question about the planner alone, answered here in seconds instead of a 35-minute harvest run:

* the farm of a seed; for the bolls on the lane-facing halves of some plants beside a lane, the
  robot stands on the lane's centre line, heading ``yaw_rad`` (pi/2: up the lane, -pi/2: down it),
  with the UR5e's shoulder ``shoulder_offset_m`` past the boll along its heading (the route stops
  when a boll comes abeam);
* the harvest node's own planning (``Harvester.plan_from_here``): every boll of the farm is a
  ground-truth target, the outward direction and the stems are estimated as on the route, the
  arm starts at the ready pose (the nozzle over the bin);
* every planned motion, transit (ready pose -> pre-grasp), approach, retreat and deliver (back to
  the bin), is swept in joint steps of ``sweep_step_rad`` against the plants' true stems and main
  branches with the simulator's contact geometry (cottonsim_world.robot.arm_contacts: the link
  capsules unpadded, the nozzle's tip allowance left out).

A pick *touches* when any link of any motion overlaps a stem or branch. The approach is also
swept against every boll of the farm (all on their plants) with the nozzle's capture rule
(cottonsim_common.vacuum_capture, the simulator's: the nearest boll to the tip, when it
qualifies): the boll it *captures* first is the target, a neighbour, or none. ``summarise``
counts the planner's results, the touching picks and the touches by phase, arm link and plant
part (one touch = one (phase, link, capsule) pair of a pick), the captures (a neighbour caught
first: 'neighbour_planned_clear' when that neighbour is a study boll whose own approach catches
it, so picking it first clears the way), and the mean durations of the motions.
Frames: world (the farm's), metres, radians.
"""
from __future__ import annotations

import collections
import math
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from cottonsim_common.kinematics.arm_capsules import ARM_LINKS, ArmCollisionConfig
from cottonsim_common.kinematics.ur5e import link_frames
from cottonsim_common.vacuum_capture import CaptureConfig, check_capture
from cottonsim_common.validation import require_fields, require_int

PHASES = ("transit", "approach", "retreat", "deliver")
CAPTURE_STEP_RAD = 0.002       # joint step of the capture sweep: the tip moves ~2 mm (half a 2 cm capture radius / 5)


@dataclass(frozen=True)
class PickContactsConfig:
    """The study's set-up.

    lane_index: the lane the robot stands on; first_plant: the first plant (from the lane's start,
    both rows beside it) whose bolls are picked; plants: how many plants from there.
    shoulder_offset_m: the shoulder stands this far past the boll along the robot's heading [m].
    yaw_rad: the robot's heading on the lane (world; pi/2 up the lane, -pi/2 down it) [rad].
    sweep_step_rad: the largest joint step between two configurations checked [rad].
    """

    lane_index: int = 1
    first_plant: int = 4
    plants: int = 12
    shoulder_offset_m: float = 0.0
    yaw_rad: float = 0.5 * math.pi
    sweep_step_rad: float = 0.01

    def __post_init__(self) -> None:
        for name in ("lane_index", "first_plant"):
            require_int(f"PickContactsConfig.{name}", getattr(self, name), 0)
        require_int("PickContactsConfig.plants", self.plants, 1)
        require_fields(self, "PickContactsConfig.", finite=("shoulder_offset_m", "yaw_rad"), positive=("sweep_step_rad",))


@dataclass(frozen=True)
class Touch:
    """One link of one motion overlapping one stem or branch capsule of a plant."""

    phase: str
    link: str
    part: str
    plant_id: int
    depth_m: float


@dataclass(frozen=True)
class PlannedPick:
    """A boll's planned pick: the planner's reason ('ok', 'unreachable', ...) and detail, its touches and the
    durations of its motions [s] (transit, approach, retreat; None when not planned)."""

    boll_id: int
    reason: str
    detail: str = ""
    touches: Tuple[Touch, ...] = ()
    durations_s: Optional[Tuple[float, float, float]] = None
    captured_id: int = -1           # the boll the approach captures first (-1: none; planned picks only)


def sweep(path_rad: np.ndarray, step_rad: float) -> np.ndarray:
    """The straight joint-space segments through path_rad (N, 6), every step at most step_rad on any joint."""
    path = np.asarray(path_rad, dtype=float)
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(math.ceil(np.abs(b - a).max() / step_rad)))
        out.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
    return np.concatenate(out)


def touches_of(path_rad: np.ndarray, woody_arm, contact_model, phase: str, step_rad: float) -> List[Touch]:
    """The (link, capsule) overlaps along a joint path, each once, with its deepest overlap.
    woody_arm: the plants' stems and branches in the arm's base frame (names '<part>/<plant id>')."""
    configs = sweep(path_rad, step_rad)
    clearance, _, _ = contact_model.clearances(configs, woody_arm)          # (K, links, capsules)
    deepest: Dict[Tuple[int, int], float] = {}
    for k, li, ci in np.argwhere(clearance < 0.0):
        deepest[(li, ci)] = min(deepest.get((li, ci), 0.0), float(clearance[k, li, ci]))
    out = []
    for (li, ci), depth in sorted(deepest.items()):
        part, plant = woody_arm.names[ci].split("/")
        out.append(Touch(phase, ARM_LINKS[li], part, int(plant), -depth))
    return out


def first_capture(path_rad: np.ndarray, arm_T_world: np.ndarray, centres_world_m: np.ndarray,
                  outwards_world: np.ndarray, nozzle_length_m: float, step_rad: float,
                  capture: CaptureConfig = CaptureConfig()) -> int:
    """Index of the boll the nozzle captures first along a joint path (vacuum on throughout, every boll on its
    plant; the simulator's rule: the nearest boll to the tip, when it qualifies), -1 for none."""
    configs = sweep(path_rad, step_rad)
    flange = link_frames(configs)[:, -1]                                            # (K, 4, 4), arm base
    world_T_arm = np.linalg.inv(arm_T_world)
    axes = flange[:, :3, 2] @ world_T_arm[:3, :3].T
    tips = (flange[:, :3, 3] + nozzle_length_m * flange[:, :3, 2]) @ world_T_arm[:3, :3].T + world_T_arm[:3, 3]
    for tip, axis in zip(tips, axes):
        nearest = int(np.argmin(np.linalg.norm(centres_world_m - tip, axis=1)))
        if check_capture(tip, axis, centres_world_m[nearest], outwards_world[nearest], capture).captured:
            return nearest
    return -1


def study_bolls(farm, config: PickContactsConfig) -> List[int]:
    """Ids of the bolls (BollField numbering) on the lane-facing halves of the study's plants."""
    from cottonsim_experiments.harvest.reachability import lane_facing
    from cottonsim_world.farm.bolls import BollField

    lane = _lane(farm, config.lane_index)
    beside = sorted((p for p in farm.plants if abs(p.x_m - lane.x_m) <= 1.5), key=lambda p: (p.y_m, p.x_m))
    chosen = {p.plant_id: p for p in beside[config.first_plant:config.first_plant + config.plants]}
    bolls = BollField(farm)
    positions = bolls.positions_m()
    return [i for i in range(bolls.count) if int(bolls.plant_id[i]) in chosen and
            lane_facing(positions[i], (chosen[int(bolls.plant_id[i])].x_m, chosen[int(bolls.plant_id[i])].y_m), [lane])]


def _lane(farm, index: int):
    lanes = [lane for lane in farm.lanes if lane.index == index]
    if not lanes:
        raise ValueError(f"the farm has no lane {index} (lanes {[lane.index for lane in farm.lanes]})")
    return lanes[0]


def plan_picks(farm, robot, harvester_factory, ready_rad, config: PickContactsConfig = PickContactsConfig(),
               boll_ids: Optional[Sequence[int]] = None) -> List[PlannedPick]:
    """Plan the study's picks (module docstring) and find their touches.

    robot: cottonsim_experiments.harvest.reachability.RobotGeometry (the arm on the base, the body);
    harvester_factory: () -> a cottonsim_manipulation Harvester whose planner is the one studied;
    ready_rad: the joints every pick starts from and delivers to (the bin pose)."""
    from cottonsim_world.farm.bolls import BollField
    from cottonsim_world.farm.plant_obstacles import PlantObstacles
    from cottonsim_world.robot.arm_contacts import ArmContactConfig
    from cottonsim_manipulation.planning.collision import ArmCollisionModel

    lane = _lane(farm, config.lane_index)
    bolls = BollField(farm)
    positions = bolls.positions_m()
    ids = study_bolls(farm, config) if boll_ids is None else [int(i) for i in boll_ids]
    harvester = harvester_factory()
    harvester.add_detections(positions, 0.0, harvester.fusion.config.min_sigma_m)
    obstacles = PlantObstacles.from_farm(farm)
    contact_model = ArmCollisionModel(ArmContactConfig().arm_shape())
    ready = np.asarray(ready_rad, dtype=float)
    shoulder_x = float(robot.base_T_arm[0, 3])
    heading = (math.cos(config.yaw_rad), math.sin(config.yaw_rad))
    if abs(heading[0]) > 1e-6:
        raise ValueError(f"PickContactsConfig.yaw_rad must point along the lane (+-pi/2), got {config.yaw_rad}")
    out = []
    for boll_id in ids:
        p = positions[boll_id]
        along = (config.shoulder_offset_m - shoulder_x) * heading[1]        # base_link behind the shoulder
        world_T_base = np.array([[heading[0], -heading[1], 0.0, lane.x_m],
                                 [heading[1], heading[0], 0.0, p[1] + along],
                                 [0.0, 0.0, 1.0, robot.base_height_m], [0.0, 0.0, 0.0, 1.0]])
        arm_T_world = np.linalg.inv(world_T_base @ robot.base_T_arm)
        harvester.update_pose(arm_T_world, np.linalg.inv(robot.base_T_arm))
        result = harvester.plan_from_here(p, ready)
        if not result.ok:
            out.append(PlannedPick(boll_id, result.reason, result.detail))
            continue
        plan = result.plan
        woody = obstacles.woody_capsules(obstacles.plants_near(p, 1.5)).transformed(arm_T_world)
        paths = (plan.transit.waypoints_rad, plan.approach.waypoints_rad, plan.retreat.waypoints_rad,
                 np.stack([plan.q_retreat_rad, ready]))
        touches = [t for phase, path in zip(PHASES, paths)
                   for t in touches_of(path, woody, contact_model, phase, config.sweep_step_rad)]
        captured = first_capture(plan.approach.waypoints_rad, arm_T_world, positions, bolls.outward,
                                 ArmCollisionConfig().nozzle_length_m, CAPTURE_STEP_RAD)
        out.append(PlannedPick(boll_id, "ok", result.detail, tuple(touches),
                               (plan.transit.duration_s, plan.approach.duration_s, plan.retreat.duration_s),
                               captured))
    return out


def summarise(picks: Sequence[PlannedPick]) -> Dict:
    """Counts (module docstring): bolls, results, touching picks, touches by phase / link / part, mean
    motion durations [s]."""
    planned = [p for p in picks if p.reason == "ok"]
    touches = [t for p in planned for t in p.touches]
    durations = np.array([p.durations_s for p in planned]) if planned else np.zeros((0, 3))
    by_id = {p.boll_id: p for p in planned}
    neighbour = [p for p in planned if p.captured_id not in (-1, p.boll_id)]
    return {
        "bolls": len(picks),
        "results": dict(sorted(collections.Counter(p.reason for p in picks).items())),
        "touching_picks": sum(1 for p in planned if p.touches),
        "touching_percent_of_planned": 100.0 * sum(1 for p in planned if p.touches) / len(planned) if planned else None,
        "touches_by_phase": {ph: sum(1 for t in touches if t.phase == ph) for ph in PHASES},
        "touches_by_link": dict(sorted(collections.Counter(t.link for t in touches).items())),
        "touches_by_part": dict(sorted(collections.Counter(t.part for t in touches).items())),
        "captures": {"target": sum(1 for p in planned if p.captured_id == p.boll_id),
                     "neighbour": len(neighbour),
                     "neighbour_planned_clear": sum(1 for p in neighbour if by_id.get(p.captured_id) is not None and
                                                    by_id[p.captured_id].captured_id == p.captured_id),
                     "none": sum(1 for p in planned if p.captured_id == -1)},
        "mean_motion_s": {name: float(durations[:, k].mean()) if len(durations) else None
                          for k, name in enumerate(("transit", "approach", "retreat"))},
    }
