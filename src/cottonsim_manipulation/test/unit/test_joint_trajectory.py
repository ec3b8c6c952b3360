"""Timed joint trajectories: limits at every sample, synchronised joints, validation."""
import math

import numpy as np
import pytest

from cottonsim_common.kinematics.ur5e import link_frames
from cottonsim_common.testing import assert_config_rejects
from cottonsim_manipulation.planning.trajectory import (
    JointTrajectory,
    TrajectoryConfig,
    concatenate,
    interpolate_path,
    plan_trajectory,
    tool_speed_per_unit_m,
)

PI = math.pi


def random_waypoints(rng, n):
    lower = np.array([-2 * PI, -2 * PI, -PI, -2 * PI, -2 * PI, -2 * PI])
    return rng.uniform(lower, -lower, (n, 6))


def finite_difference_limits(traj):
    times, q, qd, qdd = traj.sampled()
    dt = np.diff(times)
    vel = np.diff(q, axis=0) / dt[:, None]
    # Second differences on the (uniform) interior of the sampling.
    uniform = np.abs(dt[1:] - dt[:-1]) < 1e-12
    acc = (q[2:] - 2 * q[1:-1] + q[:-2])[uniform] / (dt[1:][uniform] ** 2)[:, None]
    return times, q, qd, qdd, vel, acc


@pytest.mark.parametrize("seed", range(6))
def test_limits_hold_at_every_sample(seed):
    rng = np.random.default_rng(seed)
    cfg = TrajectoryConfig(velocity_scale=rng.uniform(0.2, 1.0),
                           max_acceleration_rad_s2=tuple(rng.uniform(1.0, 8.0, 6)), sample_rate_hz=250.0)
    wp = random_waypoints(rng, 5)
    wp[2] = wp[1] + rng.uniform(-0.05, 0.05, 6)       # a short segment: triangular profile
    traj = plan_trajectory(wp, cfg)
    times, q, qd, qdd, vel, acc = finite_difference_limits(traj)
    vmax = np.array(cfg.max_velocity_rad_s) * cfg.velocity_scale
    amax = np.array(cfg.max_acceleration_rad_s2)
    assert np.all(np.abs(vel) <= vmax * (1 + 1e-9))
    assert np.all(np.abs(acc) <= amax * (1 + 1e-6))
    assert np.all(np.abs(qd) <= vmax * (1 + 1e-9))
    assert np.all(np.abs(qdd) <= amax * (1 + 1e-9))
    # Starts and ends at the first and last waypoint, at rest; passes every waypoint.
    np.testing.assert_allclose(q[0], wp[0], atol=1e-12)
    np.testing.assert_allclose(q[-1], wp[-1], atol=1e-12)
    np.testing.assert_allclose(qd[[0, -1]], 0.0, atol=1e-12)
    at_wp, v_wp, _ = traj.at(traj.start_times_s)
    np.testing.assert_allclose(at_wp, wp, atol=1e-9)
    np.testing.assert_allclose(v_wp, 0.0, atol=1e-9)
    # The reported velocity is the derivative of the position.
    mid = 0.5 * (times[1:] + times[:-1])
    np.testing.assert_allclose(traj.at(mid)[1], vel, atol=amax.max() / cfg.sample_rate_hz)


def test_each_segment_is_time_optimal_for_its_slowest_joint():
    cfg = TrajectoryConfig(velocity_scale=0.5, max_acceleration_rad_s2=(4.0,) * 6, max_tool_speed_m_s=None)
    v, a = 0.5 * PI, 4.0
    # Long move: trapezoid, T = D / v + v / a for the joint with the largest distance.
    traj = plan_trajectory([[0.0] * 6, [2.0, 1.0, 0, 0, 0, -0.5]], cfg)
    assert traj.duration_s == pytest.approx(2.0 / v + v / a)
    times, q, qd, _ = traj.sampled()
    assert np.abs(qd[:, 0]).max() == pytest.approx(v, rel=1e-9)
    # Short move: triangle, T = 2 sqrt(D / a).
    short = plan_trajectory([[0.0] * 6, [0.1, 0, 0, 0, 0, 0]], cfg)
    assert short.duration_s == pytest.approx(2 * math.sqrt(0.1 / a))


def tool_speeds_m_s(traj, tool_length_m):
    """Finite-difference speeds of the flange and the nozzle tip at the trajectory's samples [m/s]."""
    times, q, _, _ = traj.sampled()
    frames = link_frames(q)[:, 6]
    flange = frames[:, :3, 3]
    tip = flange + tool_length_m * frames[:, :3, 2]
    dt = np.diff(times)[:, None]
    return (np.linalg.norm(np.diff(flange, axis=0) / dt, axis=1),
            np.linalg.norm(np.diff(tip, axis=0) / dt, axis=1))


def test_the_tool_speed_limit_holds_and_a_long_swing_reaches_it():
    cfg = TrajectoryConfig(sample_rate_hz=500.0)
    # The shoulder swung half a turn with the arm stretched out: the joints alone would move the tip at ~2.8 m/s.
    stretched = [0.0, -0.3, 0.3, -1.57, -1.57, 0.0]
    swing = plan_trajectory([stretched, [3.0] + stretched[1:]], cfg)
    flange, tip = tool_speeds_m_s(swing, cfg.tool_length_m)
    fastest = max(flange.max(), tip.max())
    assert fastest <= cfg.max_tool_speed_m_s * 1.002
    assert fastest >= cfg.max_tool_speed_m_s * 0.99            # the limit binds: no slower than it must be
    unlimited = plan_trajectory([stretched, [3.0] + stretched[1:]], TrajectoryConfig(max_tool_speed_m_s=None))
    assert swing.duration_s > unlimited.duration_s + 0.5
    # Random moves over the workspace keep the limit at every sample.
    rng = np.random.default_rng(11)
    traj = plan_trajectory(random_waypoints(rng, 6), cfg)
    flange, tip = tool_speeds_m_s(traj, cfg.tool_length_m)
    assert max(flange.max(), tip.max()) <= cfg.max_tool_speed_m_s * 1.002


def test_a_turn_of_the_last_wrist_joint_runs_at_the_joint_limit():
    # wrist 3 turns the nozzle about its own axis: neither the flange nor the tip moves.
    q0 = np.array([0.0, -1.2, 1.2, -1.57, -1.57, 0.0])
    q1 = q0 + np.array([0, 0, 0, 0, 0, 2.0])
    assert tool_speed_per_unit_m(q0, q1 - q0, 0.15) < 1e-9
    cfg = TrajectoryConfig()
    assert plan_trajectory([q0, q1], cfg).duration_s == pytest.approx(
        plan_trajectory([q0, q1], TrajectoryConfig(max_tool_speed_m_s=None)).duration_s)


def test_joints_move_in_step_on_the_straight_segment():
    rng = np.random.default_rng(3)
    wp = random_waypoints(rng, 2)
    traj = plan_trajectory(wp)
    times, q, _, _ = traj.sampled()
    frac = (q - wp[0]) / (wp[1] - wp[0])
    # Every joint has covered the same fraction of its distance at every sample.
    np.testing.assert_allclose(frac, np.repeat(frac[:, :1], 6, axis=1), atol=1e-9)
    assert np.all(np.diff(frac[:, 0]) >= -1e-12)


def test_repeated_and_single_waypoints():
    wp = [[0.1] * 6, [0.1] * 6, [0.3] * 6]
    traj = plan_trajectory(wp)
    assert traj.segment_durations_s[0] == 0.0 and traj.segment_durations_s[1] > 0
    times, q, _, _ = traj.sampled()
    np.testing.assert_allclose(q[-1], [0.3] * 6)
    still = plan_trajectory([[0.2] * 6])
    assert still.duration_s == 0.0
    times, q, qd, _ = still.sampled()
    assert len(times) == 1 and np.all(q == 0.2) and np.all(qd == 0.0)


def test_bad_waypoints_are_named():
    with pytest.raises(ValueError, match=r"waypoint 1: elbow_joint is nan"):
        plan_trajectory([[0] * 6, [0, 0, np.nan, 0, 0, 0]])
    with pytest.raises(ValueError, match=r"waypoint 0: elbow_joint = 3.500000 rad is outside its limits"):
        plan_trajectory([[0, 0, 3.5, 0, 0, 0]])
    with pytest.raises(ValueError, match=r"shape"):
        plan_trajectory([[0, 0, 0]])
    with pytest.raises(ValueError, match=r"shape"):
        plan_trajectory(np.zeros((0, 6)))
    with pytest.raises(ValueError, match="sequence"):
        plan_trajectory([["a"] * 6])


def test_config_is_validated():
    assert_config_rejects(TrajectoryConfig, ("velocity_scale", 0.0), ("velocity_scale", 1.5),
                          ("max_acceleration_rad_s2", (4.0,) * 5 + (-1.0,)),
                          ("max_velocity_rad_s", (float("nan"),) * 6), ("sample_rate_hz", 0),
                          ("max_tool_speed_m_s", 0.0), ("max_tool_speed_m_s", float("inf")), ("tool_length_m", -0.1))
    with pytest.raises(ValueError, match="lower"):
        TrajectoryConfig(lower_limits_rad=(1.0,) * 6, upper_limits_rad=(0.0,) * 6)


def test_interpolate_path_and_concatenate():
    wp = np.array([[0.0] * 6, [0.25, 0, 0, 0, 0, -0.1], [0.25, 0, 0, 0, 0, -0.1]])
    path = interpolate_path(wp, 0.1)
    assert np.abs(np.diff(path, axis=0)).max() <= 0.1 + 1e-12
    np.testing.assert_allclose(path[[0, -1]], wp[[0, -1]])
    with pytest.raises(ValueError, match="step_rad"):
        interpolate_path(wp, 0.0)
    a = plan_trajectory(wp[:2])
    b = plan_trajectory([wp[1], [0.0] * 6])
    both = concatenate([a, b])
    assert isinstance(both, JointTrajectory)
    assert both.duration_s == pytest.approx(a.duration_s + b.duration_s)
    np.testing.assert_allclose(both.at([a.duration_s + b.duration_s])[0][0], 0.0)
    with pytest.raises(ValueError, match="do not join"):
        concatenate([a, a])
