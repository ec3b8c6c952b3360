"""The move_base state machine with fake planners and a fake clock, and once with the real ones."""
import math

import numpy as np
import pytest

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.core.grid import GridSpec
from cottonsim_navigation.move_base.config import MoveBaseConfig, VisionBiasConfig
from cottonsim_navigation.move_base.state_machine import MoveBase, MoveBaseState, Outcome
from cottonsim_navigation.move_base.vision_bias import blend_vision, inside_crop_row
from cottonsim_navigation.planning.base import LocalPlannerStatus
from cottonsim_navigation.planning.costmap import make_global_costmap, make_local_costmap

from move_base_fakes import DT, CountingRecovery, FakeGlobal, FakeLocal, empty_costmaps, run


# ----------------------------------------------------------------- state machine
def test_success_with_fake_planners_passes_the_command_through():
    glob, local = empty_costmaps()
    lp = FakeLocal(0.3, 0.1)
    mb = MoveBase(MoveBaseConfig(), glob, local, FakeGlobal(), lp, recoveries=[])
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    r = mb.step(0.0, Pose2D(0, 0, 0), Pose2D(0, 0, 0))
    assert r.outcome == Outcome.ACTIVE and r.state == MoveBaseState.CONTROLLING
    assert (r.v_mps, r.w_radps) == (0.3, 0.1)
    assert r.new_plan is not None and len(r.new_plan) == 2
    # predicted local trajectory starts at the robot and bends left (w > 0)
    assert np.allclose(r.local_path[0, :2], [0, 0]) and r.local_path[-1, 1] > 0
    lp.status = LocalPlannerStatus.GOAL_REACHED
    r = mb.step(DT, Pose2D(2, 0, 0), Pose2D(2, 0, 0))
    assert r.outcome == Outcome.SUCCEEDED and (r.v_mps, r.w_radps) == (0.0, 0.0)
    assert not mb.active
    assert mb.step(2 * DT, Pose2D(2, 0, 0), Pose2D(2, 0, 0)).outcome == Outcome.IDLE


def test_plan_failure_runs_recoveries_in_order_then_aborts_with_reason():
    glob, local = empty_costmaps()
    log = []
    gp = FakeGlobal(fail=True)
    cfg = MoveBaseConfig(planner_patience=1.0)
    mb = MoveBase(cfg, glob, local, gp, FakeLocal(), [CountingRecovery("a", log), CountingRecovery("b", log, 3)])
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    results, t = run(mb, 100)
    states = [r.state for r in results]
    # planning is retried (no recovery) while within planner_patience (1 s = 5 cycles)
    first_clear = states.index(MoveBaseState.CLEARING)
    assert first_clear * DT > cfg.planner_patience
    assert all(s == MoveBaseState.PLANNING for s in states[:first_clear])
    assert log == ["a", "b"]
    last = results[-1]
    assert last.outcome == Outcome.ABORTED
    assert last.reason.startswith("no valid plan after 2 recovery behaviours")
    assert "fake: no path" in last.reason
    # recovery commands are passed through while they run, the abort stops the robot
    assert any(r.w_radps == 0.5 for r in results if r.state == MoveBaseState.CLEARING)
    assert (last.v_mps, last.w_radps) == (0.0, 0.0)
    assert len(gp.goals) >= 1 + first_clear


def test_max_planning_retries_triggers_recovery_before_patience():
    glob, local = empty_costmaps()
    log = []
    mb = MoveBase(MoveBaseConfig(planner_patience=100.0, max_planning_retries=2), glob, local,
                  FakeGlobal(fail=True), FakeLocal(), [CountingRecovery("a", log)])
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    _, t = run(mb, 2)
    assert log == []
    run(mb, 1, t)
    assert log == ["a"]                   # the third failure exceeds 2 retries
    results, _ = run(mb, 50, t + DT)
    assert results[-1].outcome == Outcome.ABORTED and log == ["a"]


def test_goal_inside_static_obstacle_aborts_at_once():
    spec = GridSpec(0.05, 200, 200, -5.0, -5.0)
    occ = np.zeros(spec.shape, np.int8)
    occ[100:120, 140:160] = 100          # a 1 x 1 m block at x 2..3, y 0..1
    glob = make_global_costmap(occ, spec)
    local = make_local_costmap()
    mb = MoveBase(MoveBaseConfig(), glob, local)           # real navfn (default_tolerance 0.1) and DWA
    mb.set_goal(Pose2D(2.5, 0.5, 0.0), 0.0)
    r = mb.step(0.0, Pose2D(0, 0, 0), Pose2D(0, 0, 0))
    assert r.outcome == Outcome.ABORTED
    assert "is in or next to an obstacle (cost 254" in r.reason and "default_tolerance 0.1 m" in r.reason
    # make_plan reports the same reason and an empty path; a reachable goal gives a path
    p = mb.make_plan(Pose2D(0, 0, 0), Pose2D(2.5, 0.5, 0.0))
    assert not p.ok and "cost 254" in p.reason
    p = mb.make_plan(Pose2D(0, 0, 0), Pose2D(4.0, 0.5, 0.0))
    assert p.ok and np.allclose(p.poses[-1, :2], [4.0, 0.5])
    # no cell of the path is an obstacle
    assert glob.cost_at_world(p.poses[:, 0], p.poses[:, 1]).max() < 253


def test_goal_in_obstacle_goes_through_recoveries_without_abort_on_blocked_goal():
    glob, local = empty_costmaps(obstacle_layer_in_global=True)
    glob.obstacle_layer.add_observation(np.array([[2.0, 0.0, 0.5]]), (0.0, 0.0, 0.5))
    glob.update_map(Pose2D(0, 0, 0))
    log = []
    mb = MoveBase(MoveBaseConfig(planner_patience=0.5, abort_on_blocked_goal=False), glob, local,
                  recoveries=[CountingRecovery("a", log)])
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    r = mb.step(0.0, Pose2D(0, 0, 0), Pose2D(0, 0, 0))
    assert r.outcome == Outcome.ACTIVE                     # an obstacle-layer cell may be cleared
    results, _ = run(mb, 50, DT)
    assert log == ["a"] and results[-1].outcome == Outcome.ABORTED
    assert "no valid plan after 1 recovery behaviours" in results[-1].reason and "cost 254" in results[-1].reason


def test_controller_failure_replans_then_recovers_then_aborts():
    glob, local = empty_costmaps()
    gp = FakeGlobal()
    lp = FakeLocal(status=LocalPlannerStatus.NO_VALID_TRAJECTORY)
    log = []
    cfg = MoveBaseConfig(controller_patience=1.0)
    mb = MoveBase(cfg, glob, local, gp, lp, [CountingRecovery("r1", log), CountingRecovery("r2", log)])
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    results, _ = run(mb, 100)
    # while within controller_patience every failed cycle asks for a new plan and stops the robot
    early = [r for r in results if r.state != MoveBaseState.CLEARING][:4]
    assert all((r.v_mps, r.w_radps) == (0.0, 0.0) for r in early)
    assert len(gp.goals) >= 5
    assert log == ["r1", "r2"]
    assert results[-1].outcome == Outcome.ABORTED
    assert results[-1].reason.startswith("no valid trajectory after 2 recovery behaviours")
    assert "no_valid_trajectory" in results[-1].reason


def test_valid_control_resets_the_recovery_index():
    glob, local = empty_costmaps()
    lp = FakeLocal(status=LocalPlannerStatus.NO_VALID_TRAJECTORY)
    log = []
    mb = MoveBase(MoveBaseConfig(controller_patience=0.5), glob, local, FakeGlobal(), lp,
                  [CountingRecovery("r1", log), CountingRecovery("r2", log)])
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    t = 0.0
    while not log:
        _, t = run(mb, 1, t)
    assert log == ["r1"] and t > 0.5
    lp.status = LocalPlannerStatus.OK
    run(mb, 3, t)
    assert mb.recovery_index == 0
    lp.status = LocalPlannerStatus.NO_VALID_TRAJECTORY
    results, _ = run(mb, 100, t + 3 * DT)
    assert log == ["r1", "r1", "r2"]      # the sequence started over
    assert results[-1].outcome == Outcome.ABORTED


def test_oscillation_triggers_recovery_only_when_the_robot_does_not_move():
    glob, local = empty_costmaps()
    log = []
    cfg = MoveBaseConfig(oscillation_timeout=2.0, oscillation_distance=0.5)
    # a robot that moves 0.1 m per cycle (0.5 m/s) never oscillates
    mb = MoveBase(cfg, glob, local, FakeGlobal(), FakeLocal(0.5, 0.0), [CountingRecovery("osc", log)])
    mb.set_goal(Pose2D(20.0, 0.0, 0.0), 0.0)
    results, _ = run(mb, 40, move=lambda p, t: Pose2D(p.x_m + 0.1, 0.0, 0.0))
    assert all(r.state == MoveBaseState.CONTROLLING for r in results) and log == []
    # a robot that only turns on the spot for longer than the timeout gets the recovery, then an abort
    mb = MoveBase(cfg, glob, local, FakeGlobal(), FakeLocal(0.0, 0.4), [CountingRecovery("osc", log, 2)])
    mb.set_goal(Pose2D(20.0, 0.0, 0.0), 0.0)
    results, _ = run(mb, 100)
    first_clear = [r.state for r in results].index(MoveBaseState.CLEARING)
    assert first_clear * DT > cfg.oscillation_timeout
    assert log == ["osc"]
    assert results[-1].outcome == Outcome.ABORTED and "oscillating" in results[-1].reason
    # after the recovery the timer restarted: the abort comes one timeout later
    assert (len(results) - 1 - first_clear) * DT > cfg.oscillation_timeout


def test_preemption_replaces_the_goal_and_resets_recoveries():
    glob, local = empty_costmaps()
    gp = FakeGlobal(fail=True)
    log = []
    mb = MoveBase(MoveBaseConfig(planner_patience=0.4), glob, local, gp, FakeLocal(),
                  [CountingRecovery("a", log, 100), CountingRecovery("b", log)])
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    results, t = run(mb, 6)
    assert mb.state == MoveBaseState.CLEARING and log == ["a"]
    gp.fail = False
    mb.set_goal(Pose2D(-1.0, 3.0, 1.0), t)
    assert mb.state == MoveBaseState.PLANNING and mb.recovery_index == 0
    r = mb.step(t, Pose2D(0, 0, 0), Pose2D(0, 0, 0))
    assert gp.goals[-1] == Pose2D(-1.0, 3.0, 1.0)
    assert r.state == MoveBaseState.CONTROLLING and np.allclose(r.new_plan.poses[-1], [-1.0, 3.0, 1.0])
    mb.cancel()
    assert mb.step(t + DT, Pose2D(0, 0, 0), Pose2D(0, 0, 0)).outcome == Outcome.IDLE


def test_plan_is_handed_to_the_local_planner_in_the_local_frame():
    glob, local = empty_costmaps()
    lp = FakeLocal()
    mb = MoveBase(MoveBaseConfig(), glob, local, FakeGlobal(), lp, [])
    # map -> odom = translation (1, 2), rotation +90 deg: robot at map (1, 2, 90deg) is odom (0, 0, 0)
    mb.set_goal(Pose2D(1.0, 4.0, math.pi / 2), 0.0)
    mb.step(0.0, Pose2D(1.0, 2.0, math.pi / 2), Pose2D(0.0, 0.0, 0.0))
    plan = lp.plans[-1]
    # goal 2 m ahead along map +y = 2 m along odom +x, yaw 0
    assert np.allclose(plan[-1], [2.0, 0.0, 0.0], atol=1e-9)
    assert np.allclose(plan[0, :2], [0.0, 0.0], atol=1e-9)
    n = len(lp.plans)
    mb.step(DT, Pose2D(1.0, 2.0, math.pi / 2), Pose2D(0.0, 0.0, 0.0))
    assert len(lp.plans) == n                 # unchanged transform: the plan is not re-sent
    mb.step(2 * DT, Pose2D(1.5, 2.0, math.pi / 2), Pose2D(0.0, 0.0, 0.0))   # map -> odom jumped 0.5 m
    assert len(lp.plans) == n + 1 and np.allclose(lp.plans[-1][-1, :2], [2.0, 0.5], atol=1e-9)
    # a moved map -> odom re-expresses the same plan (the local planner keeps its latches);
    # only a new plan is a set_plan
    assert lp.calls == ["set_plan", "update_plan_frame"]
    mb.set_goal(Pose2D(3.0, 4.0, 0.0), 3 * DT)
    mb.step(3 * DT, Pose2D(1.5, 2.0, math.pi / 2), Pose2D(0.0, 0.0, 0.0))
    assert lp.calls[-1] == "set_plan"


def test_bad_input_is_rejected_with_named_errors():
    glob, local = empty_costmaps()
    mb = MoveBase(MoveBaseConfig(), glob, local, FakeGlobal(), FakeLocal(), [])
    with pytest.raises(ValueError, match="goal"):
        mb.set_goal((float("nan"), 0.0, 0.0), 0.0)
    assert not mb.active
    mb.set_goal(Pose2D(1.0, 0.0, 0.0), 0.0)
    with pytest.raises(ValueError, match="global_pose"):
        mb.step(0.0, (0.0, float("inf"), 0.0), Pose2D(0, 0, 0))
    # a NaN velocity from odometry is treated as standing still, not a crash
    assert mb.step(0.0, Pose2D(0, 0, 0), Pose2D(0, 0, 0), (float("nan"), 0.0)).outcome == Outcome.ACTIVE
    for kwargs, name in [({"controller_frequency": 0.0}, "controller_frequency"),
                         ({"planner_patience": -1.0}, "planner_patience"),
                         ({"max_planning_retries": -2}, "max_planning_retries"),
                         ({"recovery_behaviours": ("spin",)}, "recovery_behaviours"),
                         ({"oscillation_distance": float("nan")}, "oscillation_distance"),
                         ({"clearing_rotation_allowed": "yes"}, "clearing_rotation_allowed")]:
        with pytest.raises(ValueError, match=name):
            MoveBaseConfig(**kwargs)
    with pytest.raises(ValueError, match="max_vision_rate"):
        VisionBiasConfig(max_vision_rate=-0.1)
    with pytest.raises(ValueError, match="unknown global planner"):
        MoveBase(MoveBaseConfig(base_global_planner="carrot"), glob, local)


def test_default_recovery_list_follows_move_base():
    glob, local = empty_costmaps()
    mb = MoveBase(MoveBaseConfig(), glob, local, FakeGlobal(), FakeLocal())
    assert [r.name for r in mb.recoveries] == ["conservative_reset", "rotate_recovery", "aggressive_reset",
                                               "rotate_recovery"]
    mb = MoveBase(MoveBaseConfig(clearing_rotation_allowed=False), glob, local, FakeGlobal(), FakeLocal())
    assert [r.name for r in mb.recoveries] == ["conservative_reset", "aggressive_reset"]
    # aggressive reset keeps 4 x the circumscribed radius of the Husky's body padded by 0.03 m
    r_c = math.hypot(0.495 + 0.03, 0.335 + 0.03)
    assert mb.recoveries[1].config.reset_distance_m == pytest.approx(4 * r_c)
    mb = MoveBase(MoveBaseConfig(recovery_behavior_enabled=False), glob, local, FakeGlobal(), FakeLocal())
    assert mb.recoveries == []


# ----------------------------------------------------------------- with the real planners
def test_real_navfn_and_dwa_drive_a_unicycle_to_the_goal_around_a_wall():
    spec = GridSpec(0.05, 160, 120, -1.0, -3.0)       # x -1..7, y -3..3
    occ = np.zeros(spec.shape, np.int8)
    occ[40:80, 60:64] = 100                            # wall at x 2.0..2.2, y -1..1
    glob = make_global_costmap(occ, spec)
    local = make_local_costmap()
    local.update_map(Pose2D(0, 0, 0))
    mb = MoveBase(MoveBaseConfig(), glob, local)
    goal = Pose2D(4.0, 0.0, 0.0)
    mb.set_goal(goal, 0.0)
    x = y = th = 0.0
    v = w = 0.0
    t = 0.0
    plan = None
    for _ in range(400):
        pose = Pose2D(x, y, th)
        local.update_map(pose)
        r = mb.step(t, pose, pose, (v, w))
        plan = r.new_plan if r.new_plan is not None else plan
        if r.outcome != Outcome.ACTIVE:
            break
        v, w = r.v_mps, r.w_radps
        assert 0.0 <= v <= 0.5 + 1e-9 and abs(w) <= 1.0 + 1e-9
        x += v * math.cos(th) * DT
        y += v * math.sin(th) * DT
        th += w * DT
        # never inside the wall (static map) with the robot centre
        assert not (2.0 <= x <= 2.2 and -1.0 <= y <= 1.0)
        t += DT
    assert r.outcome == Outcome.SUCCEEDED, r.reason
    assert math.hypot(x - goal.x_m, y - goal.y_m) <= 0.2
    assert abs(math.remainder(th - goal.yaw_rad, 2 * math.pi)) <= 0.1 + 0.2 * DT
    # the plan went around the wall: some pose beyond |y| 1 m near x = 2.1
    near = plan.poses[np.abs(plan.poses[:, 0] - 2.1) < 0.3]
    assert len(near) and np.abs(near[:, 1]).min() > 1.0


# ----------------------------------------------------------------- vision blend
def test_blend_vision_adds_a_bounded_fresh_correction_only_inside_a_row():
    on = VisionBiasConfig(enabled=True, max_age_s=0.5, max_vision_rate=0.08)
    assert blend_vision(0.2, 0.05, 0.1, True, on) == pytest.approx(0.25)
    assert blend_vision(0.2, 0.5, 0.1, True, on) == pytest.approx(0.28)        # clipped to +0.08
    assert blend_vision(0.2, -0.5, 0.1, True, on) == pytest.approx(0.12)       # clipped to -0.08
    assert blend_vision(0.2, 0.05, 0.6, True, on) == 0.2                       # stale
    assert blend_vision(0.2, 0.05, 0.1, False, on) == 0.2                      # not in a row
    assert blend_vision(0.2, None, None, True, on) == 0.2                      # no estimate
    assert blend_vision(0.2, float("nan"), 0.1, True, on) == 0.2               # bad estimate
    assert blend_vision(0.2, 0.05, 0.1, True, VisionBiasConfig()) == 0.2       # disabled by default
    assert VisionBiasConfig().max_vision_rate == pytest.approx(math.radians(5.0))


def row_costmap(left=True, right=True):
    spec = GridSpec(0.05, 100, 100, -2.5, -2.5)
    occ = np.zeros(spec.shape, np.int8)
    if left:
        occ[67:70, :] = 100       # y ~ +0.85..1.0 along the whole map (robot heading +x)
    if right:
        occ[32:35, :] = 100       # y ~ -0.85..-0.75
    return make_global_costmap(occ, spec)


def test_inside_crop_row_needs_obstacles_on_both_sides():
    assert inside_crop_row(row_costmap(), Pose2D(0, 0, 0), 1.0)
    assert not inside_crop_row(row_costmap(right=False), Pose2D(0, 0, 0), 1.0)
    assert not inside_crop_row(row_costmap(left=False), Pose2D(0, 0, 0), 1.0)
    # heading along the rows the other way still counts; heading across them does not
    assert inside_crop_row(row_costmap(), Pose2D(0, 0, math.pi), 1.0)
    assert not inside_crop_row(row_costmap(), Pose2D(0, 0, math.pi / 2), 1.0)
    assert not inside_crop_row(row_costmap(), Pose2D(0, 0, 0), 0.5)           # walls beyond the reach


def test_vision_correction_is_applied_by_the_state_machine_only_in_a_row():
    glob = row_costmap()
    local = make_local_costmap()
    vis = VisionBiasConfig(enabled=True)
    mb = MoveBase(MoveBaseConfig(), glob, local, FakeGlobal(), FakeLocal(0.4, 0.1), [], vision=vis)
    mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
    r = mb.step(0.0, Pose2D(0, 0, 0), Pose2D(0, 0, 0), vision_w_radps=0.03, vision_age_s=0.1)
    assert r.vision_applied and r.w_radps == pytest.approx(0.13)
    r = mb.step(DT, Pose2D(0, 0, 0), Pose2D(0, 0, 0), vision_w_radps=0.03, vision_age_s=0.9)
    assert not r.vision_applied and r.w_radps == pytest.approx(0.1)


def test_vision_correction_sees_the_row_in_the_local_costmap_when_the_map_is_empty():
    # the GPS route's global costmap is an empty map: the row is only in the LiDAR's local costmap
    empty = row_costmap(left=False, right=False)
    vis = VisionBiasConfig(enabled=True)
    for local, applied in ((row_costmap(), True), (row_costmap(left=False), False)):
        mb = MoveBase(MoveBaseConfig(), empty, local, FakeGlobal(), FakeLocal(0.4, 0.1), [], vision=vis)
        mb.set_goal(Pose2D(2.0, 0.0, 0.0), 0.0)
        r = mb.step(0.0, Pose2D(0, 0, 0), Pose2D(0, 0, 0), vision_w_radps=0.03, vision_age_s=0.1)
        assert r.vision_applied is applied
