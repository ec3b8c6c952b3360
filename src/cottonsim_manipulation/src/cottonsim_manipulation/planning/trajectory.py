"""Time-parameterised joint trajectories through waypoints, within speed and acceleration limits.

The arm stops at every waypoint (a pick is a chain of stops: pre-grasp, grasp,
retreat), and between two waypoints all joints move on one synchronised
trapezoidal velocity profile: every joint starts, cruises and arrives
together, so the joint-space path is the straight segment between the
waypoints whatever the timing (the collision checker relies on this). Per
segment, with D_j the distance of joint j, the normalised profile s(t) in
[0, 1] runs at the largest speed V = min_j v_j / |D_j| and acceleration
A = min_j a_j / |D_j| that no joint exceeds:

* V^2 / A <= 1: accelerate for V / A, cruise, decelerate (trapezoid),
  duration 1 / V + V / A;
* otherwise a triangle: accelerate for sqrt(1 / A), then decelerate.

The tool's speed is limited too, as a UR's safety settings limit it: V is
lowered until neither the flange nor the nozzle's tip moves faster than
``max_tool_speed_m_s`` anywhere on the segment (their speed per unit of s is
measured by forward kinematics at points along it, ``TOOL_SPEED_STEP_RAD`` of
the leading joint apart). So a long swing of the shoulder runs at the tool's
limit, while the wrist's short turns run at the joints' limits.

This is the time-optimal profile among those that keep the joints in step.
Limits: UR5e 180 deg/s per joint (cottonsim_common.kinematics.ur5e), of which
a plan uses ``velocity_scale``; acceleration ``max_acceleration_rad_s2``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

from cottonsim_common.kinematics.arm_capsules import ArmCollisionConfig
from cottonsim_common.kinematics.ur5e import (
    JOINT_NAMES,
    NUM_JOINTS,
    UR5E_LOWER_LIMITS_RAD,
    UR5E_MAX_SPEED_RAD_S,
    UR5E_UPPER_LIMITS_RAD,
    link_frames,
)

TOOL_SPEED_STEP_RAD = 0.05  # the leading joint's step between the points where the tool's speed is measured [rad]


def _finite_tuple(values, name: str, positive: bool = False) -> None:
    if len(values) != NUM_JOINTS or not all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values
    ):
        raise ValueError(f"TrajectoryConfig.{name} must be {NUM_JOINTS} finite numbers, got {values!r}")
    if positive and any(v <= 0 for v in values):
        raise ValueError(f"TrajectoryConfig.{name} must all be > 0, got {values!r}")


@dataclass(frozen=True)
class TrajectoryConfig:
    """Limits of a planned joint trajectory.

    max_velocity_rad_s: per-joint speed limits [rad/s] (UR5e: pi, 180 deg/s, each).
    velocity_scale: fraction of the speed limits a plan may use, (0, 1].
    max_tool_speed_m_s: the flange's and the nozzle tip's speed limit [m/s], or None for none;
        default 1.5, the UR e-Series' default safety limit of the tool's speed. With it the
        joints may use their full speed: the long swings between the bin and the bolls
        run at the tool's limit, the short moves at the joints'.
    tool_length_m: the nozzle tip's distance from the flange along tool0's z [m] (the
        nozzle's length, ArmCollisionConfig's default).
    max_acceleration_rad_s2: per-joint acceleration limits [rad/s^2]; 10 rad/s^2 each, the
        top of what MoveIt's UR configurations use (5-10: the UR limits torques, not
        accelerations; the shoulder's 150 N m turn the stretched arm at about 20 rad/s^2).
        Against 6 rad/s^2 it cuts the moves between the bin and a boll from 1.74 to 1.59 s
        and the approach from 0.44 to 0.34 s (harvest_pick_contacts' plans, seed 0, lane 1).
    sample_rate_hz: rate of sampled() [Hz] (the simulator's physics runs at 200 Hz).
    lower_limits_rad, upper_limits_rad: joint position limits [rad]; a waypoint
        outside them is rejected.
    """

    max_velocity_rad_s: Tuple[float, ...] = UR5E_MAX_SPEED_RAD_S
    velocity_scale: float = 1.0
    max_tool_speed_m_s: Optional[float] = 1.5
    tool_length_m: float = ArmCollisionConfig.nozzle_length_m
    max_acceleration_rad_s2: Tuple[float, ...] = (10.0,) * NUM_JOINTS
    sample_rate_hz: float = 100.0
    lower_limits_rad: Tuple[float, ...] = UR5E_LOWER_LIMITS_RAD
    upper_limits_rad: Tuple[float, ...] = UR5E_UPPER_LIMITS_RAD

    def __post_init__(self) -> None:
        _finite_tuple(self.max_velocity_rad_s, "max_velocity_rad_s", positive=True)
        _finite_tuple(self.max_acceleration_rad_s2, "max_acceleration_rad_s2", positive=True)
        _finite_tuple(self.lower_limits_rad, "lower_limits_rad")
        _finite_tuple(self.upper_limits_rad, "upper_limits_rad")
        for name, lo, hi in zip(JOINT_NAMES, self.lower_limits_rad, self.upper_limits_rad):
            if lo >= hi:
                raise ValueError(f"TrajectoryConfig limits of {name}: lower {lo} must be below upper {hi}")
        scale = self.velocity_scale
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not (0.0 < scale <= 1.0):
            raise ValueError(f"TrajectoryConfig.velocity_scale must be in (0, 1], got {scale!r}")
        tool = self.max_tool_speed_m_s
        if tool is not None and (isinstance(tool, bool) or not isinstance(tool, (int, float))
                                 or not (0.0 < tool < math.inf)):
            raise ValueError(f"TrajectoryConfig.max_tool_speed_m_s must be a speed > 0 m/s or None (no limit), "
                             f"got {tool!r}")
        length = self.tool_length_m
        if isinstance(length, bool) or not isinstance(length, (int, float)) or not (0.0 <= length <= 1.0):
            raise ValueError(f"TrajectoryConfig.tool_length_m must be in [0, 1] m, got {length!r}")
        rate = self.sample_rate_hz
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not (0.0 < rate <= 10000.0):
            raise ValueError(f"TrajectoryConfig.sample_rate_hz must be in (0, 10000], got {rate!r}")

    @property
    def velocity_limits_rad_s(self) -> np.ndarray:
        """The speeds a plan uses: max_velocity_rad_s * velocity_scale [rad/s]."""
        return np.asarray(self.max_velocity_rad_s) * self.velocity_scale


def validate_waypoints(waypoints_rad, config: TrajectoryConfig) -> np.ndarray:
    """Waypoints as an (N, 6) float array; ValueError naming the waypoint and joint that is bad."""
    try:
        wp = np.array(waypoints_rad, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("waypoints must be a sequence of 6-joint configurations of numbers") from None
    if wp.ndim == 1 and wp.size == NUM_JOINTS:
        wp = wp[None, :]
    if wp.ndim != 2 or wp.shape[1] != NUM_JOINTS or wp.shape[0] < 1:
        raise ValueError(f"waypoints must have shape (N >= 1, {NUM_JOINTS}), got {wp.shape}")
    bad = ~np.isfinite(wp)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ValueError(f"waypoint {i}: {JOINT_NAMES[j]} is {wp[i, j]} (NaN or infinite)")
    lower, upper = np.asarray(config.lower_limits_rad), np.asarray(config.upper_limits_rad)
    outside = (wp < lower - 1e-9) | (wp > upper + 1e-9)
    if outside.any():
        i, j = np.argwhere(outside)[0]
        raise ValueError(
            f"waypoint {i}: {JOINT_NAMES[j]} = {wp[i, j]:.6f} rad is outside its limits "
            f"[{lower[j]:.6f}, {upper[j]:.6f}]"
        )
    return np.clip(wp, lower, upper)


def tool_speed_per_unit_m(start_rad: np.ndarray, delta_rad: np.ndarray, tool_length_m: float) -> float:
    """The largest speed of the flange and the nozzle tip on the straight joint segment start -> start + delta
    when its normalised parameter s in [0, 1] advances at 1/s [m]: the longest chord between points
    TOOL_SPEED_STEP_RAD of the leading joint apart (at least 8 of them), times their number."""
    steps = max(8, int(math.ceil(float(np.abs(delta_rad).max()) / TOOL_SPEED_STEP_RAD)))
    s = np.linspace(0.0, 1.0, steps + 1)[:, None]
    frames = link_frames(start_rad + s * delta_rad)[:, NUM_JOINTS]
    flange = frames[:, :3, 3]
    tip = flange + tool_length_m * frames[:, :3, 2]
    chords = np.maximum(np.linalg.norm(np.diff(flange, axis=0), axis=1), np.linalg.norm(np.diff(tip, axis=0), axis=1))
    return float(chords.max()) * steps


def _segment_profile(start: np.ndarray, delta: np.ndarray, vmax: np.ndarray, amax: np.ndarray,
                     config: TrajectoryConfig) -> Tuple[float, float, float]:
    """(duration [s], acceleration time [s], normalised acceleration [1/s^2]) of one segment."""
    dist = np.abs(delta)
    moving = dist > 0.0
    if not moving.any():
        return 0.0, 0.0, 0.0
    v = float(np.min(vmax[moving] / dist[moving]))
    if config.max_tool_speed_m_s is not None:
        tool_m = tool_speed_per_unit_m(start, delta, config.tool_length_m)
        if tool_m > 0.0:
            v = min(v, config.max_tool_speed_m_s / tool_m)
    a = float(np.min(amax[moving] / dist[moving]))
    if v * v / a <= 1.0:
        t_acc = v / a
        return 1.0 / v + t_acc, t_acc, a
    t_acc = math.sqrt(1.0 / a)
    return 2.0 * t_acc, t_acc, a


@dataclass(frozen=True)
class JointTrajectory:
    """A rest-to-rest trajectory through waypoints (see the module docstring).

    waypoints_rad: (N, 6); segment_durations_s: (N - 1,); start_times_s: (N,) the
    time the arm is at each waypoint. Evaluate with at(t) or sampled().
    """

    waypoints_rad: np.ndarray
    segment_durations_s: np.ndarray
    accel_times_s: np.ndarray
    accel_norm: np.ndarray
    sample_rate_hz: float

    @property
    def start_times_s(self) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(self.segment_durations_s)])

    @property
    def duration_s(self) -> float:
        return float(np.sum(self.segment_durations_s))

    def at(self, times_s) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions [rad], velocities [rad/s], accelerations [rad/s^2], each (K, 6), at times (K,)."""
        t = np.atleast_1d(np.asarray(times_s, dtype=float))
        if not np.all(np.isfinite(t)):
            raise ValueError("trajectory times must be finite")
        t = np.clip(t, 0.0, self.duration_s)
        wp = self.waypoints_rad
        if len(wp) == 1:
            zeros = np.zeros((t.size, NUM_JOINTS))
            return np.repeat(wp, t.size, axis=0), zeros, zeros.copy()
        starts = self.start_times_s
        seg = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(wp) - 2)
        tau = t - starts[seg]
        dur = self.segment_durations_s[seg]
        ta = self.accel_times_s[seg]
        a = self.accel_norm[seg]
        peak = a * ta
        rising = tau < ta
        falling = tau > dur - ta
        s = np.where(rising, 0.5 * a * tau ** 2, 0.5 * a * ta ** 2 + peak * (tau - ta))
        s = np.where(falling, 1.0 - 0.5 * a * (dur - tau) ** 2, s)
        sd = np.where(rising, a * tau, np.where(falling, a * (dur - tau), peak))
        sdd = np.where(rising, a, np.where(falling, -a, 0.0))
        s = np.where(dur > 0.0, np.clip(s, 0.0, 1.0), 1.0)
        delta = wp[seg + 1] - wp[seg]
        q = wp[seg] + s[:, None] * delta
        return q, sd[:, None] * delta, sdd[:, None] * delta

    def sampled(self) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Times (K,) at sample_rate_hz from 0, plus the exact end, and positions,
        velocities, accelerations (K, 6) there."""
        step = 1.0 / self.sample_rate_hz
        n = int(math.floor(self.duration_s / step + 1e-9))
        times = np.arange(n + 1) * step
        if self.duration_s - times[-1] > 1e-9:
            times = np.append(times, self.duration_s)
        q, qd, qdd = self.at(times)
        return times, q, qd, qdd


def plan_trajectory(waypoints_rad, config: TrajectoryConfig = TrajectoryConfig()) -> JointTrajectory:
    """Time the path through the waypoints (rest at each) within config's limits.

    ValueError names a malformed, NaN or out-of-limits waypoint.
    """
    wp = validate_waypoints(waypoints_rad, config)
    vmax = config.velocity_limits_rad_s
    amax = np.asarray(config.max_acceleration_rad_s2, dtype=float)
    profiles = [_segment_profile(a, b - a, vmax, amax, config) for a, b in zip(wp[:-1], wp[1:])]
    arr = np.array(profiles, dtype=float).reshape(-1, 3)
    return JointTrajectory(wp, arr[:, 0], arr[:, 1], arr[:, 2], float(config.sample_rate_hz))


def interpolate_path(waypoints_rad: np.ndarray, step_rad: float) -> np.ndarray:
    """Configurations along the straight joint-space segments between waypoints,
    no joint moving more than step_rad between neighbours; (K, 6), first and
    last waypoint included. This is the geometric path of a JointTrajectory."""
    wp = np.asarray(waypoints_rad, dtype=float)
    if wp.ndim != 2 or wp.shape[1] != NUM_JOINTS or len(wp) < 1:
        raise ValueError(f"a path must have shape (N >= 1, {NUM_JOINTS}), got {wp.shape}")
    if not np.all(np.isfinite(wp)):
        raise ValueError("the path contains NaN or infinity")
    if not (isinstance(step_rad, (int, float)) and math.isfinite(step_rad) and step_rad > 0.0):
        raise ValueError(f"step_rad must be a positive number of radians, got {step_rad!r}")
    pieces = [wp[:1]]
    for a, b in zip(wp[:-1], wp[1:]):
        n = max(1, int(math.ceil(np.max(np.abs(b - a)) / step_rad - 1e-12)))
        frac = np.arange(1, n + 1)[:, None] / n
        pieces.append(a + frac * (b - a))
    return np.concatenate(pieces)


def path_of(trajectory_or_waypoints) -> np.ndarray:
    """The waypoints of a JointTrajectory, or an (N, 6) array of waypoints as given."""
    if isinstance(trajectory_or_waypoints, JointTrajectory):
        return trajectory_or_waypoints.waypoints_rad
    return np.atleast_2d(np.asarray(trajectory_or_waypoints, dtype=float))


def concatenate(trajectories: Sequence[JointTrajectory]) -> JointTrajectory:
    """One trajectory that runs the given ones in turn (each must start where the last ended)."""
    if not trajectories:
        raise ValueError("nothing to concatenate")
    wp = [trajectories[0].waypoints_rad]
    parts = [(t.segment_durations_s, t.accel_times_s, t.accel_norm) for t in trajectories]
    for prev, nxt in zip(trajectories[:-1], trajectories[1:]):
        gap = np.max(np.abs(prev.waypoints_rad[-1] - nxt.waypoints_rad[0]))
        if gap > 1e-9:
            raise ValueError(f"trajectories do not join: a jump of {gap:.3g} rad")
        wp.append(nxt.waypoints_rad[1:])
    return JointTrajectory(
        np.concatenate(wp),
        np.concatenate([p[0] for p in parts]),
        np.concatenate([p[1] for p in parts]),
        np.concatenate([p[2] for p in parts]),
        trajectories[0].sample_rate_hz,
    )
