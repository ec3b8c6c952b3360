"""UR5e arm in the simulator: a joint-limit-respecting position follower.

The CottonSim robot carries a UR5e that, as in the original, is only driven to
poses (e.g. a stow pose) and reported on /joint_states. The simulator does not
need the arm's dynamics, so the arm is modelled as six joints that each move
towards their commanded target at no more than the joint's velocity limit and
never leave its position limits, like a position-controlled trajectory
follower with infinite acceleration (``command`` / ``step``, the
/arm_controller/command topic). The trajectory action drives it with
``track``: joint servos with a velocity feed-forward, a position gain and an
acceleration limit (robot/arm_tracker.py).

The kinematics (the UR5e's DH table, forward and inverse kinematics) live in
cottonsim_common.kinematics.ur5e, shared with the robot-side arm code; the
names below are re-exported from there. The URDF chain ur5e_base -> ur5e_tool0
gives the same pose as forward_kinematics (checked by the unit tests).
"""
from __future__ import annotations

import math
from typing import Mapping, Optional, Sequence, Tuple

import numpy as np

from cottonsim_common.kinematics.ur5e import (  # noqa: F401  (re-exported API)
    JOINT_NAMES,
    NUM_JOINTS,
    Ur5eKinematics,
    dh_transform,
    forward_kinematics,
    joint_vector as _joint_vector,
)
from cottonsim_world.robot.urdf_model import JointLimits, UrdfModel

__all__ = ["JOINT_NAMES", "NUM_JOINTS", "Ur5eArm", "Ur5eKinematics", "dh_transform", "forward_kinematics"]


class Ur5eArm:
    """Six joints following position targets within their limits.

    ``command(q)`` sets targets (clamped into the position limits); each
    ``step(dt_s)`` moves every joint towards its target by at most
    velocity_limit * dt_s and records the resulting velocity [rad/s].
    Joint order: JOINT_NAMES (shoulder pan first, wrist 3 last).
    """

    def __init__(self, limits: Sequence[JointLimits], initial_positions: Optional[Sequence[float]] = None):
        limits = tuple(limits)
        if len(limits) != NUM_JOINTS:
            raise ValueError(f"limits must have {NUM_JOINTS} JointLimits (one per joint), got {len(limits)}")
        for name, lim in zip(JOINT_NAMES, limits):
            if not isinstance(lim, JointLimits):
                raise ValueError(f"limits of {name} must be a JointLimits, got {type(lim).__name__}")
            values = (lim.lower, lim.upper, lim.velocity, lim.effort)
            if not all(math.isfinite(v) for v in values):
                raise ValueError(f"limits of {name} must be finite, got {lim}")
            if lim.lower > lim.upper:
                raise ValueError(f"limits of {name}: lower {lim.lower} > upper {lim.upper}")
            if lim.velocity <= 0.0:
                raise ValueError(f"limits of {name}: velocity must be > 0 rad/s, got {lim.velocity}")
        self.limits: Tuple[JointLimits, ...] = limits
        self._lower = np.array([lim.lower for lim in limits])
        self._upper = np.array([lim.upper for lim in limits])
        self._max_speed = np.array([lim.velocity for lim in limits])
        if initial_positions is None:
            start = np.clip(np.zeros(NUM_JOINTS), self._lower, self._upper)
        else:
            start = _joint_vector(initial_positions, "initial_positions")
            outside = (start < self._lower) | (start > self._upper)
            if np.any(outside):
                bad = [JOINT_NAMES[i] for i in np.flatnonzero(outside)]
                raise ValueError(f"initial_positions outside the position limits for {bad}")
        self._positions = start.copy()
        self._targets = start.copy()
        self._velocities = np.zeros(NUM_JOINTS)

    @classmethod
    def from_urdf(cls, model: UrdfModel, prefix: str = "ur5e_",
                  initial_positions: Optional[Sequence[float]] = None) -> "Ur5eArm":
        """Build with the limits of joints '<prefix><joint name>' of a URDF."""
        return cls([model.joint_limits(prefix + name) for name in JOINT_NAMES], initial_positions)

    @property
    def positions(self) -> np.ndarray:
        """Current joint angles [rad] (a copy)."""
        return self._positions.copy()

    @property
    def velocities(self) -> np.ndarray:
        """Joint velocities of the last step [rad/s] (a copy)."""
        return self._velocities.copy()

    @property
    def targets(self) -> np.ndarray:
        """Current targets after clamping [rad] (a copy)."""
        return self._targets.copy()

    def command(self, positions: Sequence[float] | Mapping[str, float]) -> np.ndarray:
        """Set target angles [rad]: 6 values in JOINT_NAMES order, or a dict
        by joint name (missing joints keep their target). Targets outside the
        position limits are clamped; the clamped targets are returned."""
        if isinstance(positions, Mapping):
            targets = self._targets.copy()
            for name, value in positions.items():
                if name not in JOINT_NAMES:
                    raise ValueError(f"unknown UR5e joint {name!r}; expected one of {JOINT_NAMES}")
                value = float(value)
                if not math.isfinite(value):
                    raise ValueError(f"target of {name} is not finite: {value}")
                targets[JOINT_NAMES.index(name)] = value
        else:
            targets = _joint_vector(positions, "commanded positions")
        self._targets = np.clip(targets, self._lower, self._upper)
        return self._targets.copy()

    def step(self, dt_s: float) -> np.ndarray:
        """Advance dt_s seconds; returns the new positions [rad]."""
        dt = float(dt_s)
        if not math.isfinite(dt) or dt <= 0.0:
            raise ValueError(f"dt_s must be a positive finite time step, got {dt_s!r}")
        max_move = self._max_speed * dt
        move = np.clip(self._targets - self._positions, -max_move, max_move)
        self._positions = np.clip(self._positions + move, self._lower, self._upper)
        self._velocities = move / dt
        return self._positions.copy()

    def track(self, desired_rad: np.ndarray, desired_velocity_rad_s: np.ndarray, dt_s: float, gain_1_s: float,
              max_acceleration_rad_s2: float) -> np.ndarray:
        """One step of the joint servos following a trajectory [rad, rad/s]: velocity = desired velocity +
        gain_1_s * position error, within the velocity limits and max_acceleration_rad_s2 of the last
        step's velocity; the target becomes the desired positions. Returns the new positions [rad]."""
        dt = float(dt_s)
        if not math.isfinite(dt) or dt <= 0.0:
            raise ValueError(f"dt_s must be a positive finite time step, got {dt_s!r}")
        velocity = np.asarray(desired_velocity_rad_s, dtype=float) + gain_1_s * (desired_rad - self._positions)
        velocity = np.clip(velocity, -self._max_speed, self._max_speed)
        change = max_acceleration_rad_s2 * dt
        velocity = np.clip(velocity, self._velocities - change, self._velocities + change)
        new = np.clip(self._positions + velocity * dt, self._lower, self._upper)
        self._velocities = (new - self._positions) / dt
        self._positions = new
        self._targets = np.clip(np.asarray(desired_rad, dtype=float), self._lower, self._upper)
        return self._positions.copy()

    def come_to_rest(self) -> None:
        """Stop: velocities zero, the target the current positions (the servos have settled)."""
        self._velocities = np.zeros(NUM_JOINTS)
        self._targets = self._positions.copy()

    def at_target(self, tolerance_rad: float = 1e-9) -> bool:
        """True when every joint is within tolerance_rad of its target."""
        return bool(np.all(np.abs(self._targets - self._positions) <= tolerance_rad))

    def tool_pose(self, kinematics: Optional[Ur5eKinematics] = None) -> np.ndarray:
        """4x4 pose of tool0 in ur5e_base at the current positions."""
        return forward_kinematics(self._positions, kinematics)
