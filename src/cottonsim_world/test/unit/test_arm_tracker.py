"""The simulated arm controller (robot/arm_tracker.py): tracking, goal and path tolerances, cancel, preemption."""
import math
import pathlib

import numpy as np
import pytest

from cottonsim_world.robot.arm_goal import (GOAL_TOLERANCE_VIOLATED, PATH_TOLERANCE_VIOLATED, SUCCESSFUL,
                                            JointToleranceSpec, TrajectoryGoal, TrajectoryPoint, validate_goal)
from cottonsim_world.robot.arm_tracker import ArmControllerConfig, ArmTrajectoryTracker
from cottonsim_world.robot.sim_arm import SimulatedArm
from cottonsim_world.robot.ur5e import Ur5eArm
from cottonsim_world.robot.urdf_model import UrdfModel

URDF = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"
HOME = np.array([0.0, -2.2, 2.4, -1.77, -1.57, 0.0])
TARGET = HOME + np.array([1.2, 0.5, -0.8, 0.3, 0.4, -1.0])
DT = 0.005      # the physics step


@pytest.fixture
def arm():
    return Ur5eArm.from_urdf(UrdfModel.from_file(URDF), "ur5e_", initial_positions=HOME)


def names():
    return tuple("ur5e_" + n for n in ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                                       "wrist_2_joint", "wrist_3_joint"))


def limits_of(arm):
    from cottonsim_world.robot.arm_goal import ArmLimits
    return ArmLimits(names(), np.array([lim.lower for lim in arm.limits]), np.array([lim.upper for lim in arm.limits]),
                     np.array([lim.velocity for lim in arm.limits]))


def plan(arm, tracker, now, points, **kw):
    goal = TrajectoryGoal(names(), tuple(TrajectoryPoint(tuple(q), tuple(v), (), t) for q, v, t in points), **kw)
    return validate_goal(goal, limits_of(arm), now, arm.positions, arm.velocities, tracker.config.goal_defaults())


def run(tracker, t0, duration, log=None):
    """Step at the physics rate from t0 for duration; returns the end time and the outcomes."""
    outcomes, t = [], t0
    for _ in range(int(round(duration / DT))):
        t += DT
        tracker.step(t, DT)
        outcomes += tracker.take_outcomes()
        if log is not None:
            log.append((t, tracker.arm.positions, tracker.arm.velocities))
    return t, outcomes


def test_a_goal_is_tracked_within_the_limits_and_succeeds_at_its_end(arm):
    tracker = ArmTrajectoryTracker(arm, ArmControllerConfig())
    mid = (HOME + TARGET) / 2
    tracker.accept("g1", plan(arm, tracker, 0.0, [(mid, (TARGET - HOME) / 2.0, 1.0), (TARGET, np.zeros(6), 2.0)]))
    log = []
    t, outcomes = run(tracker, 0.0, 2.6, log)
    assert [(o.goal_id, o.status, o.error_code) for o in outcomes] == [("g1", "succeeded", SUCCESSFUL)]
    q = np.array([p for _, p, _ in log])
    v = np.array([v for _, _, v in log])
    assert np.all(np.abs(v) <= math.pi + 1e-9)                                   # speed limit
    assert np.all(np.abs(np.diff(v, axis=0)) <= 15.0 * DT + 1e-9)              # acceleration limit: no jumps
    assert np.max(np.abs(q[-1] - TARGET)) < 0.01
    # it tracks (a small lag), it does not teleport: half-way it is near the middle point
    half = q[int(round(1.0 / DT)) - 1]
    assert 1e-4 < np.max(np.abs(half - mid)) < 0.05
    assert not tracker.busy        # at rest after the hold, the follower holds the final position
    assert np.allclose(arm.targets, q[-1]) and np.max(np.abs(arm.velocities)) == 0.0


def test_cancel_brakes_to_rest_where_it_is_and_then_ends_the_goal(arm):
    cfg = ArmControllerConfig(stop_deceleration_rad_s2=6.0)
    tracker = ArmTrajectoryTracker(arm, cfg)
    tracker.accept("g", plan(arm, tracker, 0.0, [(TARGET, np.zeros(6), 2.0)]))
    t, outcomes = run(tracker, 0.0, 0.8)
    assert outcomes == [] and tracker.active_goal == "g"
    q_cancel, v_cancel = arm.positions, arm.velocities
    assert np.max(np.abs(v_cancel)) > 0.3
    assert tracker.cancel("g", t) and not tracker.cancel("other", t)
    log = []
    t_end, outcomes = run(tracker, t, 1.5, log)
    assert [(o.status, o.error_code) for o in outcomes] == [("canceled", SUCCESSFUL)]
    ended = next(i for i, (ti, _, _) in enumerate(log) if ti >= t + 0.3)      # v / a = at most ~0.3 s of braking
    q_rest = log[-1][1]
    assert np.max(np.abs(log[ended][2])) < 0.05 and np.max(np.abs(log[-1][2])) < 1e-4
    braking = v_cancel ** 2 / (2 * cfg.stop_deceleration_rad_s2)
    assert np.all(np.abs(q_rest - q_cancel) <= braking + 0.03)      # stopped where it was, not at the goal
    assert np.max(np.abs(q_rest - TARGET)) > 0.3
    run(tracker, t_end, 1.0)
    assert np.allclose(arm.positions, q_rest, atol=1e-6) and not tracker.busy    # and stays
    assert np.max(np.abs(arm.velocities)) == 0.0


def test_a_new_goal_preempts_and_continues_from_the_current_state(arm):
    tracker = ArmTrajectoryTracker(arm, ArmControllerConfig())
    tracker.accept("first", plan(arm, tracker, 0.0, [(TARGET, np.zeros(6), 2.0)]))
    t, _ = run(tracker, 0.0, 0.7)
    tracker.accept("second", plan(arm, tracker, t, [(HOME, np.zeros(6), 2.0)]))
    assert [(o.goal_id, o.status) for o in tracker.take_outcomes()] == [("first", "preempted")]
    log = []
    _, outcomes = run(tracker, t, 2.6, log)
    assert [(o.goal_id, o.status) for o in outcomes] == [("second", "succeeded")]
    v = np.array([v for _, _, v in log])
    assert np.all(np.abs(np.diff(v, axis=0)) <= 15.0 * DT + 1e-9)
    assert np.max(np.abs(arm.positions - HOME)) < 0.01


def test_path_tolerance_violation_aborts_and_stops(arm):
    tracker = ArmTrajectoryTracker(arm, ArmControllerConfig())
    tight = tuple(JointToleranceSpec(n, 1e-4) for n in names())
    tracker.accept("g", plan(arm, tracker, 0.0, [(TARGET, (), 2.0)], path_tolerance=tight))
    _, outcomes = run(tracker, 0.0, 1.0)
    assert [(o.status, o.error_code) for o in outcomes] == [("aborted", PATH_TOLERANCE_VIOLATED)]
    assert "path tolerance" in outcomes[0].error_string
    assert np.max(np.abs(arm.velocities)) < 1e-3 and np.max(np.abs(arm.positions - TARGET)) > 0.5


def test_goal_tolerance_violation_after_the_goal_time_tolerance(arm):
    tracker = ArmTrajectoryTracker(arm, ArmControllerConfig())
    strict = tuple(JointToleranceSpec(n, 1e-6) for n in names())
    # positions only: a linear segment arrives at speed, the servos lag by ~ v / gain when it ends
    tracker.accept("g", plan(arm, tracker, 0.0, [(TARGET, (), 2.0)], goal_tolerance=strict,
                             goal_time_tolerance_s=0.01))
    _, outcomes = run(tracker, 0.0, 2.5)
    assert [(o.status, o.error_code) for o in outcomes] == [("aborted", GOAL_TOLERANCE_VIOLATED)]
    assert "from its goal" in outcomes[0].error_string


def test_a_position_command_supersedes_a_goal():
    sim_arm = SimulatedArm(UrdfModel.from_file(URDF), "ur5e_", HOME, ArmControllerConfig(), _vacuum_config(),
                           _no_bolls())
    goal = TrajectoryGoal(names(), (TrajectoryPoint(tuple(TARGET), (), (), 2.0),))
    sim_arm.accept_goal("g", goal, 0.0)
    for k in range(40):
        sim_arm.step((k + 1) * DT, DT, lambda: np.eye(4))
    sim_arm.command_positions(HOME)
    outcomes = sim_arm.tracker.take_outcomes()
    assert [(o.goal_id, o.status) for o in outcomes] == [("g", "aborted")]
    assert "/arm_controller/command" in outcomes[0].error_string
    for k in range(300):
        sim_arm.step(0.2 + (k + 1) * DT, DT, lambda: np.eye(4))
    assert np.allclose(sim_arm.arm.positions, HOME)


def test_config_keys_are_validated_by_name():
    with pytest.raises(ValueError, match="servo_gain_1_s"):
        ArmControllerConfig(servo_gain_1_s=0.0)
    with pytest.raises(ValueError, match="goal_time_tolerance_s"):
        ArmControllerConfig(goal_time_tolerance_s=math.nan)


def _vacuum_config():
    from cottonsim_world.robot.vacuum import VacuumConfig
    return VacuumConfig()


def _no_bolls():
    from cottonsim_world.robot.boll_store import BollFieldStore
    return BollFieldStore.of_plants([])
