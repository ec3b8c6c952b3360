"""move_base gives up on goals it cannot reach: blocked goals, blocked plans and a robot that makes no progress."""
import numpy as np

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.move_base.config import MoveBaseConfig
from cottonsim_navigation.move_base.goal_checks import blocked_goal_reason, plan_blocked_at
from cottonsim_navigation.move_base.state_machine import MoveBase, MoveBaseState, Outcome, RecoveryTrigger

from move_base_fakes import DT, CountingRecovery, FakeGlobal, FakeLocal, empty_costmaps, run


def mark(costmap, *points_xy):
    """An observation from the origin marking these points as obstacles (one stem each)."""
    pts = np.array([[x, y, 0.5] for x, y in points_xy])
    costmap.obstacle_layer.add_observation(pts, (0.0, 0.0, 0.5))
    costmap.update_map(Pose2D(0, 0, 0))


def test_goal_on_a_stem_and_next_to_one_is_blocked_but_a_goal_beside_the_row_is_not():
    glob, _ = empty_costmaps(obstacle_layer_in_global=True)
    mark(glob, (2.0, 0.0))
    r_in = glob.inscribed_radius_m                                  # 0.365 m: the padded Husky's half width
    assert "in or next to an obstacle" in blocked_goal_reason(glob, Pose2D(2.0, 0.0, 0.0), 0.1)
    assert "in or next to an obstacle" in blocked_goal_reason(glob, Pose2D(2.0, 0.25, 0.0), 0.0)
    assert blocked_goal_reason(glob, Pose2D(2.0, r_in + 0.1, 0.0), 0.0) == ""
    # a tolerance that reaches a free cell makes the goal reachable
    assert blocked_goal_reason(glob, Pose2D(2.0, 0.25, 0.0), 0.25) == ""
    assert "off the global costmap" in blocked_goal_reason(glob, Pose2D(50.0, 0.0, 0.0), 0.1)


def test_goal_on_a_stem_is_aborted_after_planner_patience_without_clearing_recoveries():
    glob, local = empty_costmaps(obstacle_layer_in_global=True)
    mark(glob, (2.0, 0.0))
    log = []
    mb = MoveBase(MoveBaseConfig(planner_patience=2.0), glob, local, FakeGlobal(fail=True), FakeLocal(),
                  recoveries=[CountingRecovery("a", log)])
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    results, t_end = run(mb, 100)
    assert results[-1].outcome == Outcome.ABORTED
    assert "in or next to an obstacle" in results[-1].reason and "planner_patience" in results[-1].reason
    assert 2.0 <= t_end <= 2.0 + 2 * DT                             # bounded by the patience
    assert log == []                                               # the stem was not cleared away
    assert all(r.v_mps == 0.0 and r.w_radps == 0.0 for r in results)


def test_a_goal_that_becomes_blocked_while_driving_is_aborted_and_one_that_frees_up_is_not():
    glob, local = empty_costmaps(obstacle_layer_in_global=True)
    mb = MoveBase(MoveBaseConfig(planner_patience=1.0), glob, local, FakeGlobal(), FakeLocal(0.3, 0.0))
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    results, t = run(mb, 5)
    assert results[-1].state == MoveBaseState.CONTROLLING and results[-1].v_mps == 0.3
    mark(glob, (2.0, 0.0))                                         # the LiDAR now sees a stem on the goal
    results, t2 = run(mb, 3, t)
    assert results[-1].outcome == Outcome.ACTIVE and mb.goal_blocked_since_s == t
    assert all(r.v_mps == 0.0 and r.w_radps == 0.0 for r in results)   # it stops in front of the stem
    glob.obstacle_layer.clear_all()                                # it was not there after all
    glob.update_map(Pose2D(0, 0, 0))
    results, t3 = run(mb, 10, t2)
    assert results[-1].outcome == Outcome.ACTIVE and mb.goal_blocked_since_s is None
    mark(glob, (2.0, 0.0))
    results, t4 = run(mb, 20, t3)
    assert results[-1].outcome == Outcome.ABORTED and t4 - t3 <= 1.0 + 2 * DT


def test_a_blocked_goal_is_aborted_at_once_when_the_global_costmap_cannot_change():
    glob, local = empty_costmaps()
    glob.static_layer.map_costs[100, 140] = 254                    # a stem at (2.0, 0.0) in the static map
    glob.update_map(Pose2D(0, 0, 0))
    mb = MoveBase(MoveBaseConfig(), glob, local, FakeGlobal(fail=True), FakeLocal())
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    r = mb.step(0.0, Pose2D(0, 0, 0), Pose2D(0, 0, 0))
    assert r.outcome == Outcome.ABORTED and "in or next to an obstacle" in r.reason


def test_plan_blocked_ahead_is_found_and_remade():
    glob, local = empty_costmaps(obstacle_layer_in_global=True)
    poses = np.column_stack([np.linspace(0, 4, 81), np.zeros(81), np.zeros(81)])
    assert plan_blocked_at(glob, poses, Pose2D(0, 0, 0), 0.6) == -1
    mark(glob, (2.0, 0.0))
    i = plan_blocked_at(glob, poses, Pose2D(0, 0, 0), 0.6)
    assert 1.55 <= poses[i, 0] <= 1.65                             # where the inscribed radius begins
    assert plan_blocked_at(glob, poses, Pose2D(3.0, 0, 0), 0.6) == -1    # behind the robot
    # the state machine asks for a new plan when the plan ahead is blocked, not while it is clear
    glob2, local2 = empty_costmaps(obstacle_layer_in_global=True)
    gp = FakeGlobal()
    mb = MoveBase(MoveBaseConfig(), glob2, local2, gp, FakeLocal(0.3, 0.0))
    mb.set_goal(Pose2D(4.0, 0.0, 0.0), 0.0)
    run(mb, 5)
    assert len(gp.goals) == 1
    mark(glob2, (2.0, 0.0))
    run(mb, 6, 1.0)                                                # remade at most once a second
    assert len(gp.goals) == 2


def test_a_robot_that_makes_no_progress_runs_its_recoveries_then_aborts_within_the_oscillation_timeout():
    glob, local = empty_costmaps()
    log = []
    cfg = MoveBaseConfig()                                         # oscillation_timeout 20 s by default
    assert cfg.oscillation_timeout == 20.0
    mb = MoveBase(cfg, glob, local, FakeGlobal(), FakeLocal(0.3, 0.0),
                  recoveries=[CountingRecovery("a", log), CountingRecovery("b", log)])
    mb.set_goal(Pose2D(4.0, 0.0, 0.0), 0.0)
    results, t = run(mb, 1000)                                     # pinned: the pose never changes
    assert log == ["a", "b"]
    assert results[-1].outcome == Outcome.ABORTED and "oscillating" in results[-1].reason
    assert mb.recovery_trigger == RecoveryTrigger.OSCILLATION
    assert 3 * 20.0 <= t <= 3 * 20.0 + 10 * DT                     # one timeout per recovery plus the last


def test_a_robot_that_keeps_moving_is_not_aborted():
    glob, local = empty_costmaps()
    mb = MoveBase(MoveBaseConfig(), glob, local, FakeGlobal(), FakeLocal(0.3, 0.0), recoveries=[])

    def drive(pose, t):
        return Pose2D(0.1 * t, 0.0, 0.0)
    mb.set_goal(Pose2D(40.0, 0.0, 0.0), 0.0)
    results, _ = run(mb, 400, move=drive)                          # 80 s at 0.1 m/s
    assert len(results) == 400 and all(r.outcome == Outcome.ACTIVE for r in results)
