"""The pick cycle state machine: happy path, every failure reason, timeouts, no targets."""
from types import SimpleNamespace

import numpy as np
import pytest

from cottonsim_manipulation.harvest.pick_cycle import (
    CancelTrajectory,
    CaptureConfirmed,
    CaptureMissed,
    HaltRoute,
    PickCycle,
    PickCycleConfig,
    PickTarget,
    ResumeRoute,
    RobotStopped,
    SendTrajectory,
    SetVacuum,
    TargetLost,
    TrajectoryDone,
    TrajectoryFailed,
)
from cottonsim_manipulation.planning.trajectory import plan_trajectory

START = np.array([1.57, -2.2, 2.4, -1.77, -1.57, 0.0])


def fake_plan(q_from, k):
    pre = START + 0.1 * (k + 1)
    grasp, retreat = pre + 0.05, pre
    return SimpleNamespace(q_pregrasp_rad=pre, q_grasp_rad=grasp, q_retreat_rad=retreat,
                           transit=plan_trajectory(np.stack([q_from, pre])),
                           approach=plan_trajectory(np.stack([pre, grasp])),
                           retreat=plan_trajectory(np.stack([grasp, retreat])))


def planner(failures=None):
    """A stand-in approach planner: targets in `failures` fail with that reason."""
    failures = failures or {}

    def plan(target, q):
        reason = failures.get(target.target_id)
        if reason:
            return SimpleNamespace(ok=False, reason=reason, detail="test", plan=None)
        return SimpleNamespace(ok=True, reason="ok", detail="", plan=fake_plan(q, target.target_id))
    return plan


def targets(n):
    return [PickTarget(k, (0.7, 0.1 * k, 0.2), (-1.0, 0.0, 0.0)) for k in range(n)]


def purposes(commands):
    return [c.purpose for c in commands if isinstance(c, SendTrajectory)]


def pick_one(cycle, now):
    """Drive one target through the happy path; returns the time after."""
    assert cycle.phase == "approach"
    c = cycle.on_event(TrajectoryDone(), now)
    assert SetVacuum(True) in c and purposes(c) == ["approach"]
    now += 1.0
    assert cycle.on_event(CaptureConfirmed(), now) == []          # during the advance
    c = cycle.on_event(TrajectoryDone(), now + 0.5)
    assert purposes(c) == ["deliver"]                             # the retreat and on to the bin, one motion
    deliver = next(cmd.trajectory for cmd in c if isinstance(cmd, SendTrajectory))
    np.testing.assert_allclose(deliver.waypoints_rad[0], cycle._current.plan.q_grasp_rad)
    np.testing.assert_allclose(deliver.waypoints_rad[1], cycle._current.plan.q_retreat_rad)
    np.testing.assert_allclose(deliver.waypoints_rad[-1], PickCycleConfig().bin_joints_rad)
    c = cycle.on_event(TrajectoryDone(), now + 2.0)
    assert c == [SetVacuum(False)] and cycle.phase == "release"
    assert cycle.tick(now + 2.1) == []                            # dwell not over yet
    return now + 2.5


def test_happy_path_three_targets():
    cycle = PickCycle(targets(3), START, planner())
    assert cycle.start(0.0) == [HaltRoute()]
    c = cycle.on_event(RobotStopped(), 0.5)
    assert purposes(c) == ["transit"]
    now = 1.0
    for k in range(3):
        now = pick_one(cycle, now)
        c = cycle.tick(now)
        if k < 2:
            assert purposes(c) == ["transit"]
    assert c == [ResumeRoute()] and cycle.done
    assert [r.target_id for r in cycle.results] == [0, 1, 2]
    assert all(r.ok for r in cycle.results)
    assert sum(r.cycle_time_s for r in cycle.results) == pytest.approx(now)
    assert cycle.results[0].cycle_time_s == pytest.approx(4.5)             # stop (0 s) to the first release


def test_no_targets_resumes_at_once():
    cycle = PickCycle([], START, planner())
    assert cycle.start(0.0) == [ResumeRoute()] and cycle.done and cycle.results == []


@pytest.mark.parametrize("reason", ["unreachable", "ik_failed", "collision"])
def test_planning_failures_go_to_the_next_target_with_their_reason(reason):
    cycle = PickCycle(targets(2), START, planner({0: reason}))
    cycle.start(0.0)
    c = cycle.on_event(RobotStopped(), 0.1)
    assert purposes(c) == ["transit"]
    assert cycle.results[0].target_id == 0 and cycle.results[0].reason == reason
    pick_one(cycle, 1.0)
    assert cycle.tick(10.0) == [ResumeRoute()]
    assert [r.reason for r in cycle.results] == [reason, "ok"]


def start_first(n=2):
    cycle = PickCycle(targets(n), START, planner())
    cycle.start(0.0)
    cycle.on_event(RobotStopped(), 0.0)
    return cycle


def test_capture_missed_retreats_without_delivering_then_next():
    cycle = start_first()
    cycle.on_event(TrajectoryDone(), 1.0)
    cycle.on_event(TrajectoryDone(), 2.0)                       # approach ends, no capture yet
    c = cycle.on_event(CaptureMissed("too far"), 2.1)
    assert SetVacuum(False) in c and purposes(c) == ["retreat"]
    c = cycle.on_event(TrajectoryDone(), 3.0)
    assert purposes(c) == ["transit"]
    assert cycle.results[0].reason == "capture_missed"


def test_no_capture_confirmation_in_time_is_a_miss():
    cycle = start_first()
    cycle.on_event(TrajectoryDone(), 1.0)
    cycle.on_event(TrajectoryDone(), 2.0)
    assert cycle.tick(2.0 + cycle.config.capture_wait_s - 0.01) == []
    c = cycle.tick(2.0 + cycle.config.capture_wait_s)
    assert SetVacuum(False) in c and purposes(c) == ["retreat"]
    cycle.on_event(TrajectoryDone(), 3.0)
    assert cycle.results[0].reason == "capture_missed"


def test_target_lost_during_approach_and_before_its_turn():
    cycle = start_first(3)
    assert cycle.on_event(TargetLost(2), 0.5) == []             # a later one: skipped in its turn
    c = cycle.on_event(TargetLost(0), 0.6)                      # the current one, still approaching
    assert CancelTrajectory() in c and purposes(c) == ["transit"]
    pick_one(cycle, 1.0)
    assert cycle.tick(10.0) == [ResumeRoute()]
    assert [(r.target_id, r.reason) for r in cycle.results] == [(0, "lost"), (1, "ok"), (2, "lost")]


def test_a_captured_target_out_of_view_is_not_lost():
    cycle = start_first(1)
    cycle.on_event(TrajectoryDone(), 1.0)
    cycle.on_event(CaptureConfirmed(), 1.5)
    assert cycle.on_event(TargetLost(0), 1.6) == []
    assert cycle.phase == "capture"


def test_trajectory_failure_is_aborted_with_vacuum_off():
    cycle = start_first()
    cycle.on_event(TrajectoryDone(), 1.0)
    c = cycle.on_event(TrajectoryFailed("path tolerance"), 1.5)
    assert SetVacuum(False) in c and purposes(c) == ["transit"]
    assert cycle.results[0].reason == "aborted" and "path tolerance" in cycle.results[0].detail


@pytest.mark.parametrize("phase", ["approach", "capture", "deliver", "retreat"])
def test_every_motion_phase_times_out_and_the_cycle_ends(phase):
    cycle = start_first(1)
    now = 0.0
    if phase != "approach":
        cycle.on_event(TrajectoryDone(), now)                   # at the pre-grasp: the approach goes out
    if phase in ("deliver", "retreat"):
        cycle.on_event(CaptureConfirmed() if phase == "deliver" else CaptureMissed("test"), now)
        cycle.on_event(TrajectoryDone(), now)                   # at the boll: on to the bin, or back out
    assert cycle.phase == phase
    c = []
    for step in range(1, 200):                                  # no event ever comes: only time passes
        c = cycle.tick(now + 0.1 * step)
        if c:
            break
    assert CancelTrajectory() in c and SetVacuum(False) in c and c[-1] == ResumeRoute()
    assert cycle.done and cycle.results[0].reason == "timeout" and phase in cycle.results[0].detail


def test_halt_timeout_abandons_the_stop():
    cycle = PickCycle(targets(2), START, planner())
    cycle.start(0.0)
    assert cycle.tick(cycle.config.halt_timeout_s) == [ResumeRoute()]
    assert [r.reason for r in cycle.results] == ["timeout", "timeout"]


def test_bad_config_and_input():
    with pytest.raises(ValueError, match="halt_timeout_s"):
        PickCycleConfig(halt_timeout_s=0.0)
    with pytest.raises(ValueError, match="bin_joints_rad"):
        PickCycleConfig(bin_joints_rad=(0.0,) * 5)
    with pytest.raises(ValueError, match="bin_joints_rad"):
        PickCycleConfig(bin_joints_rad=(0.0, 0.0, 9.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="unique"):
        PickCycle(targets(1) * 2, START, planner())
    with pytest.raises(ValueError, match="time"):
        PickCycle(targets(1), START, planner()).start(float("nan"))
    cycle = start_first(1)
    with pytest.raises(RuntimeError, match="already started"):
        cycle.start(1.0)
    assert cycle.current_target_id == 0


def test_cancel_stops_the_arm_and_ends_the_cycle_with_every_target_cancelled():
    cycle = PickCycle(targets(3), START, planner())
    cycle.start(0.0)
    assert purposes(cycle.on_event(RobotStopped(), 0.1)) == ["transit"]
    commands = cycle.cancel(0.5, "stop")
    assert commands == [CancelTrajectory(), SetVacuum(False), ResumeRoute()] and cycle.done
    assert [(r.target_id, r.reason, r.detail) for r in cycle.results] == [(0, "cancelled", "stop"),
                                                                          (1, "cancelled", "stop"),
                                                                          (2, "cancelled", "stop")]
    assert cycle.cancel(0.6) == [] and cycle.tick(100.0) == []


def test_cancel_while_halting_sends_no_trajectory_cancel():
    cycle = PickCycle(targets(1), START, planner())
    cycle.start(0.0)
    assert cycle.cancel(0.2) == [SetVacuum(False), ResumeRoute()]
    assert [r.reason for r in cycle.results] == ["cancelled"]


def test_targets_chosen_once_the_robot_stands_and_deadlines_counted_after_planning():
    """A stop that chooses its targets when the robot stands (a callable): the selection sees the joints and
    the time of the stop; planning the selection took 8 s (the clock moved on), so the transit's deadline
    counts from the end of the planning, not from the RobotStopped call's time."""
    clock = {"now": 0.0}
    asked = []

    def select(q, now_s):
        asked.append((q.copy(), now_s))
        clock["now"] = now_s + 8.0                    # the plans of the stop took 8 s
        return targets(2)

    cycle = PickCycle(select, START, planner(), PickCycleConfig(motion_margin_s=1.0), clock=lambda: clock["now"])
    assert cycle.start(0.0) == [HaltRoute()] and asked == []
    commands = cycle.on_event(RobotStopped(), 2.0)
    assert len(asked) == 1 and np.allclose(asked[0][0], START) and asked[0][1] == 2.0
    assert purposes(commands) == ["transit"]
    transit_s = commands[0].trajectory.duration_s
    assert cycle.tick(2.0 + transit_s + 1.5) == []     # past the deadline counted from the call: not timed out
    assert cycle.phase == "approach"
    assert not any(r.reason == "timeout" for r in cycle.results)
    cycle.tick(10.0 + transit_s + 1.1)                 # past the deadline counted from the plan's end
    assert cycle.results[0].reason == "timeout"


def test_an_empty_selection_resumes_the_route():
    cycle = PickCycle(lambda q, now_s: [], START, planner())
    assert cycle.start(0.0) == [HaltRoute()]
    assert cycle.on_event(RobotStopped(), 1.0) == [ResumeRoute()] and cycle.done
