"""Sampling of an accepted joint trajectory, and the stop profile of a cancelled one.

Between two knots of a ``ValidTrajectory`` each joint follows the polynomial
that ros_control's joint_trajectory_controller uses for the data the knots
carry: quintic when both knots have velocities and accelerations, cubic
(Hermite) when both have velocities, linear otherwise. Before the first knot
the trajectory holds the first knot; after the last it holds the last, with
zero velocity.

``StopProfile``: a cancelled, preempted or aborted motion stops where it is,
smoothly: every joint brakes from its velocity at a constant deceleration and
holds where it comes to rest (a joint already at rest holds its position).
"""
from __future__ import annotations

import math
from typing import Tuple

import numpy as np

from cottonsim_world.robot.arm_goal import ValidTrajectory

Sample = Tuple[np.ndarray, np.ndarray, np.ndarray]   # positions [rad], velocities [rad/s], accelerations [rad/s^2]


def _segment(q0, v0, a0, q1, v1, a1, duration: float, tau: float) -> Sample:
    """One segment of length duration [s] at tau in [0, duration]; v/a NaN where not given."""
    has_v = not (np.isnan(v0).any() or np.isnan(v1).any())
    has_a = has_v and not (np.isnan(a0).any() or np.isnan(a1).any())
    T = duration
    if not has_v:
        s = tau / T
        velocity = (q1 - q0) / T
        return q0 + s * (q1 - q0), velocity, np.zeros_like(q0)
    if has_a:     # quintic: positions, velocities and accelerations at both ends
        c0, c1, c2 = q0, v0, 0.5 * a0
        T2, T3, T4, T5 = T * T, T ** 3, T ** 4, T ** 5
        c3 = (20 * (q1 - q0) - (8 * v1 + 12 * v0) * T - (3 * a0 - a1) * T2) / (2 * T3)
        c4 = (30 * (q0 - q1) + (14 * v1 + 16 * v0) * T + (3 * a0 - 2 * a1) * T2) / (2 * T4)
        c5 = (12 * (q1 - q0) - 6 * (v1 + v0) * T - (a0 - a1) * T2) / (2 * T5)
        coeffs = (c0, c1, c2, c3, c4, c5)
    else:         # cubic Hermite: positions and velocities at both ends
        c2 = (3 * (q1 - q0) - (2 * v0 + v1) * T) / (T * T)
        c3 = (2 * (q0 - q1) + (v0 + v1) * T) / (T ** 3)
        coeffs = (q0, v0, c2, c3)
    q = np.zeros_like(q0)
    qd = np.zeros_like(q0)
    qdd = np.zeros_like(q0)
    for power, c in enumerate(coeffs):
        q = q + c * tau ** power
        if power >= 1:
            qd = qd + power * c * tau ** (power - 1)
        if power >= 2:
            qdd = qdd + power * (power - 1) * c * tau ** (power - 2)
    return q, qd, qdd


def sample(trajectory: ValidTrajectory, time_s: float) -> Sample:
    """Desired positions, velocities and accelerations (each (6,)) at sim time time_s."""
    t = float(time_s)
    if not math.isfinite(t):
        raise ValueError(f"sample time must be finite, got {time_s!r}")
    times = trajectory.times_s
    if t <= times[0]:
        q = trajectory.positions[0].copy()
        v0 = trajectory.velocities[0]
        return q, np.where(np.isnan(v0), 0.0, v0), np.zeros_like(q)
    if t >= times[-1]:
        n = trajectory.positions.shape[1]
        return trajectory.positions[-1].copy(), np.zeros(n), np.zeros(n)
    k = int(np.searchsorted(times, t, side="right") - 1)
    P, V, A = trajectory.positions, trajectory.velocities, trajectory.accelerations
    return _segment(P[k], V[k], A[k], P[k + 1], V[k + 1], A[k + 1], times[k + 1] - times[k], t - times[k])


class StopProfile:
    """Braking from (positions, velocities) at start_s with deceleration_rad_s2 per joint, then holding."""

    def __init__(self, start_s: float, positions_rad: np.ndarray, velocities_rad_s: np.ndarray,
                 deceleration_rad_s2: float):
        if not (math.isfinite(deceleration_rad_s2) and deceleration_rad_s2 > 0.0):
            raise ValueError(f"deceleration_rad_s2 must be > 0, got {deceleration_rad_s2!r}")
        self.start_s = float(start_s)
        self.q0 = np.asarray(positions_rad, dtype=float).copy()
        self.v0 = np.asarray(velocities_rad_s, dtype=float).copy()
        self.decel = float(deceleration_rad_s2)
        self.stop_times_s = np.abs(self.v0) / self.decel
        self.rest_rad = self.q0 + self.v0 * self.stop_times_s - 0.5 * np.sign(self.v0) * self.decel \
            * self.stop_times_s ** 2

    @property
    def end_time_s(self) -> float:
        """When the last joint comes to rest [s sim time]."""
        return self.start_s + float(np.max(self.stop_times_s, initial=0.0))

    def sample(self, time_s: float) -> Sample:
        tau = np.minimum(max(float(time_s) - self.start_s, 0.0), self.stop_times_s)
        braking = tau < self.stop_times_s
        a = -np.sign(self.v0) * self.decel
        q = self.q0 + self.v0 * tau + 0.5 * a * tau ** 2
        qd = np.where(braking, self.v0 + a * tau, 0.0)
        return q, qd, np.where(braking, a, 0.0)
