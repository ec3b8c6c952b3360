"""Which open bolls can the arm reach from the route? The denominator of the harvest success.

A boll is reachable from a lane when, from some stop on the lane's centre
line (stops every ``stop_spacing_m``, the robot heading along the lane), the
UR5e has a configuration within its joint limits that puts the nozzle tip on
the boll's centre with the nozzle pointing into the boll (against one of the
approach directions the planner tries: the outward direction turned about the
vertical and tilted up, planning.approach.approach_directions with the
planner's ApproachConfig; rolled about its axis by one of its ``roll_samples``),
and the same IK branch reaches the pre-grasp ``pregrasp_distance_m`` out along
that direction, both free of the
plants' stems and main branches, the robot's own body and the arm itself
(leaves are soft and ignored). This is what the approach planner
(cottonsim_manipulation.planning.approach) needs at the ends of its
approach; the transit to the pre-grasp is not checked.

Uses the simulator's ground truth (evaluation side): the bolls' centres and
outward directions and the plants' skeletons (cottonsim_world.farm). Frames:
world (z up, ground z = 0) for the farm, the arm's base frame for the IK
(cottonsim_common.kinematics.ur5e) and the collision model
(cottonsim_manipulation.planning.collision).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional, Sequence

import numpy as np

from cottonsim_common.kinematics.ur5e import NUM_JOINTS, inverse_kinematics_batch
from cottonsim_manipulation.planning.approach import ApproachConfig, approach_directions, tool_rotations
from cottonsim_manipulation.planning.collision import ArmCollisionModel

REASONS = ("reachable", "no_stop_in_range", "no_ik", "collision")
_CHUNK = 8          # candidate configurations checked for collisions at a time


@dataclass(frozen=True)
class ReachabilityConfig:
    """stop_spacing_m: stops along each lane's centre line this far apart [m].
    max_reach_m: only stops within this horizontal distance of a boll are tried [m] (the arm's
        reach plus its mount's offset from base_link).
    approach: the planner's configuration (planning.approach.ApproachConfig, default its defaults, as the
        harvest node's config/harvest.yaml sets them): its approach directions (yaw and tilt samples,
        max_deviation_rad), roll_samples and pregrasp_distance_m are the nozzle poses tried.
    """

    stop_spacing_m: float = 0.1
    max_reach_m: float = 1.4
    approach: ApproachConfig = ApproachConfig()

    def __post_init__(self) -> None:
        for name, low, high in (("stop_spacing_m", 0.01, 5.0), ("max_reach_m", 0.1, 5.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (low <= v <= high):
                raise ValueError(f"ReachabilityConfig.{name} must be a number in [{low}, {high}], got {v!r}")
        if not isinstance(self.approach, ApproachConfig):
            raise ValueError(f"ReachabilityConfig.approach must be an ApproachConfig, got "
                             f"{type(self.approach).__name__}")


@dataclass(frozen=True)
class RobotGeometry:
    """Where the arm sits on the robot: base_T_arm, the arm's base frame in base_link (4x4), and
    base_height_m, base_link's height over the ground [m]; the collision model with the robot's body."""

    base_T_arm: np.ndarray
    base_height_m: float
    model: ArmCollisionModel = field(default_factory=ArmCollisionModel)


@dataclass(frozen=True)
class LaneStop:
    """A stop of the robot: base_link at (x_m, y_m) heading yaw_rad (world), on lane lane_index."""

    lane_index: int
    x_m: float
    y_m: float
    yaw_rad: float


@dataclass(frozen=True)
class BollReach:
    """The verdict on one boll: reason (REASONS), the stop it is reachable from, the joints there."""

    boll_id: int
    reason: str
    stop: Optional[LaneStop] = None
    q_grasp_rad: Optional[np.ndarray] = None

    @property
    def reachable(self) -> bool:
        return self.reason == "reachable"


def lane_stops(lanes: Sequence, spacing_m: float, yaw_rad: float = 0.5 * math.pi) -> List[LaneStop]:
    """Stops every spacing_m along each lane's centre line (farm.model.Lane: x_m, y_start_m, y_end_m),
    from its south end to its north end, the robot heading yaw_rad (default north, along the lane)."""
    stops = []
    for lane in lanes:
        length = float(lane.y_end_m) - float(lane.y_start_m)
        n = max(1, int(math.floor(length / spacing_m + 1e-9)) + 1)
        for y in np.linspace(lane.y_start_m, lane.y_start_m + (n - 1) * spacing_m, n):
            stops.append(LaneStop(int(lane.index), float(lane.x_m), float(y), float(yaw_rad)))
    return stops


def _world_T_arm(stop: LaneStop, robot: RobotGeometry) -> np.ndarray:
    c, s = math.cos(stop.yaw_rad), math.sin(stop.yaw_rad)
    world_T_base = np.array([[c, -s, 0.0, stop.x_m], [s, c, 0.0, stop.y_m], [0.0, 0.0, 1.0, robot.base_height_m],
                             [0.0, 0.0, 0.0, 1.0]])
    return world_T_base @ robot.base_T_arm


def _rigid_inverse(t: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = t[:3, :3].T
    out[:3, 3] = -t[:3, :3].T @ t[:3, 3]
    return out


def reach_boll(boll_id: int, centre_m, outward, stops: Sequence[LaneStop], obstacles, robot: RobotGeometry,
               config: ReachabilityConfig = ReachabilityConfig()) -> BollReach:
    """Whether the boll at centre_m (world) facing `outward` (horizontal unit vector from its stem) is
    reachable from one of `stops`, nearest stop first. obstacles: the plants as
    cottonsim_world.farm.plant_obstacles.PlantObstacles (only their stems and main branches count)."""
    p = np.asarray(centre_m, dtype=float).reshape(-1)
    n = np.asarray(outward, dtype=float).reshape(-1)
    if p.shape != (3,) or n.shape != (3,) or not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
        raise ValueError(f"boll {boll_id}: centre and outward direction must be 3 finite numbers each")
    if np.linalg.norm(n) < 1e-9:
        n = np.array([1.0, 0.0, 0.0])
    d = [math.hypot(s.x_m - p[0], s.y_m - p[1]) for s in stops]
    order = [i for i in np.argsort(d, kind="stable") if d[i] <= config.max_reach_m]
    if not order:
        return BollReach(boll_id, "no_stop_in_range")
    model = robot.model
    nozzle = model.config.nozzle_length_m
    approach = config.approach
    rolls = np.arange(approach.roll_samples) * (2.0 * math.pi / approach.roll_samples)
    woody = obstacles.woody_capsules(obstacles.plants_near(p, config.max_reach_m))
    any_ik = False
    arm_T_world = [_rigid_inverse(_world_T_arm(stops[i], robot)) for i in order]
    for candidate in approach_directions(n, approach):
        direction_world = candidate.vector
        rot_world = tool_rotations(-direction_world, rolls)                        # (R, 3, 3)
        # the nozzle's grasp and pre-grasp poses from every stop in range, in one IK call
        poses = np.zeros((len(order), len(rolls), 2, 4, 4))
        for k, t in enumerate(arm_T_world):
            direction = t[:3, :3] @ direction_world
            p_arm = t[:3, :3] @ p + t[:3, 3]
            poses[k, :, :, :3, :3] = (t[:3, :3] @ rot_world)[:, None]
            for j, s in enumerate((0.0, approach.pregrasp_distance_m)):             # grasp, pre-grasp
                poses[k, :, j, :3, 3] = p_arm + (s + nozzle) * direction          # the flange behind the tip
        poses[..., 3, 3] = 1.0
        q, _ = inverse_kinematics_batch(poses.reshape(-1, 4, 4), np.zeros(NUM_JOINTS), model.kinematics)
        q = q.reshape(len(order), len(rolls), 2, 8, NUM_JOINTS)
        both = np.all(np.isfinite(q), axis=-1).all(axis=2)                         # (S, R, 8)
        for k in np.flatnonzero(both.any(axis=(1, 2))):                           # nearest stop first
            any_ik = True
            r_idx, b_idx = np.nonzero(both[k])
            plants_arm = woody.transformed(arm_T_world[k])
            for first in range(0, len(r_idx), _CHUNK):
                rr, bb = r_idx[first:first + _CHUNK], b_idx[first:first + _CHUNK]
                configs = q[k, rr, :, bb].reshape(-1, NUM_JOINTS)                  # (C * 2, 6)
                free = ~model.in_collision(configs, plants_arm).reshape(-1, 2).any(axis=1)
                if free.any():
                    c = int(np.flatnonzero(free)[0])
                    return BollReach(boll_id, "reachable", stops[order[k]], q[k, rr[c], 0, bb[c]].copy())
    return BollReach(boll_id, "collision" if any_ik else "no_ik")


def lane_facing(centre_m, plant_xy_m, lanes: Sequence, max_lane_offset_m: float = 1.5) -> bool:
    """Whether a boll is on a lane-facing half of its plant: a lane (farm.model.Lane) runs on the boll's
    side of the stem (across the rows, world x), no farther than max_lane_offset_m from the stem."""
    dx = float(centre_m[0]) - float(plant_xy_m[0])
    return any(dx * (lane.x_m - float(plant_xy_m[0])) > 0.0 and abs(lane.x_m - float(plant_xy_m[0])) <= max_lane_offset_m
               for lane in lanes)


def robot_geometry_from_urdf(urdf_xml: str, arm_base_frame: str = "ur5e_base") -> RobotGeometry:
    """The arm's mount, base_link's height and the collision model with the robot's body (and the
    ground) from the robot description."""
    from cottonsim_manipulation.planning.robot_body import body_boxes_from_urdf
    from cottonsim_world.robot.urdf_model import UrdfModel

    urdf = UrdfModel.from_string(urdf_xml)
    height = float(urdf.fixed_transform("base_footprint", "base_link")[2, 3])
    return RobotGeometry(urdf.fixed_transform("base_link", arm_base_frame), height,
                         ArmCollisionModel(body=body_boxes_from_urdf(urdf_xml, arm_base_frame=arm_base_frame)))


def farm_reachability(farm, lanes: Sequence, robot: RobotGeometry,
                      config: ReachabilityConfig = ReachabilityConfig(), headings=None) -> List[BollReach]:
    """Every boll of the farm (ids as the simulator's BollField numbers them) judged from stops on
    `lanes` (the route's lanes); headings: lane index -> robot yaw there [rad] (default: north)."""
    from cottonsim_world.farm.bolls import BollField
    from cottonsim_world.farm.plant_obstacles import PlantObstacles

    headings = headings or {}
    stops = [s for lane in lanes for s in lane_stops([lane], config.stop_spacing_m,
                                                      headings.get(lane.index, 0.5 * math.pi))]
    bolls = BollField(farm)
    obstacles = PlantObstacles.from_farm(farm)
    positions = bolls.positions_m()
    return [reach_boll(i, positions[i], bolls.outward[i], stops, obstacles, robot, config)
            for i in range(bolls.count)]
