"""UR5e arm: forward kinematics (DH) and a joint-limit-respecting position follower.

The CottonSim robot carries a UR5e that, as in the original, is only driven to
poses (e.g. a stow pose) and reported on /joint_states. The simulator does not
need the arm's dynamics, so the arm is modelled as six joints that each move
towards their commanded target at no more than the joint's velocity limit and
never leave its position limits, like a position-controlled trajectory
follower with infinite acceleration.

Forward kinematics uses the UR5e's standard Denavit-Hartenberg table
(Universal Robots' published parameters; lengths in metres):

    i   a_i       alpha_i   d_i
    1   0         +pi/2     d1 = 0.1625
    2   a2=-0.425  0        0
    3   a3=-0.3922 0        0
    4   0         +pi/2     d4 = 0.1333
    5   0         -pi/2     d5 = 0.0997
    6   0          0        d6 = 0.0996

A_i = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i); T_base_tool0 = A_1 ... A_6. The
base frame is the UR controller's 'base' (ur5e_base in the URDF: ur5e_base_link
turned by pi about z); tool0 has z out of the flange. The URDF chain
ur5e_base -> ur5e_tool0 gives the same pose (checked by the unit tests).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Optional, Sequence, Tuple

import numpy as np

from cottonsim_world.robot.urdf_model import JointLimits, UrdfModel

JOINT_NAMES: Tuple[str, ...] = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
NUM_JOINTS = len(JOINT_NAMES)


@dataclass(frozen=True)
class Ur5eKinematics:
    """UR5e DH lengths [m] (defaults: Universal Robots' published values)."""

    d1_m: float = 0.1625
    a2_m: float = -0.425
    a3_m: float = -0.3922
    d4_m: float = 0.1333
    d5_m: float = 0.0997
    d6_m: float = 0.0996

    def __post_init__(self) -> None:
        for name in ("d1_m", "a2_m", "a3_m", "d4_m", "d5_m", "d6_m"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"Ur5eKinematics.{name} must be a finite number, got {value!r}")
            if abs(value) > 5.0:
                raise ValueError(f"Ur5eKinematics.{name} = {value} m is not a plausible UR5e length")

    def dh_table(self) -> Tuple[Tuple[float, float, float], ...]:
        """Rows (a_i [m], alpha_i [rad], d_i [m]) for i = 1..6."""
        half_pi = math.pi / 2.0
        return (
            (0.0, half_pi, self.d1_m),
            (self.a2_m, 0.0, 0.0),
            (self.a3_m, 0.0, 0.0),
            (0.0, half_pi, self.d4_m),
            (0.0, -half_pi, self.d5_m),
            (0.0, 0.0, self.d6_m),
        )


def dh_transform(a_m: float, alpha_rad: float, d_m: float, theta_rad: float) -> np.ndarray:
    """Standard DH step Rz(theta) Tz(d) Tx(a) Rx(alpha) as a 4x4 matrix."""
    ct, st = math.cos(theta_rad), math.sin(theta_rad)
    ca, sa = math.cos(alpha_rad), math.sin(alpha_rad)
    return np.array(
        [
            [ct, -st * ca, st * sa, a_m * ct],
            [st, ct * ca, -ct * sa, a_m * st],
            [0.0, sa, ca, d_m],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _joint_vector(values: Sequence[float], what: str) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be {NUM_JOINTS} numbers, got {values!r}") from None
    if arr.shape != (NUM_JOINTS,):
        raise ValueError(f"{what} must have {NUM_JOINTS} values, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} contains NaN or infinity: {arr.tolist()}")
    return arr


def forward_kinematics(q_rad: Sequence[float], kinematics: Optional[Ur5eKinematics] = None) -> np.ndarray:
    """4x4 pose of tool0 in the arm's base frame (ur5e_base) for joint angles q [rad]."""
    q = _joint_vector(q_rad, "joint angles")
    kin = kinematics or Ur5eKinematics()
    out = np.eye(4)
    for (a, alpha, d), theta in zip(kin.dh_table(), q):
        out = out @ dh_transform(a, alpha, d, theta)
    return out


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

    def at_target(self, tolerance_rad: float = 1e-9) -> bool:
        """True when every joint is within tolerance_rad of its target."""
        return bool(np.all(np.abs(self._targets - self._positions) <= tolerance_rad))

    def tool_pose(self, kinematics: Optional[Ur5eKinematics] = None) -> np.ndarray:
        """4x4 pose of tool0 in ur5e_base at the current positions."""
        return forward_kinematics(self._positions, kinematics)
