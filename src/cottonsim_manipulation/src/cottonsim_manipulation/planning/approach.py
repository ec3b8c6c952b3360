"""Plan the arm to a boll: transit to a pre-grasp pose, a straight approach along the boll's outward
direction, and a retreat, collision-free and with the least joint travel.

Geometry (arm base frame, metres): the boll's centre p and its outward
direction n (from the plant's stem towards the boll, about horizontal). The
nozzle points into the boll: tool0's z axis is -n, and the nozzle tip (the
flange + nozzle_length_m along z) moves on the line p + s n:

    pre-grasp  s = standoff + pregrasp_distance_m
    grasp      s = standoff                (standoff 0: tip at the boll centre)
    retreat    s = standoff + retreat_distance_m

The nozzle is round, so its rotation about its axis (the roll) is free: the
planner tries ``roll_samples`` rolls, for each the (up to) 8 IK branches, and
follows each branch along the approach line at ``approach_steps`` points
(a branch that jumps by more than ``max_step_jump_rad`` between neighbouring
points, or leaves the joint limits, is dropped). The survivors are sorted by
joint travel (sum over joints of |dq| from the current joints through the
whole pick) and checked for collisions in that order; the first that is free
is the plan. When no candidate of a direction is free, the next approach direction
is tried (approach_directions: the outward direction turned about the vertical by
each of ``yaw_samples_rad`` and tilted up by each of ``tilt_samples_rad``, the
least deviation from the outward direction first, none beyond
``max_deviation_rad``). Otherwise the result says why: 'unreachable' (no arm
configuration puts the nozzle there), 'ik_failed' (configurations exist but
none stays within the joint limits and on one branch along the approach),
'collision' (every candidate hits a plant, the robot or itself).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from cottonsim_common.kinematics.ur5e import (
    BRANCHES,
    IkConfig,
    NUM_JOINTS,
    inverse_kinematics_batch,
    joint_vector,
    link_frames,
)
from cottonsim_common.validation import require_unit_vector
from cottonsim_common.vacuum_capture import CaptureConfig
from cottonsim_common.capsules import CapsuleSet
from cottonsim_manipulation.planning.collision import ArmCollisionModel
from cottonsim_manipulation.planning.trajectory import JointTrajectory, TrajectoryConfig, plan_trajectory

REASONS = ("ok", "unreachable", "ik_failed", "collision")
_ANGLE_TOLERANCE_RAD = 1e-9


@dataclass(frozen=True)
class ApproachConfig:
    """How a boll is approached.

    pregrasp_distance_m: nozzle tip distance from the grasp point before the approach [m].
    retreat_distance_m: how far the tip backs out along n after the grasp [m].
    via_distance_m: when larger than the pre-grasp and retreat distances, the arm comes to
        the pre-grasp from a point this far out along n (the tip outside the plant's
        canopy) and goes back out to it after the retreat, each a joint move of its own;
        the big swings to and from the bin then happen outside the plant (their branches
        are not seen) [m]; 0 = straight to the pre-grasp and from the retreat's end.
    grasp_standoff_m: the tip stops this far short of the boll centre along n [m].
    approach_steps: points on the approach (and retreat) line that IK follows (>= 2).
    roll_samples: rotations of the nozzle about its axis tried, evenly over a turn.
    max_step_jump_rad: largest joint change between neighbouring points of the
        approach line; more means the branch flips (near a singularity) [rad].
    max_line_deviation_m: the approach and retreat move in joint space straight
        between their ends when the tip then stays this close to the line;
        otherwise they pass (and stop) at every approach point [m].
    collision_step_rad: joint step of the collision checks along paths [rad].
    tilt_samples_rad: approach directions tried in turn: the outward direction
        turned upwards by each angle (the nozzle then comes from above, which
        reaches low bolls near the robot); the first that gives a plan wins [rad].
        Keep them inside the capture cone (cottonsim_common.vacuum_capture).
    yaw_samples_rad: the outward direction is also turned about the vertical (the arm
        base's z) by each of these, combined with every tilt; a boll that faces along the
        row (towards the next plant) is reached from the lane's side [rad], each in
        [-pi/2, pi/2]. (0.0,) tries the outward direction's own vertical plane only.
    max_deviation_rad: combinations of yaw and tilt that turn the approach further than
        this from the outward direction are not tried [rad]; default 35 deg, 10 deg inside
        the capture cone's half angle (CaptureConfig.cone_half_angle_rad, 45 deg), for the
        outward estimate's error (harvest.harvester 'row_grid': p90 8 deg on row 1 of seed 0).
        At 45 deg every missed capture of a ground-truth run on row 1 was 'misaligned'
        (47-64 deg off); the lane-facing bolls of row 1 stay 100 % reachable at 35 deg.
    stem_radius_m, stem_height_m, stem_merge_distance_m: the plants' estimated stems as
        obstacles (planning.stems.stem_obstacles, passed to plan_approach as `obstacles`):
        vertical capsules of this radius (a stem's ~1 cm plus the estimate's error) [m]
        from the ground up this high (the plants' height) [m]; estimates closer than the
        merge distance are one stem (every boll of a plant estimates its stem) [m].
    """

    pregrasp_distance_m: float = 0.10
    retreat_distance_m: float = 0.10
    via_distance_m: float = 0.0
    grasp_standoff_m: float = 0.0
    approach_steps: int = 5
    roll_samples: int = 12
    max_step_jump_rad: float = 0.5
    max_line_deviation_m: float = 0.005
    collision_step_rad: float = 0.02
    tilt_samples_rad: Tuple[float, ...] = (0.0, 0.3, 0.6)
    yaw_samples_rad: Tuple[float, ...] = (0.0, 0.3, -0.3, 0.6, -0.6)
    max_deviation_rad: float = CaptureConfig().cone_half_angle_rad - math.radians(10.0)
    stem_radius_m: float = 0.02
    stem_height_m: float = 1.0
    stem_merge_distance_m: float = 0.1

    def __post_init__(self) -> None:
        for name in ("pregrasp_distance_m", "retreat_distance_m", "via_distance_m", "grasp_standoff_m",
                     "max_step_jump_rad",
                     "max_line_deviation_m", "collision_step_rad", "max_deviation_rad", "stem_radius_m",
                     "stem_height_m", "stem_merge_distance_m"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"ApproachConfig.{name} must be a finite number, got {value!r}")
            if value < 0.0 or (value == 0.0 and name in ("max_step_jump_rad", "collision_step_rad")):
                raise ValueError(f"ApproachConfig.{name} must be > 0, got {value!r}")
        if self.pregrasp_distance_m > 0.5 or self.retreat_distance_m > 0.5 or self.via_distance_m > 0.5 \
                or self.grasp_standoff_m > 0.2:
            raise ValueError("ApproachConfig distances must stay within the arm's scale "
                             "(pre-grasp, retreat and via <= 0.5 m, standoff <= 0.2 m)")
        for name, high in (("stem_radius_m", 0.2), ("stem_height_m", 5.0), ("stem_merge_distance_m", 1.0)):
            if getattr(self, name) > high:
                raise ValueError(f"ApproachConfig.{name} must be at most {high} m, got {getattr(self, name)!r}")
        tilts = self.tilt_samples_rad
        if not isinstance(tilts, tuple) or not tilts or not all(
                isinstance(t, (int, float)) and not isinstance(t, bool) and 0.0 <= t <= 0.5 * math.pi for t in tilts):
            raise ValueError(f"ApproachConfig.tilt_samples_rad must be a non-empty tuple of angles in [0, pi/2], "
                             f"got {tilts!r}")
        yaws = self.yaw_samples_rad
        if not isinstance(yaws, tuple) or not yaws or not all(
                isinstance(y, (int, float)) and not isinstance(y, bool) and abs(y) <= 0.5 * math.pi for y in yaws):
            raise ValueError(f"ApproachConfig.yaw_samples_rad must be a non-empty tuple of angles in "
                             f"[-pi/2, pi/2], got {yaws!r}")
        if self.max_deviation_rad > math.pi:
            raise ValueError(f"ApproachConfig.max_deviation_rad must be in [0, pi], got {self.max_deviation_rad!r}")
        least = min(math.acos(math.cos(t) * math.cos(y)) for t in tilts for y in yaws)
        if least > self.max_deviation_rad + _ANGLE_TOLERANCE_RAD:
            raise ValueError(f"ApproachConfig: every combination of tilt_samples_rad and yaw_samples_rad turns "
                             f"a horizontal approach more than max_deviation_rad {self.max_deviation_rad!r} "
                             f"from the outward direction (the least by {least:.3f} rad)")
        for name, low in (("approach_steps", 2), ("roll_samples", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not (low <= value <= 360):
                raise ValueError(f"ApproachConfig.{name} must be an integer in [{low}, 360], got {value!r}")


@dataclass(frozen=True)
class ApproachPlan:
    """A pick's motion: transit (current -> pre-grasp), approach (-> grasp), retreat.

    approach_direction: the unit direction the nozzle moves in during the approach
    (its axis; the outward direction reversed, turned by the yaw and tilted up by the tilt
    that worked: yaw_rad, tilt_rad).
    """

    q_pregrasp_rad: np.ndarray
    q_grasp_rad: np.ndarray
    q_retreat_rad: np.ndarray
    transit: JointTrajectory
    approach: JointTrajectory
    retreat: JointTrajectory
    roll_rad: float
    branch: Tuple[int, int, int]
    joint_travel_rad: float
    approach_direction: np.ndarray
    yaw_rad: float = 0.0
    tilt_rad: float = 0.0

    @property
    def duration_s(self) -> float:
        return self.transit.duration_s + self.approach.duration_s + self.retreat.duration_s


@dataclass(frozen=True)
class ApproachResult:
    """reason: one of REASONS; detail says more (e.g. the contact); plan is set when ok."""

    reason: str
    detail: str = ""
    plan: Optional[ApproachPlan] = None
    candidates: int = 0

    @property
    def ok(self) -> bool:
        return self.reason == "ok"


def tool_rotations(axis_z: np.ndarray, rolls_rad: np.ndarray) -> np.ndarray:
    """Rotations (R, 3, 3) with z = axis_z, turned about it by each roll [rad]."""
    z = require_unit_vector("tool axis", axis_z, 3)
    ref = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x0 = np.cross(ref, z)
    x0 /= np.linalg.norm(x0)
    y0 = np.cross(z, x0)
    c, s = np.cos(rolls_rad)[:, None], np.sin(rolls_rad)[:, None]
    x = c * x0 + s * y0
    y = np.cross(z, x)
    return np.stack([x, y, np.broadcast_to(z, x.shape)], axis=-1)


def _unwrap_chain(chain: np.ndarray) -> np.ndarray:
    """Make each joint continuous along axis 0 (whole turns removed between neighbours)."""
    out = chain.copy()
    for s in range(1, len(out)):
        out[s] = out[s - 1] + np.mod(out[s] - out[s - 1] + math.pi, 2 * math.pi) - math.pi
    return out


def plan_approach(
    boll_m,
    outward,
    q_current_rad,
    model: ArmCollisionModel,
    obstacles: Optional[CapsuleSet] = None,
    config: ApproachConfig = ApproachConfig(),
    trajectory_config: TrajectoryConfig = TrajectoryConfig(),
    ik_config: Optional[IkConfig] = None,
) -> ApproachResult:
    """Plan a pick of the boll at boll_m (arm base frame) approached against `outward`.

    ValueError on malformed input (NaN, wrong shapes, a zero direction, joints
    outside their limits); every planning failure is a result with a reason.
    """
    p = np.asarray(boll_m, dtype=float).reshape(-1)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"boll position must be 3 finite numbers [m], got {boll_m!r}")
    n = require_unit_vector("outward direction", outward, 3)
    q0 = joint_vector(q_current_rad, "current joints")
    ik_cfg = ik_config or IkConfig(lower_limits_rad=trajectory_config.lower_limits_rad,
                                   upper_limits_rad=trajectory_config.upper_limits_rad)
    lower, upper = np.asarray(ik_cfg.lower_limits_rad), np.asarray(ik_cfg.upper_limits_rad)
    if np.any(q0 < lower - 1e-9) or np.any(q0 > upper + 1e-9):
        raise ValueError(f"current joints {q0.tolist()} are outside the joint limits")
    results = []
    for direction in approach_directions(n, config):
        result = _plan_direction(p, direction.vector, q0, model, obstacles, config, trajectory_config, ik_cfg)
        if result.ok:
            plan = dataclasses.replace(result.plan, yaw_rad=direction.yaw_rad, tilt_rad=direction.tilt_rad)
            return dataclasses.replace(result, plan=plan)
        results.append((direction, result))
    # None worked: the most telling reason (collision > ik_failed > unreachable), of the least deviation.
    for reason in ("collision", "ik_failed", "unreachable"):
        for direction, result in results:
            if result.reason == reason:
                return ApproachResult(reason, f"yaw {direction.yaw_rad:.2f} rad, tilt {direction.tilt_rad:.2f} rad: "
                                              f"{result.detail}", None, result.candidates)
    raise AssertionError("unreachable code: every result has a reason")


@dataclass(frozen=True)
class ApproachDirection:
    """A direction tried: the outward direction turned about z by yaw_rad, then tilted up by tilt_rad;
    vector (unit, from the boll out: the nozzle moves against it); deviation_rad: its angle from the
    outward direction."""

    yaw_rad: float
    tilt_rad: float
    vector: np.ndarray
    deviation_rad: float


def approach_directions(outward, config: ApproachConfig = ApproachConfig()) -> List[ApproachDirection]:
    """The approach directions plan_approach tries for `outward` (unit after scaling), in order: every
    yaw sample x tilt sample, the least deviation from the outward direction first (ties in the
    order of yaw_samples_rad, then tilt_samples_rad), none deviating more than max_deviation_rad
    (the least deviating one is always kept); repeats are dropped."""
    n = require_unit_vector("outward direction", outward, 3)
    found: List[ApproachDirection] = []
    for yaw in config.yaw_samples_rad:
        turned = turned_about_z(n, yaw)
        for tilt in config.tilt_samples_rad:
            vector = tilted_up(turned, tilt)
            deviation = math.acos(min(1.0, max(-1.0, float(vector @ n))))
            if not any(np.abs(d.vector - vector).max() < 1e-9 for d in found):
                found.append(ApproachDirection(float(yaw), float(tilt), vector, deviation))
    found.sort(key=lambda d: round(d.deviation_rad, 9))
    kept = [d for d in found if d.deviation_rad <= config.max_deviation_rad + _ANGLE_TOLERANCE_RAD]
    return kept or found[:1]


def turned_about_z(direction: np.ndarray, yaw_rad: float) -> np.ndarray:
    """The direction turned by yaw_rad about the z axis (counter-clockwise seen from above)."""
    d = np.asarray(direction, dtype=float).reshape(3)
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return np.array([c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]])


def tilted_up(direction: np.ndarray, tilt_rad: float) -> np.ndarray:
    """The direction turned by tilt_rad upwards (towards +z) in its vertical plane, unit length.

    A vertical direction has no vertical plane of its own and is returned as it is."""
    d = require_unit_vector("direction", direction, 3)
    horizontal = np.array([d[0], d[1], 0.0])
    h = np.linalg.norm(horizontal)
    if tilt_rad == 0.0 or h < 1e-9:
        return d
    elevation = math.atan2(d[2], h) + tilt_rad
    elevation = min(elevation, 0.5 * math.pi)
    return np.array([*(math.cos(elevation) * horizontal[:2] / h), math.sin(elevation)])


def _plan_direction(p, n, q0, model, obstacles, cfg, trajectory_config, ik_cfg) -> ApproachResult:
    """plan_approach for one approach direction n (unit)."""
    lower, upper = np.asarray(ik_cfg.lower_limits_rad), np.asarray(ik_cfg.upper_limits_rad)
    nozzle = model.config.nozzle_length_m
    steps = cfg.approach_steps
    rolls = np.arange(cfg.roll_samples) * (2.0 * math.pi / cfg.roll_samples)
    rot = tool_rotations(-n, rolls)                                             # (R, 3, 3)

    # Tip offsets along n: approach line (pre-grasp -> grasp), then the retreat line (grasp -> out); with a
    # via point, the via before and after them.
    approach_s = cfg.grasp_standoff_m + cfg.pregrasp_distance_m * np.linspace(1.0, 0.0, steps)
    retreat_s = cfg.grasp_standoff_m + cfg.retreat_distance_m * np.linspace(0.0, 1.0, steps)[1:]
    via = cfg.via_distance_m > max(cfg.pregrasp_distance_m, cfg.retreat_distance_m)
    via_s = [cfg.grasp_standoff_m + cfg.via_distance_m] if via else []
    line_s = np.concatenate([via_s, approach_s, retreat_s, via_s])                # (S,)
    first = 1 if via else 0                                                     # the pre-grasp's index
    grasp, retreat_end = first + steps - 1, first + 2 * steps - 2
    tips = p + line_s[:, None] * n                                              # (S, 3)
    flange = tips[None, :, :] + nozzle * n                                      # tool z = -n: flange behind the tip
    n_rolls, n_pts = len(rolls), len(line_s)
    poses = np.zeros((n_rolls, n_pts, 4, 4))
    poses[..., :3, :3] = rot[:, None]
    poses[..., :3, 3] = np.broadcast_to(flange, (n_rolls, n_pts, 3))
    poses[..., 3, 3] = 1.0
    q, _ = inverse_kinematics_batch(poses.reshape(-1, 4, 4), q0, model.kinematics, ik_cfg)
    q = q.reshape(n_rolls, n_pts, 8, NUM_JOINTS)

    # Which poses have any configuration at all (joint limits aside)?
    unlimited = IkConfig(lower_limits_rad=(-1e3,) * NUM_JOINTS, upper_limits_rad=(1e3,) * NUM_JOINTS)
    exists, _ = inverse_kinematics_batch(poses[:, [first, grasp]].reshape(-1, 4, 4), q0, model.kinematics, unlimited)
    if not np.all(np.isfinite(exists), axis=-1).reshape(n_rolls, 2, 8).any(axis=2).all(axis=1).any():
        return ApproachResult("unreachable", "no arm configuration puts the nozzle at the pre-grasp and grasp "
                                             f"poses for any of {n_rolls} rolls (boll at {np.round(p, 3).tolist()})")

    candidates = []
    for r in range(n_rolls):
        for b in range(8):
            chain = q[r, :, b]                                                  # (S, 6)
            if not np.all(np.isfinite(chain)):
                continue
            chain = _unwrap_chain(chain)                                        # [via] pre-grasp .. grasp .. retreat [via]
            if np.any(chain < lower - 1e-9) or np.any(chain > upper + 1e-9):
                continue
            if np.abs(np.diff(chain, axis=0)).max() > cfg.max_step_jump_rad:
                continue
            travel = np.abs(chain[0] - q0).sum() + np.abs(np.diff(chain, axis=0)).sum()
            candidates.append((travel, r, b, chain))
    if not candidates:
        return ApproachResult("ik_failed", "the nozzle's poses have arm configurations, but none stays inside "
                                           "the joint limits and on one IK branch along the approach and retreat")
    candidates.sort(key=lambda c: c[0])
    total = len(candidates)

    # The stops themselves ([via,] pre-grasp, grasp, retreat end) of every candidate in one go.
    stop_index = ([0] if via else []) + [first, grasp, retreat_end]
    stop_names = (("via",) if via else ()) + ("pre-grasp", "grasp", "retreat")
    stops = np.array([c[3][stop_index] for c in candidates]).reshape(-1, NUM_JOINTS)
    stop_hit = model.in_collision(stops, obstacles).reshape(total, len(stop_index)).any(axis=1)
    first_contact: Optional[str] = None
    if stop_hit[0]:
        hit = model.contacts(candidates[0][3][stop_index], obstacles, first_only=True)[0]
        first_contact = f"at its {stop_names[hit.sample]} pose {hit.link} hits {hit.kind} " \
                        f"{hit.other} ({hit.clearance_m * 1000:.1f} mm)"
    candidates = [c for c, hit in zip(candidates, stop_hit) if not hit]
    for checked, (travel, r, b, chain) in enumerate(candidates, 1):
        transit_wp = np.stack([q0] + [chain[i] for i in range(first + 1)])
        approach_wp = _line_waypoints(chain[first:grasp + 1], tips[first:grasp + 1], nozzle, cfg.max_line_deviation_m,
                                      model)
        retreat_wp = _line_waypoints(chain[grasp:retreat_end + 1], tips[grasp:retreat_end + 1], nozzle,
                                     cfg.max_line_deviation_m, model)
        if via:
            retreat_wp = np.vstack([retreat_wp, chain[-1:]])
        contact = None
        for path in (transit_wp, approach_wp, retreat_wp):
            contact = model.first_collision(path, obstacles, cfg.collision_step_rad)
            if contact is not None:
                break
        if contact is not None:
            first_contact = first_contact or f"on its path {contact}"
            continue
        plan = ApproachPlan(
            q_pregrasp_rad=chain[first].copy(),
            q_grasp_rad=chain[grasp].copy(),
            q_retreat_rad=retreat_wp[-1].copy(),
            transit=plan_trajectory(transit_wp, trajectory_config),
            approach=plan_trajectory(approach_wp, trajectory_config),
            retreat=plan_trajectory(retreat_wp, trajectory_config),
            roll_rad=float(rolls[r]),
            branch=BRANCHES[b],
            joint_travel_rad=float(travel),
            approach_direction=-n,
        )
        return ApproachResult("ok", f"candidate {checked + int(stop_hit.sum())} of {total} is free", plan, total)
    return ApproachResult("collision", f"all {total} candidates collide; the least-travel one {first_contact}",
                          None, total)


def _line_waypoints(chain: np.ndarray, tips: np.ndarray, nozzle_m: float, tolerance_m: float,
                    model: ArmCollisionModel) -> np.ndarray:
    """The chain's two ends when the straight joint-space move keeps the tip within tolerance
    of the Cartesian line at the chain's intermediate points; else the whole chain."""
    if len(chain) <= 2:
        return chain
    frac = np.linspace(0.0, 1.0, len(chain))[1:-1, None]
    mid = chain[0] + frac * (chain[-1] - chain[0])
    frames = link_frames(mid, model.kinematics)[:, 6]
    tip = frames[:, :3, 3] + nozzle_m * frames[:, :3, 2]
    if np.linalg.norm(tip - tips[1:-1], axis=1).max() <= tolerance_m:
        return chain[[0, -1]]
    return chain

