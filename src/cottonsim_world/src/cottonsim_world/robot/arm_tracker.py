"""The simulated arm controller: tracks accepted joint trajectories at the physics rate.

``ArmTrajectoryTracker`` is what a UR's joint_trajectory_controller does,
without ROS: ``accept`` a validated trajectory (arm_goal.py) for a goal id
(preempting the running one, whose motion the new trajectory continues from
the arm's current state), ``cancel`` it (the arm brakes to rest where it is,
arm_trajectory.StopProfile, and the goal ends once it is at rest), and
``step`` at every physics step: the desired state is sampled from the
trajectory and the joint servos of ``Ur5eArm.track`` follow it (velocity
feed-forward, position gain, acceleration limit), so the arm lags a little
and never jumps. Tolerances as control_msgs defines them: the path tolerance
is checked at every step (a violation aborts and brakes), the goal tolerance
from the last point's time until goal_time_tolerance later (success as soon
as every joint is within it and slower than the velocity tolerance, abort
after). Finished goals come out of ``take_outcomes`` in order.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Hashable, List, Optional, Sequence

import numpy as np

from cottonsim_world.robot.arm_goal import (GOAL_TOLERANCE_VIOLATED, PATH_TOLERANCE_VIOLATED, SUCCESSFUL, GoalDefaults,
                                            ValidTrajectory)
from cottonsim_world.robot.arm_trajectory import StopProfile, sample
from cottonsim_world.robot.ur5e import JOINT_NAMES, NUM_JOINTS, Ur5eArm

SETTLED_RAD = 1e-7          # a holding arm this close to its hold position, and ...
SETTLED_RAD_S = 1e-5        # ... this slow, is at rest: the tracker goes idle


def _number(config, name: str, low: float, high: float = math.inf, low_open: bool = True) -> None:
    v = getattr(config, name)
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v <= high \
        and (v > low if low_open else v >= low)
    if not ok:
        bound = f"> {low}" if low_open else f">= {low}"
        raise ValueError(f"ArmControllerConfig.{name} must be a finite number {bound}"
                         f"{'' if high == math.inf else f' and <= {high}'}, got {v!r}")


@dataclass(frozen=True)
class ArmControllerConfig:
    """The simulated UR5e controller (sim.yaml 'arm_controller').

    servo_gain_1_s: joint servo position gain [1/s] (error time constant 1/gain).
    max_acceleration_rad_s2: joint acceleration limit of the servos [rad/s^2].
    stop_deceleration_rad_s2: braking of a cancelled, preempted-by-stop or aborted motion [rad/s^2].
    goal_position_tolerance_rad, goal_velocity_tolerance_rad_s: defaults of a goal's goal_tolerance.
    path_position_tolerance_rad: default path tolerance [rad]; 0 = no path check.
    goal_time_tolerance_s: default goal_time_tolerance [s].
    start_tolerance_rad: how far a point at the start time may be from the current joints [rad].
    feedback_period_s: action feedback period [s sim time].
    """

    servo_gain_1_s: float = 20.0
    max_acceleration_rad_s2: float = 15.0
    stop_deceleration_rad_s2: float = 6.0
    goal_position_tolerance_rad: float = 0.01
    goal_velocity_tolerance_rad_s: float = 0.01
    path_position_tolerance_rad: float = 0.0
    goal_time_tolerance_s: float = 0.5
    start_tolerance_rad: float = 0.02
    feedback_period_s: float = 0.02

    def __post_init__(self) -> None:
        _number(self, "servo_gain_1_s", 0.0, 1000.0)
        _number(self, "max_acceleration_rad_s2", 0.0)
        _number(self, "stop_deceleration_rad_s2", 0.0)
        _number(self, "goal_position_tolerance_rad", 0.0)
        _number(self, "goal_velocity_tolerance_rad_s", 0.0)
        _number(self, "path_position_tolerance_rad", 0.0, low_open=False)
        _number(self, "goal_time_tolerance_s", 0.0, low_open=False)
        _number(self, "start_tolerance_rad", 0.0, low_open=False)
        _number(self, "feedback_period_s", 0.0, 10.0)

    def goal_defaults(self) -> GoalDefaults:
        path = self.path_position_tolerance_rad
        return GoalDefaults(self.goal_position_tolerance_rad, self.goal_velocity_tolerance_rad_s,
                            path if path > 0.0 else math.inf, self.goal_time_tolerance_s, self.start_tolerance_rad)


@dataclass(frozen=True)
class GoalOutcome:
    """How a goal ended: status 'succeeded', 'aborted', 'preempted' or 'canceled'; control_msgs' code and text."""

    goal_id: Hashable
    status: str
    error_code: int
    error_string: str


@dataclass(frozen=True)
class TrackingState:
    """Desired, actual and error at one instant, in the arm's joint order [rad, rad/s, rad/s^2]."""

    time_s: float
    desired_rad: np.ndarray
    desired_rad_s: np.ndarray
    desired_rad_s2: np.ndarray
    actual_rad: np.ndarray
    actual_rad_s: np.ndarray


class ArmTrajectoryTracker:
    """Tracks one trajectory at a time on a Ur5eArm (see the module docstring)."""

    def __init__(self, arm: Ur5eArm, config: ArmControllerConfig = ArmControllerConfig(),
                 joint_names: Sequence[str] = tuple("ur5e_" + name for name in JOINT_NAMES)):
        if len(joint_names) != NUM_JOINTS:
            raise ValueError(f"joint_names must name the arm's {NUM_JOINTS} joints, got {list(joint_names)}")
        self.arm = arm
        self.joint_names = tuple(joint_names)
        self.config = config
        self._trajectory: Optional[ValidTrajectory] = None
        self._stop: Optional[StopProfile] = None
        self._hold: Optional[np.ndarray] = None
        self._goal: Optional[Hashable] = None         # the goal the motion belongs to
        self._stop_outcome: Optional[GoalOutcome] = None   # sent once the stop is at rest
        self._outcomes: List[GoalOutcome] = []
        self._last: Optional[TrackingState] = None

    @property
    def busy(self) -> bool:
        """Whether the tracker drives the arm (a trajectory, a stop or a hold not yet at rest)."""
        return self._trajectory is not None or self._stop is not None or self._hold is not None

    @property
    def active_goal(self) -> Optional[Hashable]:
        """The goal being executed or stopped for, if any."""
        return self._goal

    @property
    def last_state(self) -> Optional[TrackingState]:
        """Desired and actual state of the last step (None before the first step with a goal)."""
        return self._last

    def take_outcomes(self) -> List[GoalOutcome]:
        out, self._outcomes = self._outcomes, []
        return out

    def _end_goal(self, status: str, code: int, text: str) -> None:
        if self._goal is not None:
            self._outcomes.append(GoalOutcome(self._goal, status, code, text))
        self._goal = None

    def accept(self, goal_id: Hashable, trajectory: ValidTrajectory) -> None:
        """Start tracking trajectory for goal_id; a running goal ends 'preempted'."""
        if self._goal is not None:
            pending = self._stop_outcome
            if pending is not None:
                self._outcomes.append(pending)
                self._goal = None
            else:
                self._end_goal("preempted", SUCCESSFUL, f"preempted by goal {goal_id}")
        self._trajectory, self._stop, self._hold, self._stop_outcome = trajectory, None, None, None
        self._goal = goal_id

    def cancel(self, goal_id: Hashable, now_s: float) -> bool:
        """Brake the arm to rest; the goal ends 'canceled' once at rest. False if goal_id is not running."""
        if goal_id != self._goal or self._stop_outcome is not None:
            return False
        self._begin_stop(now_s, GoalOutcome(goal_id, "canceled", SUCCESSFUL, "cancelled: the arm stopped where it was"))
        return True

    def supersede(self, reason: str) -> None:
        """Another command takes the arm over (the /arm_controller/command topic): the goal is aborted now."""
        if self._stop_outcome is not None:
            self._outcomes.append(self._stop_outcome)
            self._goal = None
        self._end_goal("aborted", SUCCESSFUL, reason)
        self._trajectory = self._stop = self._hold = self._stop_outcome = None

    def _begin_stop(self, now_s: float, outcome: Optional[GoalOutcome]) -> None:
        self._trajectory, self._hold = None, None
        self._stop = StopProfile(now_s, self.arm.positions, self.arm.velocities, self.config.stop_deceleration_rad_s2)
        self._stop_outcome = outcome
        if outcome is None:
            self._goal = None

    def step(self, now_s: float, dt_s: float) -> None:
        """Advance the arm by dt_s to sim time now_s following the trajectory, stop or hold."""
        cfg = self.config
        if self._trajectory is not None:
            q_d, v_d, a_d = sample(self._trajectory, now_s)
        elif self._stop is not None:
            q_d, v_d, a_d = self._stop.sample(now_s)
        elif self._hold is not None:
            q_d, v_d, a_d = self._hold, np.zeros(len(self._hold)), np.zeros(len(self._hold))
        else:
            return
        self.arm.track(q_d, v_d, dt_s, cfg.servo_gain_1_s, cfg.max_acceleration_rad_s2)
        q, v = self.arm.positions, self.arm.velocities
        self._last = TrackingState(now_s, q_d, v_d, a_d, q, v)
        if self._trajectory is not None:
            self._check_trajectory(now_s, q_d, q, v)
        elif self._stop is not None:
            if now_s >= self._stop.end_time_s and np.all(np.abs(v) <= cfg.goal_velocity_tolerance_rad_s):
                if self._stop_outcome is not None:
                    self._outcomes.append(self._stop_outcome)
                    self._goal = None
                self._hold, self._stop, self._stop_outcome = q_d, None, None
        elif np.all(np.abs(q - q_d) <= SETTLED_RAD) and np.all(np.abs(v) <= SETTLED_RAD_S):
            self.arm.come_to_rest()     # the position follower holds it from here
            self._hold = None

    def _check_trajectory(self, now_s: float, q_d: np.ndarray, q: np.ndarray, v: np.ndarray) -> None:
        traj = self._trajectory
        names = self.joint_names
        error = np.abs(q - q_d)
        if now_s < traj.end_time_s:
            over = error > traj.path_tolerance_rad
            if over.any():
                j = int(np.flatnonzero(over)[0])
                self._end_goal("aborted", PATH_TOLERANCE_VIOLATED,
                               f"{names[j]} is {error[j]:.4g} rad from the trajectory at {now_s:.3f} s, over its "
                               f"path tolerance {traj.path_tolerance_rad[j]:.4g} rad")
                self._begin_stop(now_s, None)
            return
        final = traj.positions[-1]
        error = np.abs(q - final)
        if np.all(error <= traj.goal_tolerance_rad) and np.all(np.abs(v) <= traj.goal_velocity_tolerance_rad_s):
            self._end_goal("succeeded", SUCCESSFUL, "")
            self._trajectory, self._hold = None, final.copy()
            return
        if now_s > traj.end_time_s + traj.goal_time_tolerance_s + 1e-9:
            j = int(np.argmax(error / traj.goal_tolerance_rad))     # the joint furthest out (inf: none)
            self._end_goal("aborted", GOAL_TOLERANCE_VIOLATED,
                           f"{traj.goal_time_tolerance_s:g} s after the trajectory's end {names[j]} is "
                           f"{error[j]:.4g} rad from its goal (tolerance {traj.goal_tolerance_rad[j]:.4g} rad), "
                           f"max speed {np.max(np.abs(v)):.4g} rad/s")
            self._begin_stop(now_s, None)
