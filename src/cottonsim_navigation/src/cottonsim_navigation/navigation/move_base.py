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
  ``oscillation_distance`` within that time -> CLEARING.
* CLEARING: runs the next recovery behaviour (``recovery.py``) to its end,
  then PLANNING again. When none is left, the goal is ABORTED with a
  reason naming the trigger and the number of behaviours tried. The
  recovery index goes back to 0 when the trigger's problem went away (a
  valid plan, a valid command, or enough motion).

One addition to ROS's behaviour (``abort_on_blocked_goal``): when the
global costmap cannot change through recoveries (it has no obstacle layer)
and the goal and every cell within the planner's tolerance are obstacles,
the goal is aborted at once with that reason instead of spending the whole
recovery sequence on a goal that can never become free.

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

from cottonsim_navigation.core import geometry as geo
from cottonsim_navigation.core.grid import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE
from cottonsim_navigation.navigation.recovery import (RECOVERY_NAMES, RecoveryBehaviour, RotateRecoveryConfig,
                                                      make_recovery)
from cottonsim_navigation.planning.base import (GlobalPlanner, LocalPlanner, LocalPlannerStatus, Plan,
                                                make_global_planner, make_local_planner)
from cottonsim_navigation.planning.costmap import Costmap2D, ObstacleLayer

DEFAULT_RECOVERIES = ("conservative_reset", "rotate_recovery", "aggressive_reset", "rotate_recovery")


def _check_number(name: str, value, minimum: float = 0.0, strict: bool = False) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    if value < minimum or (strict and value == minimum):
        raise ValueError(f"{name} must be {'>' if strict else '>='} {minimum}, got {value!r}")


@dataclass(frozen=True)
class MoveBaseConfig:
    """move_base parameters (ROS names; times in s, frequencies in Hz, distances in m).

    base_global_planner / base_local_planner: plugin names (the original's
    'navfn/NavfnROS' and 'dwa_local_planner/DWAPlannerROS').
    controller_frequency [Hz]: control loop rate (original 5.0).
    planner_frequency [Hz]: re-plan rate while controlling; 0 = plan only on
    a new goal or when the controller fails (move_base default 0.0).
    planner_patience [s]: how long planning may fail before recoveries
    (move_base default 5.0). controller_patience [s]: how long the local
    planner may fail before recoveries (move_base default 15.0).
    max_planning_retries: failed plans allowed before recoveries; -1 =
    unlimited (only planner_patience counts; move_base default -1).
    oscillation_timeout [s]: the robot must move oscillation_distance [m]
    within this time, else recoveries; 0 disables (move_base defaults 0.0
    and 0.5).
    recovery_behavior_enabled: run recoveries at all (default true);
    clearing_rotation_allowed: include 'rotate_recovery' entries (default true).
    recovery_behaviours: names in order (move_base's default list:
    conservative_reset, rotate_recovery, aggressive_reset, rotate_recovery).
    conservative_reset_dist [m]: square side kept by conservative_reset (3.0).
    abort_on_blocked_goal: abort at once when the goal lies in an obstacle
    of a global costmap that recoveries cannot clear (port's addition, true).
    """

    base_global_planner: str = "navfn/NavfnROS"
    base_local_planner: str = "dwa_local_planner/DWAPlannerROS"
    controller_frequency: float = 5.0
    planner_frequency: float = 0.0
    planner_patience: float = 5.0
    controller_patience: float = 15.0
    max_planning_retries: int = -1
    oscillation_timeout: float = 0.0
    oscillation_distance: float = 0.5
    recovery_behavior_enabled: bool = True
    clearing_rotation_allowed: bool = True
    recovery_behaviours: Tuple[str, ...] = DEFAULT_RECOVERIES
    conservative_reset_dist: float = 3.0
    abort_on_blocked_goal: bool = True

    def __post_init__(self) -> None:
        for name in ("base_global_planner", "base_local_planner"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise ValueError(f"{name} must be a non-empty plugin name, got {getattr(self, name)!r}")
        _check_number("controller_frequency", self.controller_frequency, strict=True)
        for name in ("planner_frequency", "planner_patience", "controller_patience", "oscillation_timeout",
                     "oscillation_distance", "conservative_reset_dist"):
            _check_number(name, getattr(self, name))
        r = self.max_planning_retries
        if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < -1:
            raise ValueError(f"max_planning_retries must be an integer >= -1, got {r!r}")
        for name in ("recovery_behavior_enabled", "clearing_rotation_allowed", "abort_on_blocked_goal"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be true or false, got {getattr(self, name)!r}")
        names = self.recovery_behaviours
        if isinstance(names, str) or not all(isinstance(n, str) for n in names):
            raise ValueError(f"recovery_behaviours must be a list of names, got {names!r}")
        for n in names:
            if n not in RECOVERY_NAMES:
                raise ValueError(f"recovery_behaviours: unknown behaviour {n!r}; known: {', '.join(RECOVERY_NAMES)}")
        object.__setattr__(self, "recovery_behaviours", tuple(names))


@dataclass(frozen=True)
class VisionBiasConfig:
    """Row-centring correction blended into move_base's angular velocity.

    enabled: use the correction (default false until perception lands).
    max_age_s [s]: an estimate older than this is ignored (0.5).
    max_vision_rate [rad/s]: bound on the added angular rate. Default
    radians(5) = 0.0873 rad/s: the paper caps a correction at 5 deg, here
    at most 5 deg of heading change per second of correction.
    row_reach_m [m]: the robot counts as inside a crop row when the global or
    the local costmap has a LETHAL cell within this lateral distance on both sides (1.0).
    """

    enabled: bool = False
    max_age_s: float = 0.5
    max_vision_rate: float = math.radians(5.0)
    row_reach_m: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise ValueError(f"enabled must be true or false, got {self.enabled!r}")
        _check_number("max_age_s", self.max_age_s)
        _check_number("max_vision_rate", self.max_vision_rate)
        _check_number("row_reach_m", self.row_reach_m, strict=True)


def blend_vision(w_radps: float, vision_w_radps: Optional[float], age_s: Optional[float], in_row: bool,
                 config: VisionBiasConfig) -> float:
    """The local planner's angular velocity plus the bounded vision correction.

    Returns ``w_radps`` unchanged unless the correction is enabled, an
    estimate exists, is finite and younger than ``max_age_s``, and the
    robot is inside a crop row; then adds ``vision_w_radps`` clipped to
    +/- ``max_vision_rate``.
    """
    if not config.enabled or vision_w_radps is None or age_s is None or not in_row:
        return w_radps
    if not (math.isfinite(vision_w_radps) and math.isfinite(age_s)) or age_s < 0 or age_s > config.max_age_s:
        return w_radps
    return w_radps + max(-config.max_vision_rate, min(config.max_vision_rate, vision_w_radps))


def inside_crop_row(costmap: Costmap2D, pose: geo.Pose2D, reach_m: float = 1.0) -> bool:
    """True when LETHAL cells lie within ``reach_m`` to the left AND to the right of the robot.

    Samples lateral lines (perpendicular to the heading) at three points
    along the robot (-0.35, 0, +0.35 m, the plant spacing's half) so a single
    missing plant does not end the row.
    """
    step = 0.5 * costmap.spec.resolution_m
    lat = np.arange(step, reach_m + 1e-9, step)
    along = np.array([-0.35, 0.0, 0.35])
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    found = []
    for side in (1.0, -1.0):
        a, d = np.meshgrid(along, side * lat)
        x = pose.x_m + a * c - d * s
        y = pose.y_m + a * s + d * c
        found.append(bool(np.any(costmap.cost_at_world(x.ravel(), y.ravel()) == LETHAL_OBSTACLE)))
    return found[0] and found[1]


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


def _finite_pose(name: str, pose) -> geo.Pose2D:
    try:
        p = geo.as_pose(pose)
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
        if not isinstance(config, MoveBaseConfig):
            raise ValueError(f"config must be a MoveBaseConfig, got {type(config).__name__}")
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
        self.goal: Optional[geo.Pose2D] = None
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
        self.oscillation_pose: Optional[geo.Pose2D] = None
        self.planning_retries = 0
        self._last_plan_s = -math.inf
        self._last_reason = ""
        self._plan_tf: Optional[geo.Pose2D] = None

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

    # ------------------------------------------------------------------ helpers
    def _tolerance_m(self) -> float:
        cfg = getattr(self.global_planner, "config", None)
        return float(getattr(cfg, "default_tolerance", 0.0))

    def _blocked_goal_reason(self, goal: geo.Pose2D) -> str:
        """Reason text when the goal and its tolerance window are all obstacle cells, else ''."""
        cm = self.global_costmap
        spec = cm.spec
        tol = self._tolerance_m()
        gx, gy = (int(v) for v in spec.world_to_map(goal.x_m, goal.y_m))
        if not spec.in_bounds(gx, gy):
            return f"goal ({goal.x_m:.2f}, {goal.y_m:.2f}) is off the global costmap"
        n = int(math.floor(tol / spec.resolution_m + 1e-9))
        win = cm.costs[max(0, gy - n):gy + n + 1, max(0, gx - n):gx + n + 1]
        if win.size == 0 or not np.all((win == INSCRIBED_INFLATED_OBSTACLE) | (win == LETHAL_OBSTACLE)):
            return ""
        return (f"goal ({goal.x_m:.2f}, {goal.y_m:.2f}) is in an obstacle (cost {int(cm.costs[gy, gx])}) "
                f"and no free cell within default_tolerance {tol:g} m")

    def _global_costmap_clearable(self) -> bool:
        return any(isinstance(layer, ObstacleLayer) and layer.enabled for layer in self.global_costmap.layers)

    def _abort(self, reason: str) -> StepResult:
        self.goal = None
        self.state = MoveBaseState.IDLE
        self._running = None
        return StepResult(0.0, 0.0, MoveBaseState.IDLE, Outcome.ABORTED, reason)

    def _local_plan_sync(self, global_pose: geo.Pose2D, local_pose: geo.Pose2D) -> None:
        """Give the local planner the plan in the local frame when the plan or map -> odom changed.

        A new plan goes through ``set_plan``; a moved map -> odom (every GPS or
        AMCL correction) only through ``update_plan_frame``, so the local
        planner keeps its progress and goal latch as move_base's does (ROS
        hands DWA the plan once and transforms it each cycle).
        """
        t = geo.compose(global_pose, geo.inverse(local_pose))          # map -> odom
        if (self._plan_tf is not None and math.hypot(t.x_m - self._plan_tf.x_m, t.y_m - self._plan_tf.y_m) < 0.01
                and abs(geo.shortest_angular_distance(t.yaw_rad, self._plan_tf.yaw_rad)) < 0.01):
            return
        to_local = geo.inverse(t)
        poses = self.plan.poses
        xy = geo.transform_points(to_local, poses[:, :2])
        yaw = geo.normalize_angle(poses[:, 2] + to_local.yaw_rad)
        if self._plan_tf is None:                       # a new plan
            self.local_planner.set_plan(np.column_stack([xy, yaw]))
        else:                                           # the same plan, map -> odom moved
            self.local_planner.update_plan_frame(np.column_stack([xy, yaw]))
        self._plan_tf = t

    def _do_plan(self, now_s: float, global_pose: geo.Pose2D) -> Optional[StepResult]:
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
            if self.config.abort_on_blocked_goal and not self._global_costmap_clearable():
                return self._abort(blocked)
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

    def _trajectory(self, pose: geo.Pose2D, v: float, w: float) -> np.ndarray:
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
        return np.column_stack([x, y, geo.normalize_angle(th)])

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

        # planning: when asked to, or periodically while controlling
        replan_due = (cfg.planner_frequency > 0 and self.state == MoveBaseState.CONTROLLING
                      and now_s - self._last_plan_s >= 1.0 / cfg.planner_frequency)
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
