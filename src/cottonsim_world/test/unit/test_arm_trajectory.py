"""Sampling of accepted trajectories and the stop profile (robot/arm_trajectory.py)."""
import numpy as np
import pytest

from cottonsim_world.robot.arm_goal import ValidTrajectory
from cottonsim_world.robot.arm_trajectory import StopProfile, sample

NAN6 = np.full(6, np.nan)


def trajectory(times, positions, velocities=None, accelerations=None):
    n = len(times)
    v = np.array(velocities, dtype=float) if velocities is not None else np.vstack([np.zeros(6)] + [NAN6] * (n - 1))
    a = np.array(accelerations, dtype=float) if accelerations is not None else np.vstack(
        [np.zeros(6)] + [NAN6] * (n - 1))
    return ValidTrajectory(np.array(times, dtype=float), np.array(positions, dtype=float), v, a,
                           np.full(6, np.inf), np.full(6, 0.01), np.full(6, 0.01), 0.5)


def test_positions_only_is_linear_and_holds_outside():
    traj = trajectory([1.0, 3.0], [np.zeros(6), np.arange(6.0)])
    q, v, a = sample(traj, 2.0)
    assert np.allclose(q, np.arange(6.0) / 2) and np.allclose(v, np.arange(6.0) / 2) and np.allclose(a, 0)
    q, v, _ = sample(traj, 0.0)
    assert np.allclose(q, 0) and np.allclose(v, 0)
    q, v, _ = sample(traj, 5.0)
    assert np.allclose(q, np.arange(6.0)) and np.allclose(v, 0)


def _finite_difference_check(traj, order):
    t = np.linspace(traj.times_s[0] + 1e-4, traj.times_s[-1] - 1e-4, 1501)
    q = np.array([sample(traj, ti)[0] for ti in t])
    v = np.array([sample(traj, ti)[1] for ti in t])
    a = np.array([sample(traj, ti)[2] for ti in t])
    dt = t[1] - t[0]
    # central differences, away from the ends and the knots (where the cubic's acceleration jumps)
    inside = np.min(np.abs(t[:, None] - traj.times_s[None, :]), axis=1) > 2 * dt
    assert np.allclose(np.gradient(q, dt, axis=0)[inside], v[inside], atol=1e-3)
    assert np.allclose(np.gradient(v, dt, axis=0)[inside], a[inside], atol=1e-2)


@pytest.mark.parametrize("with_acc", [False, True])
def test_cubic_and_quintic_meet_their_knots(with_acc):
    rng = np.random.default_rng(3)
    P = rng.uniform(-1, 1, (4, 6))
    V = rng.uniform(-0.5, 0.5, (4, 6))
    A = rng.uniform(-1, 1, (4, 6)) if with_acc else None
    times = [0.0, 1.0, 2.5, 3.0]
    traj = trajectory(times, P, V, A)
    for k, t in enumerate(times[1:-1], start=1):    # inside: both segments agree on the knot
        for eps in (-1e-9, 1e-9):
            q, v, a = sample(traj, t + eps)
            assert np.allclose(q, P[k], atol=1e-6) and np.allclose(v, V[k], atol=1e-6)
            if with_acc:
                assert np.allclose(a, A[k], atol=1e-5)
    _finite_difference_check(traj, 5 if with_acc else 3)


def test_stop_profile_brakes_each_joint_to_rest_where_it_is():
    v0 = np.array([1.0, -2.0, 0.0, 0.5, 0.0, -0.1])
    q0 = np.arange(6.0)
    stop = StopProfile(4.0, q0, v0, deceleration_rad_s2=5.0)
    assert stop.end_time_s == pytest.approx(4.4)
    q, v, a = stop.sample(4.0)
    assert np.allclose(q, q0) and np.allclose(v, v0)
    q, v, a = stop.sample(4.2)
    assert v[0] == pytest.approx(0.0) and v[1] == pytest.approx(-1.0) and a[1] == pytest.approx(5.0)
    q, v, a = stop.sample(10.0)
    assert np.allclose(v, 0) and np.allclose(a, 0)
    assert np.allclose(q, q0 + v0 * np.abs(v0) / (2 * 5.0))      # braking distance v^2 / 2a
    with pytest.raises(ValueError, match="deceleration_rad_s2"):
        StopProfile(0.0, q0, v0, 0.0)
