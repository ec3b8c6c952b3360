import math

import numpy as np
import pytest

from cottonsim_world.driving.pure_pursuit import PurePursuit, PurePursuitConfig, densify


def drive(path, pose, steps=4000, dt=0.05):
    follower = PurePursuit(np.array(path))
    x, y, yaw = pose
    trace = []
    for _ in range(steps):
        v, w = follower.command(x, y, yaw)
        if follower.done:
            break
        x += v * math.cos(yaw) * dt
        y += v * math.sin(yaw) * dt
        yaw += w * dt
        trace.append((x, y))
    return follower, np.array(trace)


def test_follows_a_straight_line_from_an_offset_start():
    follower, trace = drive([(0, 0), (10, 0)], (0.0, 0.3, 0.0))
    assert follower.done
    assert abs(trace[-1, 0] - 10) < 0.2
    assert np.abs(trace[trace[:, 0] > 4, 1]).max() < 0.03   # converged onto the line


def test_serpentine_does_not_jump_lanes():
    lane_pitch = 1.8
    path = [(0, 0), (0, 10), (-lane_pitch, 10), (-lane_pitch, 0)]
    follower, trace = drive(path, (0.0, 0.0, math.pi / 2))
    assert follower.done
    # While going north on lane 0 the robot stays on lane 0 (x ~ 0), never cutting over.
    north = trace[(trace[:, 1] > 1) & (trace[:, 1] < 8) & (np.arange(len(trace)) < len(trace) // 2)]
    assert np.abs(north[:, 0]).max() < 0.05
    assert np.linalg.norm(trace[-1] - np.array(path[-1])) < 0.2


def test_turns_in_place_when_target_is_behind():
    follower = PurePursuit(np.array([(0, 0), (-5, 0)]))
    v, w = follower.command(0.0, 0.0, 0.0)
    assert v == 0.0 and abs(w) == pytest.approx(PurePursuitConfig().max_angular_rad_s)


def test_nan_pose_stops_the_robot():
    follower = PurePursuit(np.array([(0, 0), (5, 0)]))
    assert follower.command(float("nan"), 0.0, 0.0) == (0.0, 0.0)


def test_bad_config_names_the_parameter():
    with pytest.raises(ValueError, match="lookahead_m"):
        PurePursuitConfig(lookahead_m=-1.0)


def test_densify_spacing():
    pts = densify(np.array([(0, 0), (1, 0)]), 0.1)
    assert len(pts) == 11
    assert np.allclose(np.diff(pts[:, 0]), 0.1)
    with pytest.raises(ValueError):
        densify(np.array([(0, 0)]))
