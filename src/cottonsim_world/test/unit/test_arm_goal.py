"""Validation of FollowJointTrajectory goals (robot/arm_goal.py): accepted goals and the reasons for rejections."""
import math

import numpy as np
import pytest

from cottonsim_world.robot.arm_goal import (INVALID_GOAL, INVALID_JOINTS, OLD_HEADER_TIMESTAMP, ArmLimits, GoalDefaults,
                                            GoalRejected, JointToleranceSpec, TrajectoryGoal, TrajectoryPoint,
                                            validate_goal)

NAMES = tuple("ur5e_" + n for n in ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                                    "wrist_2_joint", "wrist_3_joint"))
LIMITS = ArmLimits(NAMES, np.array([-2 * math.pi, -2 * math.pi, -math.pi, -2 * math.pi, -2 * math.pi, -2 * math.pi]),
                   np.array([2 * math.pi, 2 * math.pi, math.pi, 2 * math.pi, 2 * math.pi, 2 * math.pi]),
                   np.full(6, math.pi))
DEFAULTS = GoalDefaults(goal_position_tolerance_rad=0.01, goal_velocity_tolerance_rad_s=0.01,
                        path_position_tolerance_rad=math.inf, goal_time_tolerance_s=0.5, start_tolerance_rad=0.02)
HOME = np.array([0.0, -2.2, 2.4, -1.77, -1.57, 0.0])


def goal(points, names=NAMES, **kw):
    return TrajectoryGoal(tuple(names), tuple(points), **kw)


def point(q, t, v=(), a=()):
    return TrajectoryPoint(tuple(q), tuple(v), tuple(a), t)


def validate(g, now=10.0, current=HOME):
    return validate_goal(g, LIMITS, now, current, np.zeros(6), DEFAULTS)


def rejected(g, now=10.0, current=HOME):
    with pytest.raises(GoalRejected) as info:
        validate(g, now, current)
    return info.value


def test_valid_goal_in_any_joint_order_starts_now_at_the_current_state():
    target = HOME + [0.5, 0.2, -0.3, 0.1, 0.0, 1.0]
    order = [2, 0, 5, 1, 4, 3]
    g = goal([point(HOME[order], 0.0), point(((HOME + target) / 2)[order], 1.0), point(target[order], 2.0)],
             names=[NAMES[i] for i in order])
    traj = validate(g, now=10.0)
    # the point at the start time equals the current state: dropped; the current state is the first knot
    assert np.allclose(traj.times_s, [10.0, 11.0, 12.0])
    assert np.allclose(traj.positions[0], HOME) and np.allclose(traj.positions[-1], target)
    assert np.all(np.isnan(traj.velocities[1:])) and np.allclose(traj.velocities[0], 0.0)
    assert np.allclose(traj.goal_tolerance_rad, 0.01) and np.all(np.isinf(traj.path_tolerance_rad))
    assert traj.goal_time_tolerance_s == 0.5 and traj.end_time_s == 12.0


@pytest.mark.parametrize("names, words", [
    ((), "names no joints"),
    (NAMES[:5] + ("ur5e_elbow_joint",), "more than once"),
    (NAMES[:5] + ("gripper_joint",), "unknown joints ['gripper_joint']"),
    (NAMES[:5], "lacks joints ['ur5e_wrist_3_joint']"),
])
def test_joint_name_problems_are_invalid_joints(names, words):
    err = rejected(goal([point(HOME[:len(names)], 1.0)], names=names))
    assert err.error_code == INVALID_JOINTS and words in err.reason


@pytest.mark.parametrize("make, words", [
    (lambda: goal([]), "no points"),
    (lambda: goal([point(HOME[:5], 1.0)]), "has 5 values for 6 joint names"),
    (lambda: goal([point(HOME + [0, 0, math.nan, 0, 0, 0], 1.0)]), "point 0 position of ur5e_elbow_joint is nan"),
    (lambda: goal([point(HOME + [math.inf, 0, 0, 0, 0, 0], 1.0)]), "position of ur5e_shoulder_pan_joint is inf"),
    (lambda: goal([point(HOME, 1.0, v=[0, 0, 0, 0, math.nan, 0])]), "velocity of ur5e_wrist_2_joint is nan"),
    (lambda: goal([point(HOME, math.nan)]), "time_from_start is nan"),
    (lambda: goal([point(HOME, -1.0)]), "is negative"),
    (lambda: goal([point(HOME, 1.0), point(HOME, 1.0)]), "point 1 time_from_start 1.0 s is not after point 0"),
    (lambda: goal([point(HOME, 2.0), point(HOME, 1.0)]), "times must increase"),
    (lambda: goal([point(HOME, 1.0, a=[0] * 6)]), "accelerations but no velocities"),
    (lambda: goal([point(HOME + [0, 0, 1.0, 0, 0, 0], 1.0)]), "ur5e_elbow_joint = 3.4 rad is outside its limits"),
    (lambda: goal([point(HOME, 1.0, v=[0, 0, 0, 3.5, 0, 0])]), "ur5e_wrist_1_joint velocity 3.5 rad/s is over"),
    (lambda: goal([point(HOME + [2.0, 0, 0, 0, 0, 0], 0.5)]), "ur5e_shoulder_pan_joint must move 4 rad/s on average "
                                                             "from the current position to point 0"),
    (lambda: goal([point(HOME, 1.0), point(HOME + [0, 0, 0, 0, 0, 1.0], 1.1)]), "from point 0 to point 1"),
    (lambda: goal([point(HOME + [0.1, 0, 0, 0, 0, 0], 0.0), point(HOME, 1.0)]), "a jump"),
    (lambda: goal([point(HOME, 1.0)], goal_time_tolerance_s=-1.0), "goal_time_tolerance -1.0 s is negative"),
    (lambda: goal([point(HOME, 1.0)], goal_tolerance=(JointToleranceSpec(NAMES[0], math.nan),)), "is nan"),
])
def test_bad_goals_are_invalid_goal_with_their_reason(make, words):
    err = rejected(make())
    assert err.error_code == INVALID_GOAL and words in err.reason, err.reason


def test_tolerance_for_an_unknown_joint_is_invalid_joints():
    err = rejected(goal([point(HOME, 1.0)], path_tolerance=(JointToleranceSpec("gripper", 0.1),)))
    assert err.error_code == INVALID_JOINTS and "'gripper'" in err.reason


def test_stamps_in_the_past_drop_past_points_or_are_too_old():
    g = goal([point(HOME, 1.0), point(HOME + 0.1, 2.0)], start_time_s=8.5)     # points at 9.5 and 10.5 s
    traj = validate(g, now=10.0)
    assert np.allclose(traj.times_s, [10.0, 10.5]) and np.allclose(traj.positions[-1], HOME + 0.1)
    err = rejected(goal([point(HOME, 1.0)], start_time_s=5.0), now=10.0)
    assert err.error_code == OLD_HEADER_TIMESTAMP and "too old" in err.reason
    future = validate(goal([point(HOME + 0.1, 1.0)], start_time_s=12.0), now=10.0)
    assert np.allclose(future.times_s, [10.0, 13.0])


def test_tolerances_follow_control_msgs_conventions():
    specs = (JointToleranceSpec(NAMES[0], 0.05, 0.2), JointToleranceSpec(NAMES[1], -1.0, -1.0),
             JointToleranceSpec(NAMES[2], 0.0))
    traj = validate(goal([point(HOME, 1.0)], goal_tolerance=specs, path_tolerance=specs[:1],
                         goal_time_tolerance_s=2.0))
    assert traj.goal_tolerance_rad[0] == 0.05 and math.isinf(traj.goal_tolerance_rad[1])
    assert traj.goal_tolerance_rad[2] == 0.01         # 0 = the default
    assert traj.goal_velocity_tolerance_rad_s[0] == 0.2 and math.isinf(traj.goal_velocity_tolerance_rad_s[1])
    assert traj.path_tolerance_rad[0] == 0.05 and math.isinf(traj.path_tolerance_rad[1])
    assert traj.goal_time_tolerance_s == 2.0
