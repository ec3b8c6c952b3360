"""move_base as a pure state machine: goal -> plan -> control -> recovery -> result.

Why a pure core: the ROS node (``ros/move_base_node.py``) only converts
messages, looks up TF and calls :meth:`MoveBase.step` at
controller_frequency; everything that decides what the robot does lives here
and is unit-tested with fake planners and a fake clock.

The logic follows ROS's move_base (executeCycle):

* ``set_goal`` starts (or preempts with) a new goal: state PLANNING.
* PLANNING: the global planner plans from the robot to the goal on the
  global costmap. Success -> CONTROLLING with the new plan. Failure: retry
  next cycle until ``planner_patience`` seconds have passed since the last
  valid plan (or ``max_planning_retries`` failures), then CLEARING. If
  ``planner_frequency`` > 0 the plan is also remade at that rate while
  controlling.
* CONTROLLING: the local planner turns the plan (transformed into the
  local costmap's frame) into (v, w). GOAL_REACHED -> SUCCEEDED. A failed
  cycle stops the robot and asks for a new plan; after
  ``controller_patience`` seconds without a valid command -> CLEARING.
  If ``oscillation_timeout`` > 0 and the robot has not moved
  ``oscillation_distance`` within that time -> CLEARING. When the global
  costmap has an obstacle layer, a plan whose poses ahead of the robot now
  lie on an obstacle (seen after planning) is remade (PLANNING).
* CLEARING: runs the next recovery behaviour (``recovery.py``) to its end,
  then PLANNING again. When none is left, the goal is ABORTED with a
  reason naming the trigger and the number of behaviours tried. The
  recovery index goes back to 0 when the trigger's problem went away (a
  valid plan, a valid command, or enough motion).

Additions to ROS's behaviour (``abort_on_blocked_goal``; ``goal_checks.py``):
a goal whose cell and every cell within the planner's tolerance are obstacles
or within the global costmap's lethal radius of one (the robot cannot stand
there) is aborted with that reason instead of spending the recovery sequence
on it: at once when the global costmap cannot change (no obstacle layer),
else once it has stayed blocked for ``planner_patience`` seconds, during
which the robot stands still (an obstacle layer may still clear the goal,
and then move_base plans and drives on).
The clearing recoveries are not run for it: they would erase the very
obstacle (a plant) the robot must not drive into.

Vision correction (optional, :class:`VisionBiasConfig`): while CONTROLLING
with a valid local plan, a fresh row-centring estimate (angular rate) is
added to the local planner's angular velocity, bounded to
``max_vision_rate`` rad/s, but only when the robot is inside a crop row
(the global costmap - a map's rows - or the local costmap - the LiDAR's plants,
all a GPS route's empty map leaves - has obstacles on both sides within
``row_reach_m``).
So only move_base commands the base; the two never fight over /cmd_vel.

Frames: the global costmap and plans are in the global frame (map); the
local costmap and the local planner work in the local frame (odom). The
caller passes the robot pose in both frames each cycle; the map -> odom
transform follows from the two.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import numpy as np

from cottonsim_common.angles import shortest_angular_distance, wrap_angle
from cottonsim_common.pose import Pose2D, as_pose, compose, inverse, transform_points
from cottonsim_common.validation import require_instance
from cottonsim_navigation.move_base.config import MoveBaseConfig, VisionBiasConfig
from cottonsim_navigation.move_base.goal_checks import blocked_goal_reason, plan_blocked_at
from cottonsim_navigation.move_base.recovery import RecoveryBehaviour, RotateRecoveryConfig, make_recovery
from cottonsim_navigation.move_base.vision_bias import blend_vision, inside_crop_row
from cottonsim_navigation.planning.base import (GlobalPlanner, LocalPlanner, LocalPlannerStatus, Plan,
                                                make_global_planner, make_local_planner)
from cottonsim_navigation.planning.costmap import Costmap2D, ObstacleLayer


# A plan found blocked ahead is remade at most this often [s] (a new plan may still start in the
# robot's own inflated surroundings; navfn on GPS mode's 100 x 100 m map takes a good part of a second).
BLOCKED_PLAN_REPLAN_PERIOD_S = 1.0


class MoveBaseState(enum.Enum):
    IDLE = "idle"
    PLANNING = "planning"
    CONTROLLING = "controlling"
    CLEARING = "clearing"


class Outcome(enum.Enum):
    """What the current goal came to (the action server maps these to its states)."""

    IDLE = "idle"              # no goal
    ACTIVE = "active"
    SUCCEEDED = "succeeded"
    ABORTED = "aborted"


class RecoveryTrigger(enum.Enum):
    PLANNING = "planning"
    CONTROLLING = "controlling"
    OSCILLATION = "oscillation"


@dataclass
class StepResult:
    """One control cycle's output.

    v_mps, w_radps: the command to send; outcome / reason: the goal's state
    (reason set when ABORTED); new_plan: the global plan (global frame) when
    it changed this cycle, else None; local_path: (K, 3) predicted
    trajectory of the command in the local frame (empty when stopped);
    local_status: the local planner's status this cycle (None if not run);
    vision_applied: the vision correction changed w this cycle.
    """

    v_mps: float
    w_radps: float
    state: MoveBaseState
    outcome: Outcome
    reason: str = ""
    new_plan: Optional[Plan] = None
    local_path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    local_status: Optional[LocalPlannerStatus] = None
    vision_applied: bool = False


def _finite_pose(name: str, pose) -> Pose2D:
    try:
        p = as_pose(pose)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: {exc}") from None
    if not all(math.isfinite(v) for v in (p.x_m, p.y_m, p.yaw_rad)):
        raise ValueError(f"{name} has a non-finite coordinate: {p}")
    return p


class MoveBase:
    """The move_base state machine (see the module docstring).

    global_costmap / local_costmap: Costmap2D in the global (map) and local
    (odom) frames; the caller keeps them updated (static map, observations,
    ``update_map``). Planners default to the config's plugin names;
    recoveries default to the config's list.
    """

    def __init__(self, config: MoveBaseConfig, global_costmap: Costmap2D, local_costmap: Costmap2D,
                 global_planner: Optional[GlobalPlanner] = None, local_planner: Optional[LocalPlanner] = None,
                 recoveries: Optional[Sequence[RecoveryBehaviour]] = None,
                 vision: VisionBiasConfig = VisionBiasConfig(),
                 rotate: RotateRecoveryConfig = RotateRecoveryConfig()):
        require_instance("config", config, MoveBaseConfig)
        self.config = config
        self.vision = vision
        self.global_costmap = global_costmap
        self.local_costmap = local_costmap
        self.global_planner = global_planner or make_global_planner(config.base_global_planner)
        self.local_planner = local_planner or make_local_planner(config.base_local_planner)
        if recoveries is None:
            recoveries = []
            if config.recovery_behavior_enabled:
                for name in config.recovery_behaviours:
                    if name == "rotate_recovery" and not config.clearing_rotation_allowed:
                        continue
                    recoveries.append(make_recovery(name, local_costmap.circumscribed_radius_m, rotate,
                                                    config.conservative_reset_dist))
        self.recoveries: List[RecoveryBehaviour] = list(recoveries)
        self.state = MoveBaseState.IDLE
        self.goal: Optional[Pose2D] = None
        self.plan: Optional[Plan] = None
        self._reset_goal_state(0.0)

    # ------------------------------------------------------------------ goals
    def _reset_goal_state(self, now_s: float) -> None:
        self.recovery_index = 0
        self.recovery_trigger = RecoveryTrigger.PLANNING
        self._running: Optional[RecoveryBehaviour] = None
        self.last_valid_plan_s = now_s
        self.last_valid_control_s = now_s
        self.last_oscillation_reset_s = now_s
        self.oscillation_pose: Optional[Pose2D] = None
        self.planning_retries = 0
        self._last_plan_s = -math.inf
        self._last_reason = ""
        self._plan_tf: Optional[Pose2D] = None
        self.goal_blocked_since_s: Optional[float] = None

    def set_goal(self, goal, now_s: float) -> None:
        """Start a new goal (global frame); replaces (preempts) any active one."""
        goal = _finite_pose("goal", goal)
        self.goal = goal
        self.plan = None
        self.state = MoveBaseState.PLANNING
        self._reset_goal_state(now_s)

    def cancel(self) -> None:
        """Drop the goal; the next step returns IDLE and a zero command."""
        self.goal = None
        self.plan = None
        self.state = MoveBaseState.IDLE
        self._running = None

    @property
    def active(self) -> bool:
        return self.goal is not None

    # ------------------------------------------------------------------ services
    def make_plan(self, start, goal, tolerance_m: Optional[float] = None) -> Plan:
        """A plan on the global costmap (nav_msgs/GetPlan), without touching the goal in progress."""
        start = _finite_pose("start", start)
        goal = _finite_pose("goal", goal)
        plan = self.global_planner.make_plan(self.global_costmap, start, goal, tolerance_m)
        if not plan.ok:
            blocked = self._blocked_goal_reason(goal)
            if blocked:
                plan.reason = blocked
        return plan

    def clear_costmaps(self, global_pose, local_pose) -> None:
        """Forget every obstacle-layer cell of both costmaps (the ~clear_costmaps service)."""
        for cm in (self.global_costmap, self.local_costmap):
            for layer in cm.layers:
                if isinstance(layer, ObstacleLayer):
                    layer.clear_all()
            cm.request_full_update()

    # ------------------------------------------------------------------ helpers
    def _tolerance_m(self) -> float:
        cfg = getattr(self.global_planner, "config", None)
        return float(getattr(cfg, "default_tolerance", 0.0))

    def _blocked_goal_reason(self, goal: Pose2D) -> str:
        return blocked_goal_reason(self.global_costmap, goal, self._tolerance_m())

    def _check_blocked_goal(self, now_s: float) -> Optional[StepResult]:
        """Abort once the goal has been blocked for planner_patience on a clearable global costmap."""
        if not (self.config.abort_on_blocked_goal and self._global_costmap_clearable()):
            return None
        reason = self._blocked_goal_reason(self.goal)
        if not reason:
            self.goal_blocked_since_s = None
            return None
        if self.goal_blocked_since_s is None:
            self.goal_blocked_since_s = now_s
        if now_s - self.goal_blocked_since_s >= self.config.planner_patience:
            return self._abort(f"{reason}, for {self.config.planner_patience:g} s (planner_patience)")
        return None

    def _plan_blocked(self, gpose: Pose2D) -> bool:
        """The plan ahead of the robot crosses an obstacle the global costmap's obstacle layer saw since."""
        if self.plan is None or not self._global_costmap_clearable():
            return False
        i = plan_blocked_at(self.global_costmap, self.plan.poses, gpose, self.global_costmap.circumscribed_radius_m)
        if i < 0:
            return False
        self._last_reason = f"plan blocked at ({self.plan.poses[i, 0]:.2f}, {self.plan.poses[i, 1]:.2f})"
        return True

    def _global_costmap_clearable(self) -> bool:
        return any(isinstance(layer, ObstacleLayer) and layer.enabled for layer in self.global_costmap.layers)

    def _abort(self, reason: str) -> StepResult:
        self.goal = None
        self.state = MoveBaseState.IDLE
        self._running = None
        return StepResult(0.0, 0.0, MoveBaseState.IDLE, Outcome.ABORTED, reason)

    def _local_plan_sync(self, global_pose: Pose2D, local_pose: Pose2D) -> None:
        """Give the local planner the plan in the local frame when the plan or map -> odom changed.

        A new plan goes through ``set_plan``; a moved map -> odom (every GPS or
        AMCL correction) only through ``update_plan_frame``, so the local
        planner keeps its progress and goal latch as move_base's does (ROS
        hands DWA the plan once and transforms it each cycle).
        """
        t = compose(global_pose, inverse(local_pose))          # map -> odom
        if (self._plan_tf is not None and math.hypot(t.x_m - self._plan_tf.x_m, t.y_m - self._plan_tf.y_m) < 0.01
                and abs(shortest_angular_distance(t.yaw_rad, self._plan_tf.yaw_rad)) < 0.01):
            return
        to_local = inverse(t)
        poses = self.plan.poses
        xy = transform_points(to_local, poses[:, :2])
        yaw = wrap_angle(poses[:, 2] + to_local.yaw_rad)
        if self._plan_tf is None:                       # a new plan
            self.local_planner.set_plan(np.column_stack([xy, yaw]))
        else:                                           # the same plan, map -> odom moved
            self.local_planner.update_plan_frame(np.column_stack([xy, yaw]))
        self._plan_tf = t

    def _do_plan(self, now_s: float, global_pose: Pose2D) -> Optional[StepResult]:
        """Plan once; on failure decide between retry, recovery and abort. Returns an abort result or None."""
        self._last_plan_s = now_s
        plan = self.global_planner.make_plan(self.global_costmap, global_pose, self.goal)
        if plan.ok:
            self.plan = plan
            self._plan_tf = None
            self._new_plan = plan
            self.last_valid_plan_s = now_s
            self.planning_retries = 0
            if self.state == MoveBaseState.PLANNING:
                self.state = MoveBaseState.CONTROLLING
            if self.recovery_trigger == RecoveryTrigger.PLANNING:
                self.recovery_index = 0
            return None
        self._last_reason = plan.reason or "the global planner found no path"
        blocked = self._blocked_goal_reason(self.goal)
        if blocked:
            self._last_reason = blocked
            if self.config.abort_on_blocked_goal:
                if not self._global_costmap_clearable():
                    return self._abort(blocked)
                self.state = MoveBaseState.PLANNING        # _check_blocked_goal aborts after planner_patience
                return None
        self.planning_retries += 1
        retries_out = 0 <= self.config.max_planning_retries < self.planning_retries
        if now_s > self.last_valid_plan_s + self.config.planner_patience or retries_out:
            self.state = MoveBaseState.CLEARING
            self.recovery_trigger = RecoveryTrigger.PLANNING
        else:
            self.state = MoveBaseState.PLANNING
        return None

    def _abort_reason(self) -> str:
        n = self.recovery_index
        if self.recovery_trigger == RecoveryTrigger.PLANNING:
            return f"no valid plan after {n} recovery behaviours: {self._last_reason}"
        if self.recovery_trigger == RecoveryTrigger.CONTROLLING:
            return f"no valid trajectory after {n} recovery behaviours ({self._last_reason})"
        return (f"robot oscillating (moved less than {self.config.oscillation_distance:g} m in "
                f"{self.config.oscillation_timeout:g} s) after {n} recovery behaviours")

    def _trajectory(self, pose: Pose2D, v: float, w: float) -> np.ndarray:
        if v == 0.0 and w == 0.0:
            return np.zeros((0, 3))
        sim_time = float(getattr(getattr(self.local_planner, "config", None), "sim_time", 1.7))
        t = np.linspace(0.0, sim_time, 18)
        th = pose.yaw_rad + w * t
        if abs(w) < 1e-9:
            x = pose.x_m + v * t * math.cos(pose.yaw_rad)
            y = pose.y_m + v * t * math.sin(pose.yaw_rad)
        else:
            x = pose.x_m + v / w * (np.sin(th) - math.sin(pose.yaw_rad))
            y = pose.y_m - v / w * (np.cos(th) - math.cos(pose.yaw_rad))
        return np.column_stack([x, y, wrap_angle(th)])

    # ------------------------------------------------------------------ the cycle
    def step(self, now_s: float, global_pose, local_pose, velocity: Tuple[float, float] = (0.0, 0.0),
             vision_w_radps: Optional[float] = None, vision_age_s: Optional[float] = None) -> StepResult:
        """One control cycle at time ``now_s`` [s].

        global_pose / local_pose: the robot in the global (map) and local
        (odom) frames; velocity: current (v m/s, w rad/s) from odometry;
        vision_w_radps / vision_age_s: the latest row-centring angular rate
        and its age (None when there is none).
        """
        if not self.active:
            return StepResult(0.0, 0.0, MoveBaseState.IDLE, Outcome.IDLE)
        if not math.isfinite(now_s):
            raise ValueError(f"now_s must be finite, got {now_s!r}")
        gpose = _finite_pose("global_pose", global_pose)
        lpose = _finite_pose("local_pose", local_pose)
        try:
            vel = (float(velocity[0]), float(velocity[1]))
        except (TypeError, IndexError, ValueError):
            raise ValueError(f"velocity must be (v m/s, w rad/s), got {velocity!r}") from None
        if not all(math.isfinite(v) for v in vel):
            vel = (0.0, 0.0)
        self._new_plan: Optional[Plan] = None
        cfg = self.config

        # oscillation bookkeeping: enough motion resets the timer
        if (self.oscillation_pose is None
                or math.hypot(gpose.x_m - self.oscillation_pose.x_m,
                              gpose.y_m - self.oscillation_pose.y_m) >= cfg.oscillation_distance):
            self.oscillation_pose = gpose
            self.last_oscillation_reset_s = now_s
            if self.recovery_trigger == RecoveryTrigger.OSCILLATION:
                self.recovery_index = 0

        aborted = self._check_blocked_goal(now_s)
        if aborted is not None:
            return aborted
        if self.goal_blocked_since_s is not None:
            # do not drive towards a goal the robot cannot stand at (nor plan: navfn cannot reach it)
            self.state = MoveBaseState.PLANNING
            return StepResult(0.0, 0.0, self.state, Outcome.ACTIVE)

        # planning: when asked to, periodically while controlling, or when the plan ahead became blocked
        replan_due = (cfg.planner_frequency > 0 and self.state == MoveBaseState.CONTROLLING
                      and now_s - self._last_plan_s >= 1.0 / cfg.planner_frequency)
        if (self.state == MoveBaseState.CONTROLLING and not replan_due
                and now_s - self._last_plan_s >= BLOCKED_PLAN_REPLAN_PERIOD_S and self._plan_blocked(gpose)):
            self.state = MoveBaseState.PLANNING
        if self.state == MoveBaseState.PLANNING or replan_due:
            aborted = self._do_plan(now_s, gpose)
            if aborted is not None:
                return aborted

        v = w = 0.0
        status = None
        vision_applied = False
        if self.state == MoveBaseState.CONTROLLING:
            if cfg.oscillation_timeout > 0 and now_s - self.last_oscillation_reset_s > cfg.oscillation_timeout:
                self.state = MoveBaseState.CLEARING
                self.recovery_trigger = RecoveryTrigger.OSCILLATION
            else:
                self._local_plan_sync(gpose, lpose)
                v, w, status = self.local_planner.compute_velocity(lpose, vel, self.local_costmap)
                if status == LocalPlannerStatus.GOAL_REACHED:
                    plan = self._new_plan
                    self.goal = None
                    self.state = MoveBaseState.IDLE
                    return StepResult(0.0, 0.0, MoveBaseState.IDLE, Outcome.SUCCEEDED, "", plan,
                                      local_status=status)
                if status in (LocalPlannerStatus.OK, LocalPlannerStatus.ROTATING_TO_GOAL):
                    self.last_valid_control_s = now_s
                    if self.recovery_trigger == RecoveryTrigger.CONTROLLING:
                        self.recovery_index = 0
                    if status == LocalPlannerStatus.OK and self.vision.enabled:
                        in_row = (inside_crop_row(self.global_costmap, gpose, self.vision.row_reach_m)
                                  or inside_crop_row(self.local_costmap, lpose, self.vision.row_reach_m))
                        w2 = blend_vision(w, vision_w_radps, vision_age_s, in_row, self.vision)
                        vision_applied = w2 != w
                        w = w2
                else:
                    v = w = 0.0
                    self._last_reason = f"local planner: {status.value}"
                    if now_s > self.last_valid_control_s + cfg.controller_patience:
                        self.state = MoveBaseState.CLEARING
                        self.recovery_trigger = RecoveryTrigger.CONTROLLING
                    else:
                        self.state = MoveBaseState.PLANNING      # ask for a new plan next cycle

        if self.state == MoveBaseState.CLEARING:
            v = w = 0.0
            if self._running is None:
                if not (cfg.recovery_behavior_enabled and self.recovery_index < len(self.recoveries)):
                    return self._abort(self._abort_reason())
                self._running = self.recoveries[self.recovery_index]
                self._running.start(lpose, [(self.global_costmap, gpose), (self.local_costmap, lpose)])
            v, w, done = self._running.step(lpose, vel, self.local_costmap, 1.0 / cfg.controller_frequency)
            if done:
                v = w = 0.0
                self._running = None
                self.recovery_index += 1
                self.last_oscillation_reset_s = now_s
                self.oscillation_pose = gpose
                self.state = MoveBaseState.PLANNING

        return StepResult(v, w, self.state, Outcome.ACTIVE, "", self._new_plan,
                          self._trajectory(lpose, v, w), status, vision_applied)
