"""The harvest of a moving robot, free of ROS: boll targets in a fixed frame, stops, pick cycles, figures.

The robot knows its bolls as targets in a fixed frame (odom or map; harvest.targets
fuses the 3-D detections). :class:`Harvester` decides when to stop and what to
pick, runs one harvest.pick_cycle.PickCycle per stop and keeps the figures:

* Workspace: a confirmed target is *in reach* when its distance from the
  shoulder (the arm's base frame origin raised by the UR5e's d1) is within
  [``min_reach_m``, ``reach_m``]; the approach planner decides the rest.
* Only targets seen lately count (``max_target_age_s`` before now, when the
  caller gives the time): odometry jumps (a skid-steer robot turning into a
  lane slips by centimetres) leave targets seen before them behind their
  bolls; the bolls' new detections start new targets, and the stale ones are
  never seen again, so they neither stop the robot nor are picked. A stop's
  target is checked again when its turn comes: one last seen more than
  ``max_target_age_s`` before the newest detection is 'lost' (a jump shortly
  before the stop left two targets for one boll, both fresh when the stop
  chose them; the pick of one took the boll, and the arm went for the other
  into empty air). Measured against the newest detection, not the clock: the
  caller's loop may stand still while a stop plans its picks. 'lost' is no
  failed attempt (the arm did not move; a boll hidden by the arm for a while
  is chosen again by a later stop).
* A target the planner failed for ('unreachable', 'ik_failed', 'collision')
  is picked again once the shoulder has moved ``retry_distance_m`` from where
  it failed: from the same place the plan fails the same way. Such a failure
  does not count as an attempt (the arm did not move: a boll tried too far
  ahead of the shoulder is often reachable from the next stop). Such a target
  stops a driving robot again once the shoulder moved ``retry_distance_m``,
  ``retry_stops`` times at most; after that only once the shoulder is
  ``reach_m`` from where it last failed (the next lane): a boll that no stop of
  this lane can reach would stop it every ``retry_distance_m``; until then it is
  tried again at the stops other targets make. Offline, 7 of 39 reachable bolls
  the planner failed for with the shoulder abeam were plannable 0.2-0.4 m on.
* A stop starts (:meth:`Harvester.want_stop`) when a target in reach lies no
  more than ``stop_ahead_m`` ahead of the shoulder along the robot's heading
  (base_link x: the robot has come abeam of it), or when the robot stands
  anyway; at most ``max_targets_per_stop`` targets, the nearest first, are
  picked in that order, except that a target comes after the targets on its
  approach line (harvest.pick_order; the approach line from the estimated
  outward direction).
* The boll's outward direction (horizontal, from its stem, along which the
  nozzle comes in) is not observed; it is estimated (``outward``):
  'plant': from the estimated stem to the boll. The stem stands on
  the row's line, ``row_offset_m`` to the boll's side of the robot's centre
  line (the robot drives on the lane's centre line); along the row it is the
  centre of the boll's plant: the mean along-track position of the targets on
  that side within ``plant_half_spacing_m`` of it, iterated from the boll's
  own (a mean shift; a plant's bolls spread about its stem along the row even
  when only its lane-facing half is seen). 'row_grid' (default): the same,
  but along the row the stems stand on a regular grid, one every
  2 * ``plant_half_spacing_m`` (the paper's farm, transplanted or precision-
  planted rows); the grid's phase is the circular mean of the along-row
  positions of the targets on that side within ``grid_window_m`` of the boll,
  modulo the spacing, and the boll's stem the grid point nearest to it. A
  plant's bolls do not centre on its stem (its branches point in random
  directions): on row 1 of seed 0 (ground-truth targets) the mean shift put
  the stem 2.9 cm (median) from the truth and the outward direction 7.1 deg off
  (p90 26 deg); the grid over 3 m: 0.6 cm, 2.1 deg (p90 8 deg). Rows with
  irregular spacing want 'plant'. 'lateral': along the robot's y axis towards
  its centre line. 'radial': from the boll towards the shoulder.
* Stems as obstacles (``stem_obstacles``): the robot does not perceive stems, but the 'plant'
  estimate places each target's stem (harvest.outward.estimate_stem); the stems of the targets within
  reach of the boll go to the planner as vertical capsules (planning.stems) from the ground
  (``ground_z_m`` in base_link) up, so an approach does not run into the plant.
* A stop halts the route first; its targets are chosen and ordered once the
  robot stands, from the arm-base pose of that moment (:meth:`Harvester.update_pose`):
  a robot brakes over some centimetres. The first target is planned at its
  turn; each next one while the arm moves (:meth:`Harvester.plan_next`, from
  the bin pose, where every pick ends and the next starts), and that plan is
  used while the robot has not moved; otherwise a target is planned again
  when its turn comes. Planning every target before the first pick made the
  stop's first cycle wait for all of them.
* Results: an 'ok' marks the target picked (harvest.targets never adds it
  again); a failure of the arm ('aborted', 'capture_missed', 'timeout')
  counts a failed attempt (abandoned after TargetFusionConfig.max_attempts);
  a planning failure, 'lost' and 'cancelled' do not (above). Pick goals for a point (no target) get
  negative ids and only count in the figures.

Frames: ``frame`` is the fixed frame of the targets; poses are 4x4 matrices:
arm_T_frame maps fixed-frame points into the arm's base frame (the UR 'base'),
arm_T_base base_link into it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

from cottonsim_common.capsules import CapsuleSet
from cottonsim_common.kinematics.ur5e import Ur5eKinematics
from cottonsim_common.transforms import transform_points
from cottonsim_common.validation import require_fields, require_int, require_number
from cottonsim_manipulation.harvest.outward import OUTWARD_MODELS, estimate_outward, estimate_stem
from cottonsim_manipulation.harvest.pick_cycle import REASONS, PickCycle, PickCycleConfig, PickResult, PickTarget
from cottonsim_manipulation.harvest.pick_order import PickOrderConfig, approach_blockers, clear_approaches_first
from cottonsim_manipulation.harvest.targets import BollDetection3D, BollTarget, TargetFusion
from cottonsim_manipulation.planning.approach import ApproachConfig, ApproachResult
from cottonsim_manipulation.planning.stems import stem_obstacles
from cottonsim_manipulation.planning.trajectory import TrajectoryConfig

PLANNING_FAILURES = ("unreachable", "ik_failed", "collision")   # results the planner decided
NOT_ATTEMPTS = PLANNING_FAILURES + ("lost", "cancelled")        # failures that are no failed attempt: the arm
                                                                # did not go for the boll, or was stopped
PLAN_REUSE_MAX_JOINT_RAD = 0.01       # a stop's plan is used while the arm starts this close to its start ...
PLAN_REUSE_MAX_SHIFT_M = 0.002        # ... and no point near the arm moved more than this (robot and arm pose)

# plan(boll position, outward direction, current joints, obstacles or None), all in the arm's base frame
# -> ApproachResult (planning.approach.plan_approach)
Planner = Callable[[np.ndarray, np.ndarray, np.ndarray, Optional[CapsuleSet]], object]


@dataclass(frozen=True)
class HarvestConfig:
    """reach_m: largest shoulder-to-target distance tried [m] (UR5e: 0.85 m to the flange, + the nozzle).
    min_reach_m: smallest shoulder-to-target distance tried [m].
    stop_ahead_m: stop once a target in reach is at most this far ahead of the shoulder [m] (along base_link x).
    max_targets_per_stop: targets picked in one stop at most.
    outward: the outward-direction estimate, 'plant', 'lateral' or 'radial' (module docstring).
    row_offset_m: 'plant': the rows' stems from the robot's centre line [m] (half the row spacing).
    plant_half_spacing_m: 'plant': half the plant spacing along the row, the mean shift's window [m];
        'row_grid': half the grid's spacing.
    grid_window_m: 'row_grid': the targets within this along-row distance of the boll fit the grid's phase [m].
    detection_sigma_m: 1-sigma position error given to each detection [m].
    stopped_speed_m_s: the robot stands when its odometry speed is at most this [m/s].
    stopped_yaw_rate_rad_s: ... and its yaw rate at most this [rad/s].
    max_target_age_s: a target counts for stops and picks while its last detection is at most this old [s].
    retry_distance_m: a target the planner failed for is planned again once the shoulder moved this far [m].
    retry_stops: ... and stops a driving robot again at most this many times (0: only from reach_m away).
    stem_obstacles: the estimated stems of the targets near the boll are obstacles of its plan.
    ground_z_m: the ground's height in base_link [m], where the stems stand (the Husky: base_link 0.13228 m up)."""

    reach_m: float = 1.0
    min_reach_m: float = 0.2
    stop_ahead_m: float = 0.05
    max_targets_per_stop: int = 12
    outward: str = "row_grid"
    row_offset_m: float = 0.9
    plant_half_spacing_m: float = 0.35
    grid_window_m: float = 3.0
    detection_sigma_m: float = 0.01
    stopped_speed_m_s: float = 0.02
    stopped_yaw_rate_rad_s: float = 0.02
    max_target_age_s: float = 2.0
    retry_distance_m: float = 0.2
    retry_stops: int = 2
    stem_obstacles: bool = True
    ground_z_m: float = -0.13228

    def __post_init__(self) -> None:
        require_fields(self, "HarvestConfig.", flags=("stem_obstacles",),
                       positive=("reach_m", "min_reach_m", "detection_sigma_m", "stopped_speed_m_s",
                                 "stopped_yaw_rate_rad_s", "row_offset_m", "plant_half_spacing_m", "grid_window_m",
                                 "retry_distance_m", "max_target_age_s"))
        require_number("HarvestConfig.stop_ahead_m", self.stop_ahead_m, -10.0, 10.0)
        require_number("HarvestConfig.ground_z_m", self.ground_z_m, -5.0, 5.0)
        require_int("HarvestConfig.max_targets_per_stop", self.max_targets_per_stop, 1, 1000)
        require_int("HarvestConfig.retry_stops", self.retry_stops, 0, 100)
        if self.min_reach_m >= self.reach_m:
            raise ValueError(f"HarvestConfig.min_reach_m {self.min_reach_m} must be below reach_m {self.reach_m}")
        if self.outward not in OUTWARD_MODELS:
            raise ValueError(f"HarvestConfig.outward must be one of {OUTWARD_MODELS}, got {self.outward!r}")


@dataclass
class HarvestFigures:
    """Counts of pick results per reason, the cycle times of the picked bolls [s], stops made."""

    results: Dict[str, int] = field(default_factory=lambda: {r: 0 for r in REASONS})
    cycle_times_s: List[float] = field(default_factory=list)
    stops: int = 0

    def record(self, result: PickResult) -> None:
        self.results[result.reason] = self.results.get(result.reason, 0) + 1
        if result.ok:
            self.cycle_times_s.append(float(result.cycle_time_s))

    def as_dict(self) -> dict:
        t = np.asarray(self.cycle_times_s, dtype=float)
        return {"results": dict(self.results), "picked": self.results.get("ok", 0),
                "attempted": int(sum(self.results.values())), "stops": self.stops,
                "cycle_time_median_s": float(np.median(t)) if t.size else None,
                "cycle_time_p95_s": float(np.percentile(t, 95)) if t.size else None,
                "cycle_times_s": [round(float(x), 3) for x in t]}


def _pose(matrix, what: str) -> np.ndarray:
    t = np.asarray(matrix, dtype=float)
    if t.shape != (4, 4) or not np.all(np.isfinite(t)):
        raise ValueError(f"{what} must be a finite 4x4 matrix")
    return t


class Harvester:
    """Targets, stops and pick cycles of one run; see the module docstring."""

    def __init__(self, plan: Planner, config: HarvestConfig = HarvestConfig(), fusion: Optional[TargetFusion] = None,
                 cycle_config: PickCycleConfig = PickCycleConfig(), order_config: PickOrderConfig = PickOrderConfig(),
                 kinematics: Optional[Ur5eKinematics] = None, approach_config: ApproachConfig = ApproachConfig(),
                 trajectory_config: TrajectoryConfig = TrajectoryConfig(), clock: Optional[Callable[[], float]] = None):
        self.config = config
        self.clock = clock                          # the time now [s], for the pick cycles (harvest.pick_cycle)
        self.approach_config = approach_config      # the stems' radius, height and merge distance
        self.fusion = fusion or TargetFusion()
        self.cycle_config = cycle_config
        self.trajectory_config = trajectory_config   # the limits of the cycle's own moves (to the bin)
        self.order_config = order_config
        self.figures = HarvestFigures()
        self.cycle: Optional[PickCycle] = None
        self.last_result: Dict[int, PickResult] = {}
        self.history: List[PickResult] = []     # every result, in order
        self._plan = plan
        self._shoulder_m = np.array([0.0, 0.0, (kinematics or Ur5eKinematics()).d1_m])
        self._arm_T_frame: Optional[np.ndarray] = None
        self._arm_T_base: Optional[np.ndarray] = None
        self._next_point_id = -1
        self._newest_detection_s = -math.inf      # the stamp of the newest detections [s]
        self._stop_targets_fresh = False          # a stop's targets must have been seen lately at their turn
        self._seen = 0
        self._stop_plans: Dict[int, tuple] = {}   # target id -> (joints, arm_T_frame, result) of this stop's order
        self._plan_failed_at: Dict[int, np.ndarray] = {}  # target id -> the shoulder (fixed frame) at its plan's failure
        self._plan_failures: Dict[int, int] = {}          # target id -> planning failures so far

    # ------------------------------------------------------------------ inputs
    @property
    def busy(self) -> bool:
        return self.cycle is not None and not self.cycle.done

    def update_pose(self, arm_T_frame, arm_T_base) -> None:
        """The arm base's pose now: fixed frame -> arm base, base_link -> arm base (4x4)."""
        self._arm_T_frame = _pose(arm_T_frame, "arm_T_frame")
        self._arm_T_base = _pose(arm_T_base, "arm_T_base")

    def add_detections(self, points_frame_m, stamp_s: float, sigma_m: Optional[float] = None) -> List[int]:
        """One frame's boll centres (N, 3) in the fixed frame; returns the target id of each (-1: ignored)."""
        points = np.asarray(points_frame_m, dtype=float).reshape(-1, 3)
        sigma = self.config.detection_sigma_m if sigma_m is None else sigma_m
        if len(points):
            self._newest_detection_s = max(self._newest_detection_s, float(stamp_s))
        return self.fusion.update([BollDetection3D(p, sigma) for p in points], stamp_s)

    # ------------------------------------------------------------------ decisions
    def _require_pose(self) -> None:
        if self._arm_T_frame is None:
            raise RuntimeError("the arm base's pose is not known yet (update_pose)")

    def in_reach(self, now_s: Optional[float] = None) -> List[BollTarget]:
        """Confirmed targets within the arm's workspace now, the nearest to the shoulder first; with now_s
        [s] only those seen within max_target_age_s before it."""
        self._require_pose()
        targets = self.fusion.open_targets()
        if now_s is not None:
            targets = [t for t in targets if now_s - t.last_seen_s <= self.config.max_target_age_s]
        if not targets:
            return []
        arm = transform_points(self._arm_T_frame, [t.position_m for t in targets])
        distance = np.linalg.norm(arm - self._shoulder_m, axis=1)
        ok = (distance >= self.config.min_reach_m) & (distance <= self.config.reach_m)
        return [targets[i] for i in np.argsort(distance, kind="stable") if ok[i]]

    def _shoulder_in_frame(self) -> np.ndarray:
        return transform_points(np.linalg.inv(self._arm_T_frame), [self._shoulder_m])[0]

    def pickable(self, now_s: Optional[float] = None) -> List[BollTarget]:
        """What a stop would pick now: in_reach(now_s) less the targets the planner failed for from about
        here (retry_distance_m)."""
        return self._away_from_failures(self.in_reach(now_s), self.config.retry_distance_m)

    def _away_from_failures(self, targets: List[BollTarget], distance_m: float) -> List[BollTarget]:
        """The targets the planner never failed for, or failed for with the shoulder at least distance_m from
        where it is now."""
        shoulder = self._shoulder_in_frame()
        return [t for t in targets if t.target_id not in self._plan_failed_at or
                np.linalg.norm(shoulder - self._plan_failed_at[t.target_id]) >= distance_m]

    def want_stop(self, robot_stopped: bool, now_s: Optional[float] = None) -> bool:
        """Whether to stop for a pick now (not while a cycle runs); now_s as in :meth:`in_reach`."""
        if self.busy:
            return False
        reach = self.pickable(now_s)
        if not reach:
            return False
        if robot_stopped:
            return True
        # a target the planner failed for: retry_stops more stops retry_distance_m apart (pickable), then the next lane
        far = {t.target_id for t in self._away_from_failures(reach, self.config.reach_m)}
        reach = [t for t in reach if t.target_id in far or
                 self._plan_failures.get(t.target_id, 0) <= self.config.retry_stops]
        if not reach:
            return False
        base = transform_points(np.linalg.inv(self._arm_T_base) @ self._arm_T_frame, [t.position_m for t in reach])
        shoulder_x = (np.linalg.inv(self._arm_T_base) @ np.append(self._shoulder_m, 1.0))[0]
        return bool(np.any(base[:, 0] - shoulder_x <= self.config.stop_ahead_m))

    def start_stop(self, q_current_rad, now_s: float) -> list:
        """Start a stop: the route halts (the first command); once the robot stands (RobotStopped) the targets
        in reach then are picked, at most max_targets_per_stop, in their pick order from the joints then."""
        if self.busy:
            raise RuntimeError("a pick cycle is running")
        self.figures.stops += 1
        self._stop_targets_fresh = True
        return self._start(self._select_stop_targets, q_current_rad, now_s)

    def _select_stop_targets(self, q_rad: np.ndarray, now_s: float) -> List[PickTarget]:
        """The stop's targets, the nearest first, each after the targets on its estimated approach line
        (harvest.pick_order); none is planned yet: the first is planned at its turn, the next ones while the
        arm moves (plan_next)."""
        chosen = self.pickable(now_s)[: self.config.max_targets_per_stop]
        order = [t.target_id for t in chosen]
        radius_m = self.order_config.clear_approach_radius_m
        if radius_m > 0.0 and len(chosen) > 1:
            cfg = self.approach_config
            boll, out, _, _ = self._bolls_and_outwards([t.position_m for t in chosen])
            order = clear_approaches_first(order, approach_blockers(
                order, boll, boll + (cfg.grasp_standoff_m + cfg.pregrasp_distance_m) * out,
                boll + cfg.grasp_standoff_m * out, radius_m))
        by_id = {t.target_id: t for t in chosen}
        return [PickTarget(i, tuple(by_id[i].position_m), (0.0, 0.0, 0.0)) for i in order]

    def start_pick(self, q_current_rad, now_s: float, target_id: Optional[int] = None, point_frame_m=None) -> list:
        """Start a cycle for one boll: a target by id, or a point (fixed frame). ValueError when the target is
        unknown or already picked, or the point is not 3 finite numbers; RuntimeError while a cycle runs."""
        if self.busy:
            raise RuntimeError("a pick cycle is running")
        if target_id is not None:
            try:
                target = self.fusion.target(int(target_id))
            except KeyError:
                raise ValueError(f"no boll target {target_id}") from None
            if target.state == "picked":
                raise ValueError(f"boll target {target_id} is picked already")
            pick = PickTarget(target.target_id, tuple(target.position_m), (0.0, 0.0, 0.0))
        else:
            p = np.asarray(point_frame_m, dtype=float).reshape(-1)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise ValueError(f"the point must be 3 finite numbers [m], got {point_frame_m!r}")
            pick = PickTarget(self._next_point_id, tuple(p), (0.0, 0.0, 0.0))
            self._next_point_id -= 1
        self._stop_targets_fresh = False
        return self._start([pick], q_current_rad, now_s)

    # ------------------------------------------------------------------ the running cycle
    def on_event(self, event, now_s: float) -> list:
        return self._collect(self.cycle.on_event(event, now_s)) if self.busy else []

    def tick(self, now_s: float) -> list:
        return self._collect(self.cycle.tick(now_s)) if self.busy else []

    def cancel(self, now_s: float, detail: str = "cancelled") -> list:
        return self._collect(self.cycle.cancel(now_s, detail)) if self.busy else []

    def update_joints(self, q_rad) -> None:
        if self.busy:
            self.cycle.update_joints(q_rad)

    # ------------------------------------------------------------------ internals
    def _plan_target(self, target: PickTarget, q_rad: np.ndarray):
        """plan_pick of the PickCycle: the target from its fixed-frame position and the arm's pose now (the
        plan made ahead by plan_next when nothing moved since)."""
        self._require_pose()
        stale = self._stale(target.target_id)
        if stale:
            self._stop_plans.pop(target.target_id, None)
            return ApproachResult("lost", stale)
        cached = self._stop_plans.pop(target.target_id, None)
        if cached is not None:
            q_planned, arm_T_frame, result = cached
            shift = np.abs(arm_T_frame - self._arm_T_frame)
            if np.abs(np.asarray(q_rad) - q_planned).max() <= PLAN_REUSE_MAX_JOINT_RAD and \
                    shift[:3, 3].max() + 2.0 * self.config.reach_m * shift[:3, :3].max() <= PLAN_REUSE_MAX_SHIFT_M:
                return result
        return self.plan_from_here(target.position_m, q_rad)

    def plan_next(self) -> bool:
        """Plan the running stop's next target now, from the bin pose (where its pick will start), unless it is
        planned already; call while the arm moves, so that its turn does not wait for the planner. Whether a
        plan was made."""
        if not self.busy or not self.cycle.upcoming_targets:
            return False
        target = self.cycle.upcoming_targets[0]
        if target.target_id in self._stop_plans or self._stale(target.target_id):
            return False
        q = np.asarray(self.cycle_config.bin_joints_rad, dtype=float)
        self._stop_plans[target.target_id] = (q, self._arm_T_frame.copy(), self.plan_from_here(target.position_m, q))
        return True

    def plan_from_here(self, point_frame_m, q_rad) -> ApproachResult:
        """Plan a pick of the boll at point_frame_m (the fixed frame) with the arm where it is now (update_pose)
        and at joints q_rad: its outward direction estimated (``outward``) and the stems of the targets near
        it as obstacles (``stem_obstacles``), from every target known."""
        boll_arm, outward_arm, boll, others = self._bolls_and_outwards([point_frame_m])
        return self._plan(boll_arm[0], outward_arm[0], q_rad, self._stems(boll[0], others))

    def _bolls_and_outwards(self, points_frame_m):
        """The bolls at points_frame_m (N, 3) and their estimated outward directions in the arm's base frame;
        the bolls and every target in base_link (the targets moved into base_link once for all N)."""
        self._require_pose()
        base_T_arm = np.linalg.inv(self._arm_T_base)
        base_T_frame = base_T_arm @ self._arm_T_frame
        bolls = transform_points(base_T_frame, points_frame_m)
        others = transform_points(base_T_frame, [t.position_m for t in self.fusion.targets()])
        shoulder = transform_points(base_T_arm, [self._shoulder_m])[0]
        outwards = np.array([estimate_outward(b, others, shoulder, self.config) for b in bolls])
        return transform_points(self._arm_T_base, bolls), outwards @ self._arm_T_base[:3, :3].T, bolls, others

    def _stale(self, target_id: int) -> str:
        """Why a stop's target is not picked at its turn ('' when it is): last seen more than max_target_age_s
        before the newest detection."""
        if not self._stop_targets_fresh or target_id < 0:
            return ""
        age_s = self._newest_detection_s - self.fusion.target(target_id).last_seen_s
        if age_s <= self.config.max_target_age_s:
            return ""
        return (f"not detected in the last {age_s:.1f} s of detections when its turn came (max_target_age_s "
                f"{self.config.max_target_age_s})")

    def _stems(self, boll_base_m: np.ndarray, targets_base_m: np.ndarray) -> Optional[CapsuleSet]:
        """The estimated stems of the targets within the arm's reach of the boll, in the arm's base frame."""
        if not self.config.stem_obstacles:
            return None
        near = targets_base_m[np.linalg.norm(targets_base_m[:, :2] - boll_base_m[:2], axis=1) <= self.config.reach_m]
        stems = [estimate_stem(t, targets_base_m, self.config) for t in near] or \
            [estimate_stem(boll_base_m, targets_base_m, self.config)]
        return stem_obstacles(np.array(stems), self.config.ground_z_m, self.approach_config).transformed(
            self._arm_T_base)

    def _start(self, targets, q_rad, now_s: float) -> list:
        self._stop_plans = {}
        self.cycle = PickCycle(targets, q_rad, self._plan_target, self.cycle_config, self.trajectory_config,
                               clock=self.clock)
        self._seen = 0
        return self._collect(self.cycle.start(now_s))

    def _collect(self, commands: list) -> list:
        """Take the cycle's new results into the targets and the figures."""
        for result in self.cycle.results[self._seen:]:
            self.figures.record(result)
            self.last_result[result.target_id] = result
            self.history.append(result)
            if result.target_id >= 0:
                if result.ok:
                    self.fusion.mark_picked(result.target_id, self._newest_detection_s)
                elif result.reason not in NOT_ATTEMPTS:
                    self.fusion.mark_failed(result.target_id)
                if result.reason in PLANNING_FAILURES and self._arm_T_frame is not None:
                    self._plan_failed_at[result.target_id] = self._shoulder_in_frame()
                    self._plan_failures[result.target_id] = self._plan_failures.get(result.target_id, 0) + 1
                else:
                    self._plan_failed_at.pop(result.target_id, None)
        self._seen = len(self.cycle.results)
        return commands
