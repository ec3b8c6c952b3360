"""Validation of a joint trajectory goal for the simulated UR5e (the core of the trajectory action).

A goal carries what control_msgs/FollowJointTrajectory's goal carries, as
plain data (``TrajectoryGoal``): joint names, points (positions, optional
velocities and accelerations, time from start), path and goal tolerances and
the goal time tolerance, plus the trajectory's start time (the header stamp;
0 = now). ``validate_goal`` either returns a ``ValidTrajectory`` in the arm's
joint order and in absolute sim time, starting at the arm's current state,
or raises ``GoalRejected`` with control_msgs' error code and the reason:

* INVALID_JOINTS: no, duplicate, unknown or missing joint names (a goal moves
  all six joints), or a tolerance for a joint the arm does not have;
* INVALID_GOAL: no points, a point whose arrays do not match the joint names,
  NaN or infinite values, positions outside the joint limits, velocities
  over the velocity limits, times that do not increase, a segment that needs
  more than a joint's speed limit (its mean speed over the limit), a first
  point at the start time away from the current position (a jump), bad
  tolerances;
* OLD_HEADER_TIMESTAMP: the whole trajectory lies in the past.

Points at or before the current time (a stamp in the past) are dropped; a
first point at the start time must be within ``start_tolerance_rad`` of the
current joints and is then dropped too (MoveIt's trajectories begin with the
current state). Tolerance values follow control_msgs/JointTolerance: > 0 the
tolerance, 0 the controller's default, < 0 no check.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

# control_msgs/FollowJointTrajectoryResult's error codes (also in cottonsim_msgs' action)
SUCCESSFUL = 0
INVALID_GOAL = -1
INVALID_JOINTS = -2
OLD_HEADER_TIMESTAMP = -3
PATH_TOLERANCE_VIOLATED = -4
GOAL_TOLERANCE_VIOLATED = -5


class GoalRejected(ValueError):
    """A goal the controller refuses: ``error_code`` (control_msgs' code) and the reason (the message)."""

    def __init__(self, error_code: int, reason: str):
        super().__init__(reason)
        self.error_code = error_code
        self.reason = reason


@dataclass(frozen=True)
class TrajectoryPoint:
    """One point: positions [rad], velocities [rad/s] and accelerations [rad/s^2] (each empty or one per joint)."""

    positions: Tuple[float, ...]
    velocities: Tuple[float, ...] = ()
    accelerations: Tuple[float, ...] = ()
    time_from_start_s: float = 0.0


@dataclass(frozen=True)
class JointToleranceSpec:
    """control_msgs/JointTolerance: > 0 the tolerance, 0 the default, < 0 none [rad, rad/s, rad/s^2]."""

    name: str
    position: float = 0.0
    velocity: float = 0.0
    acceleration: float = 0.0


@dataclass(frozen=True)
class TrajectoryGoal:
    """A FollowJointTrajectory goal as plain data; start_time_s is the header stamp (0 = now) [s sim time]."""

    joint_names: Tuple[str, ...]
    points: Tuple[TrajectoryPoint, ...]
    path_tolerance: Tuple[JointToleranceSpec, ...] = ()
    goal_tolerance: Tuple[JointToleranceSpec, ...] = ()
    goal_time_tolerance_s: float = 0.0
    start_time_s: float = 0.0


@dataclass(frozen=True)
class ArmLimits:
    """The arm's joints (controller order) and their limits: position [rad] and speed [rad/s]."""

    joint_names: Tuple[str, ...]
    lower_rad: np.ndarray
    upper_rad: np.ndarray
    velocity_rad_s: np.ndarray


@dataclass(frozen=True)
class ValidTrajectory:
    """An accepted goal in the arm's joint order and absolute sim time.

    times_s (K,): knot times, the first the start (now, at the current state);
    positions (K, 6); velocities, accelerations (K, 6) with NaN where the goal
    gave none (the first knot has the current velocity and zero acceleration).
    path_tolerance_rad, goal_tolerance_rad (6,): position tolerances (inf = no
    check); goal_velocity_tolerance_rad_s (6,); goal_time_tolerance_s.
    """

    times_s: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    path_tolerance_rad: np.ndarray
    goal_tolerance_rad: np.ndarray
    goal_velocity_tolerance_rad_s: np.ndarray
    goal_time_tolerance_s: float

    @property
    def end_time_s(self) -> float:
        return float(self.times_s[-1])


def _finite(value, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise GoalRejected(INVALID_GOAL, f"{what} is not a number: {value!r}") from None
    if not math.isfinite(v):
        raise GoalRejected(INVALID_GOAL, f"{what} is {v} (NaN or infinite)")
    return v


def _check_joint_names(names: Sequence[str], limits: ArmLimits) -> np.ndarray:
    """Index into the goal's arrays of each arm joint (controller order)."""
    names = list(names)
    if not names:
        raise GoalRejected(INVALID_JOINTS, f"the goal names no joints; the arm's joints are {list(limits.joint_names)}")
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise GoalRejected(INVALID_JOINTS, f"joint names appear more than once: {duplicates}")
    unknown = [n for n in names if n not in limits.joint_names]
    if unknown:
        raise GoalRejected(INVALID_JOINTS, f"unknown joints {unknown}; the arm's joints are "
                                           f"{list(limits.joint_names)}")
    missing = [n for n in limits.joint_names if n not in names]
    if missing:
        raise GoalRejected(INVALID_JOINTS, f"the goal lacks joints {missing}: it must name all "
                                           f"{len(limits.joint_names)} arm joints")
    return np.array([names.index(n) for n in limits.joint_names])


def _point_array(values: Sequence[float], n: int, order: np.ndarray, what: str, names) -> Optional[np.ndarray]:
    """Values of one point field in controller order; None when empty."""
    if len(values) == 0:
        return None
    if len(values) != n:
        raise GoalRejected(INVALID_GOAL, f"{what} has {len(values)} values for {n} joint names")
    arr = np.array([_finite(v, f"{what} of {names[i]}") for i, v in enumerate(values)])
    return arr[order]


def _tolerances(specs: Sequence[JointToleranceSpec], limits: ArmLimits, default_position: float,
                default_velocity: float, what: str) -> Tuple[np.ndarray, np.ndarray]:
    """Position and velocity tolerances per arm joint; inf where a spec says < 0 (no check)."""
    pos = np.full(len(limits.joint_names), default_position, dtype=float)
    vel = np.full(len(limits.joint_names), default_velocity, dtype=float)
    for spec in specs:
        if spec.name not in limits.joint_names:
            raise GoalRejected(INVALID_JOINTS, f"{what} names unknown joint {spec.name!r}")
        i = limits.joint_names.index(spec.name)
        p = _finite(spec.position, f"{what} position of {spec.name}")
        v = _finite(spec.velocity, f"{what} velocity of {spec.name}")
        _finite(spec.acceleration, f"{what} acceleration of {spec.name}")
        if p != 0.0:
            pos[i] = p if p > 0.0 else math.inf
        if v != 0.0:
            vel[i] = v if v > 0.0 else math.inf
    return pos, vel


@dataclass(frozen=True)
class GoalDefaults:
    """The controller's defaults for what a goal leaves at 0 (see ArmControllerConfig)."""

    goal_position_tolerance_rad: float
    goal_velocity_tolerance_rad_s: float
    path_position_tolerance_rad: float      # inf: no path check
    goal_time_tolerance_s: float
    start_tolerance_rad: float


def validate_goal(goal: TrajectoryGoal, limits: ArmLimits, now_s: float, current_rad: np.ndarray,
                  current_velocity_rad_s: np.ndarray, defaults: GoalDefaults) -> ValidTrajectory:
    """The goal as a ValidTrajectory starting now at the current state; GoalRejected with the reason."""
    names = list(goal.joint_names)
    order = _check_joint_names(names, limits)
    if not goal.points:
        raise GoalRejected(INVALID_GOAL, "the trajectory has no points")
    start = _finite(goal.start_time_s, "the header stamp")
    start = now_s if start <= 0.0 else start
    n = len(names)
    times, positions, velocities, accelerations = [], [], [], []
    previous_t = -math.inf
    for k, point in enumerate(goal.points):
        t = _finite(point.time_from_start_s, f"point {k} time_from_start")
        if t < 0.0:
            raise GoalRejected(INVALID_GOAL, f"point {k} time_from_start {t} s is negative")
        if t <= previous_t:
            raise GoalRejected(INVALID_GOAL, f"point {k} time_from_start {t} s is not after point {k - 1}'s "
                                             f"{previous_t} s: times must increase")
        previous_t = t
        q = _point_array(point.positions, n, order, f"point {k} position", names)
        if q is None:
            raise GoalRejected(INVALID_GOAL, f"point {k} has no positions")
        qd = _point_array(point.velocities, n, order, f"point {k} velocity", names)
        qdd = _point_array(point.accelerations, n, order, f"point {k} acceleration", names)
        if qdd is not None and qd is None:
            raise GoalRejected(INVALID_GOAL, f"point {k} has accelerations but no velocities")
        outside = (q < limits.lower_rad) | (q > limits.upper_rad)
        if outside.any():
            j = int(np.flatnonzero(outside)[0])
            raise GoalRejected(INVALID_GOAL, f"point {k}: {limits.joint_names[j]} = {q[j]:.6g} rad is outside its "
                                             f"limits [{limits.lower_rad[j]:.6g}, {limits.upper_rad[j]:.6g}]")
        if qd is not None:
            over = np.abs(qd) > limits.velocity_rad_s
            if over.any():
                j = int(np.flatnonzero(over)[0])
                raise GoalRejected(INVALID_GOAL, f"point {k}: {limits.joint_names[j]} velocity {qd[j]:.6g} rad/s "
                                                 f"is over its limit {limits.velocity_rad_s[j]:.6g} rad/s")
        times.append(start + t)
        positions.append(q)
        velocities.append(qd if qd is not None else np.full(len(order), np.nan))
        accelerations.append(qdd if qdd is not None else np.full(len(order), np.nan))
    current = np.asarray(current_rad, dtype=float)
    if times[-1] <= now_s:
        raise GoalRejected(OLD_HEADER_TIMESTAMP, f"the trajectory ended at {times[-1]:.3f} s, before now "
                                                 f"({now_s:.3f} s): its header stamp is too old")
    keep = [k for k, t in enumerate(times) if t > now_s + 1e-9]
    first = keep[0]
    if first > 0 and times[first - 1] >= now_s - 1e-9:
        jump = np.abs(positions[first - 1] - current)
        if np.max(jump) > defaults.start_tolerance_rad:
            j = int(np.argmax(jump))
            raise GoalRejected(INVALID_GOAL, f"the point at the start time puts {limits.joint_names[j]} "
                                             f"{jump[j]:.4g} rad from its current position (more than the "
                                             f"{defaults.start_tolerance_rad:g} rad start tolerance): a jump")
    knots_t = np.array([now_s] + [times[k] for k in keep])
    knots_q = np.vstack([current] + [positions[k] for k in keep])
    speed = np.abs(np.diff(knots_q, axis=0)) / np.diff(knots_t)[:, None]
    over = speed > limits.velocity_rad_s * (1.0 + 1e-6)
    if over.any():
        s, j = (int(v) for v in np.argwhere(over)[0])
        what = "from the current position to point %d" % keep[0] if s == 0 else \
            "from point %d to point %d" % (keep[s - 1], keep[s])
        raise GoalRejected(INVALID_GOAL, f"{limits.joint_names[j]} must move {speed[s, j]:.4g} rad/s on average "
                                         f"{what}, over its {limits.velocity_rad_s[j]:.4g} rad/s limit")
    path_tol, _ = _tolerances(goal.path_tolerance, limits, defaults.path_position_tolerance_rad, math.inf,
                              "path_tolerance")
    goal_tol, goal_vel_tol = _tolerances(goal.goal_tolerance, limits, defaults.goal_position_tolerance_rad,
                                         defaults.goal_velocity_tolerance_rad_s, "goal_tolerance")
    time_tol = _finite(goal.goal_time_tolerance_s, "goal_time_tolerance")
    if time_tol < 0.0:
        raise GoalRejected(INVALID_GOAL, f"goal_time_tolerance {time_tol} s is negative")
    return ValidTrajectory(
        times_s=knots_t, positions=knots_q,
        velocities=np.vstack([np.asarray(current_velocity_rad_s, dtype=float)] + [velocities[k] for k in keep]),
        accelerations=np.vstack([np.zeros(len(order))] + [accelerations[k] for k in keep]),
        path_tolerance_rad=path_tol, goal_tolerance_rad=goal_tol, goal_velocity_tolerance_rad_s=goal_vel_tol,
        goal_time_tolerance_s=time_tol if time_tol > 0.0 else defaults.goal_time_tolerance_s)
