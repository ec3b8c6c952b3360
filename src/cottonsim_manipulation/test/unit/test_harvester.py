"""The harvest of a robot (harvest.harvester): targets from detections, when to stop, a stop's picks with the
real planner on a hand-built plant row, single picks of points, cancel, and the figures."""
import math

import numpy as np
import pytest
from hand_built_scene import GROUND_Z_M, STOW_RAD, plant_row

from cottonsim_common.kinematics.ur5e import forward_kinematics
from cottonsim_common.vacuum_capture import check_capture, nozzle_tip
from cottonsim_common.transforms import transform_points
from cottonsim_manipulation.harvest.harvester import PLANNING_FAILURES, HarvestConfig, Harvester
from cottonsim_manipulation.harvest.outward import estimate_outward, estimate_stem
from cottonsim_manipulation.harvest.pick_cycle import (
    PickCycleConfig,
    CancelTrajectory,
    CaptureConfirmed,
    CaptureMissed,
    HaltRoute,
    ResumeRoute,
    RobotStopped,
    SendTrajectory,
    SetVacuum,
    TrajectoryDone,
)
from cottonsim_manipulation.harvest.pick_order import PickOrderConfig
from cottonsim_manipulation.harvest.targets import CONFIRMED, PICKED, TENTATIVE
from cottonsim_manipulation.planning.approach import plan_approach

# base_link -> the arm's base frame (URDF: the arm base 0.3452 m ahead, 0.251 m up, turned +90 deg about z).
BASE_T_ARM = np.array([[0.0, -1.0, 0.0, 0.3452], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.251], [0, 0, 0, 1.0]])
ARM_T_BASE = np.linalg.inv(BASE_T_ARM)
NOZZLE_M = 0.15
# Bolls in the arm's base frame (x: the robot's left), their true outward directions.
BOLLS = {
    "a": ((0.7, 0.05, GROUND_Z_M + 0.6), (-1.0, 0.2, 0.0)),
    "b": ((0.72, -0.3, GROUND_Z_M + 0.5), (-1.0, -0.3, 0.0)),
    "c": ((0.68, 0.35, GROUND_Z_M + 0.75), (-1.0, 0.1, 0.0)),
}
FAR = (3.0, 0.0, GROUND_Z_M + 0.6)


@pytest.fixture
def harvester(model):
    plants = plant_row()
    # The hand-built bolls face their own outward directions (within 17 deg of the robot's y axis), not away
    # from a stem: the 'lateral' estimate fits them (the 'plant' estimate is tested on its own below).
    h = Harvester(lambda p, n, q, stems: plan_approach(p, n, q, model, plants if stems is None else plants + stems),
                  HarvestConfig(outward="lateral"))
    h.update_pose(np.eye(4), ARM_T_BASE)       # the fixed frame is the arm's base frame here
    return h


def see(h, points, times=(0.0, 0.1)):
    for t in times:
        h.add_detections(np.array(points), t)


def drive(h, commands, now=0.0, capture=True, visible=None):
    """Play the arm and the vacuum until the cycle ends; the commands seen, the end time. visible(h): the bolls
    the cameras see (detected at every step); default: every target not picked."""
    q, seen, vacuum = STOW_RAD.copy(), list(commands), False
    events = [RobotStopped()]
    for _ in range(200):
        if not h.busy:
            break
        points = [t.position_m for t in h.fusion.open_targets()] if visible is None else visible(h)
        if len(points):
            h.add_detections(np.array(points), now)
        for event in events:
            commands = h.on_event(event, now)
            seen += commands
        events = []
        vacuum = next((c.on for c in reversed(commands) if isinstance(c, SetVacuum)), vacuum)
        sent = [c for c in commands if isinstance(c, SendTrajectory)]
        if sent:
            now += sent[0].trajectory.duration_s
            q = sent[0].trajectory.waypoints_rad[-1]
            h.update_joints(q)
            if sent[0].purpose == "approach":
                tip, axis = nozzle_tip(forward_kinematics(q), NOZZLE_M)
                hits = [check_capture(tip, axis, p, n) for p, n in BOLLS.values()]
                if capture and vacuum and any(c.captured for c in hits):
                    events.append(CaptureConfirmed())
            events.append(TrajectoryDone())
        else:
            now += 0.1
            commands = h.tick(now)
            seen += commands
    assert not h.busy
    return seen, now


def test_detections_become_confirmed_targets_and_only_those_in_reach_count(harvester):
    see(harvester, [p for p, _ in BOLLS.values()] + [FAR], times=(0.0,))
    assert all(t.state == TENTATIVE for t in harvester.fusion.targets())
    assert harvester.in_reach() == [] and not harvester.want_stop(robot_stopped=True)
    see(harvester, [p for p, _ in BOLLS.values()] + [FAR], times=(0.1,))
    assert len(harvester.fusion.open_targets()) == 4
    near = harvester.in_reach()
    assert len(near) == 3 and all(np.linalg.norm(t.position_m - FAR) > 1.0 for t in near)
    assert harvester.want_stop(robot_stopped=True)


def test_a_moving_robot_stops_once_it_is_abeam_of_a_target(model):
    h = Harvester(lambda p, n, q, stems: plan_approach(p, n, q, model, stems), HarvestConfig(stop_ahead_m=0.05))
    ahead = (0.7, -0.4, GROUND_Z_M + 0.6)            # arm -y is ahead of the robot (base_link +x)
    see(h, [ahead])
    h.update_pose(np.eye(4), ARM_T_BASE)
    assert not h.want_stop(robot_stopped=False) and h.want_stop(robot_stopped=True)
    moved = np.eye(4)
    moved[1, 3] = 0.42                               # the robot drove 0.42 m on: the boll is abeam
    h.update_pose(moved, ARM_T_BASE)
    assert h.want_stop(robot_stopped=False)


@pytest.mark.parametrize("still_seen, reasons", [(True, ["ok", "ok"]), (False, ["ok", "lost"]),
                                                 ("nothing", ["ok", "ok"])])
def test_a_stop_target_not_seen_lately_when_its_turn_comes_is_lost(harvester, still_seen, reasons):
    """Both targets are fresh when the stop chooses them; the second's boll is seen during the first pick or
    not (its target was left behind by an odometry jump and its boll taken with the other target). With no
    detections at all meanwhile (a caller's loop busy planning), nothing is older than anything else."""
    see(harvester, [BOLLS["a"][0], BOLLS["b"][0]])
    first = []

    def visible(h):
        if not first and h.cycle.current_target_id is not None:
            first.append(h.fusion.target(h.cycle.current_target_id).position_m.copy())
        return [] if still_seen == "nothing" else [BOLLS["a"][0], BOLLS["b"][0]] if still_seen else first

    drive(harvester, harvester.start_stop(STOW_RAD, 0.2), now=0.2, visible=visible)
    assert [r.reason for r in harvester.history] == reasons
    if still_seen is False:
        assert "not detected in the last" in harvester.history[1].detail
        assert harvester.fusion.target(harvester.history[1].target_id).attempts == 0    # no failed attempt


class RecordingPlanner:
    """The real planner, recording each boll position (arm base frame) it is asked for."""

    def __init__(self, model):
        self.model, self.calls = model, []

    def __call__(self, p, n, q, stems):
        self.calls.append(np.array(p))
        return plan_approach(p, n, q, self.model, stems)


def test_a_stop_chooses_and_plans_its_targets_from_where_the_robot_stands(model):
    """The stop is decided while driving; the robot rolls 0.3 m on while it brakes: the targets are chosen and
    planned from the standing pose, not from the pose of the decision."""
    planner = RecordingPlanner(model)
    h = Harvester(planner, HarvestConfig(outward="lateral"))
    h.update_pose(np.eye(4), ARM_T_BASE)
    see(h, [p for p, _ in BOLLS.values()])
    assert h.want_stop(robot_stopped=False)
    assert h.start_stop(STOW_RAD, 0.0) == [HaltRoute()] and planner.calls == []   # nothing planned while driving
    rolled = np.eye(4)
    rolled[1, 3] = 0.3                       # base_link +x is arm -y: the fixed frame moves +y in the arm frame
    h.update_pose(rolled, ARM_T_BASE)
    commands = h.on_event(RobotStopped(), 1.0)
    assert any(isinstance(c, SendTrajectory) for c in commands)
    assert len(planner.calls) == 1                                  # the first target only; the next ones ...
    assert h.plan_next() and not h.plan_next() and len(planner.calls) == 2    # ... one at a time, while the arm moves
    expected = {tuple(np.round(np.add(p, (0.0, 0.3, 0.0)), 6)) for p, _ in BOLLS.values()}
    assert {tuple(np.round(p, 6)) for p in planner.calls} <= expected


def test_the_plans_made_for_the_order_are_used_while_nothing_moved(model):
    planner = RecordingPlanner(model)
    h = Harvester(planner, HarvestConfig(outward="lateral"))
    h.update_pose(np.eye(4), ARM_T_BASE)
    see(h, [p for p, _ in BOLLS.values()])
    ready = np.array(PickCycleConfig().bin_joints_rad)   # every pick starts where the last one ended: the bin pose
    drive(h, h.start_stop(ready, 0.0))
    assert h.figures.results["ok"] == 3 and len(planner.calls) == 3        # one plan per boll
    # the robot moved during a stop: the next target is planned again from the new pose
    planner.calls.clear()
    h2 = Harvester(planner, HarvestConfig(outward="lateral"))
    h2.update_pose(np.eye(4), ARM_T_BASE)
    see(h2, [p for p, _ in BOLLS.values()])
    h2.start_stop(ready, 0.0)
    h2.on_event(RobotStopped(), 0.1)
    assert h2.plan_next() and len(planner.calls) == 2             # the second target planned ahead
    nudged = np.eye(4)
    nudged[0, 3] = 0.01
    h2.update_pose(nudged, ARM_T_BASE)
    h2.on_event(TrajectoryDone(), 2.0)       # transit done -> approach (no new plan)
    h2.on_event(CaptureConfirmed(), 2.1)
    h2.on_event(TrajectoryDone(), 3.0)       # approach done -> retreat and on to the bin
    h2.on_event(TrajectoryDone(), 6.0)       # delivered -> release
    see(h2, [p for p, _ in BOLLS.values()][1:], times=(6.5,))
    h2.tick(7.0)                             # released -> the next target, planned again from the nudged pose
    assert len(planner.calls) == 3
    np.testing.assert_allclose(planner.calls[2] - planner.calls[1], (0.01, 0.0, 0.0), atol=1e-9)


def test_a_target_planned_ahead_is_not_planned_again_at_its_turn(model):
    planner = RecordingPlanner(model)
    h = Harvester(planner, HarvestConfig(outward="lateral"))
    h.update_pose(np.eye(4), ARM_T_BASE)
    see(h, [p for p, _ in BOLLS.values()])
    ready = np.array(PickCycleConfig().bin_joints_rad)
    assert not h.plan_next()                                       # no stop running
    h.start_stop(ready, 0.0)
    assert not h.plan_next()                                       # the robot does not stand yet: no targets
    h.on_event(RobotStopped(), 0.1)
    assert h.plan_next() and len(planner.calls) == 2
    h.on_event(TrajectoryDone(), 2.0)
    h.on_event(CaptureConfirmed(), 2.1)
    h.on_event(TrajectoryDone(), 3.0)
    h.on_event(TrajectoryDone(), 6.0)
    see(h, [p for p, _ in BOLLS.values()][1:], times=(6.5,))
    h.tick(7.0)                                                    # the second target's turn: its plan is ready
    assert len(planner.calls) == 2 and h.cycle.phase == "approach"


def test_a_stop_picks_every_reachable_boll_and_records_the_figures(harvester):
    see(harvester, [p for p, _ in BOLLS.values()] + [FAR])
    commands = harvester.start_stop(STOW_RAD, 0.0)
    assert commands == [HaltRoute()] and harvester.busy
    seen, end = drive(harvester, commands)
    assert ResumeRoute() in seen
    states = {tuple(np.round(t.position_m, 3)): t.state for t in harvester.fusion.targets()}
    assert [states[tuple(np.round(p, 3))] for p, _ in BOLLS.values()] == [PICKED] * 3
    assert states[tuple(np.round(FAR, 3))] == CONFIRMED           # out of reach: not tried
    figures = harvester.figures.as_dict()
    assert figures["picked"] == 3 and figures["attempted"] == 3 and figures["stops"] == 1
    assert len(figures["cycle_times_s"]) == 3 and 0.0 < figures["cycle_time_median_s"] < end
    # the picked bolls are never added again, nor is a stop wanted for them
    see(harvester, [p for p, _ in BOLLS.values()], times=(5.0, 5.1))
    assert len(harvester.fusion.targets()) == 4 and not harvester.want_stop(robot_stopped=True)


def test_the_detection_path_noisy_detections_over_frames_are_fused_and_picked(harvester):
    """The side cameras' path: every boll seen in 20 frames with 5 mm noise (and a stray false detection in
    one frame, never confirmed): the fused targets are picked, each capture checked against the truth."""
    rng = np.random.default_rng(3)
    truth = np.array([p for p, _ in BOLLS.values()])
    for k in range(20):
        harvester.add_detections(truth + rng.normal(0.0, 0.005, truth.shape), 0.05 * k, sigma_m=0.005)
    harvester.add_detections([(0.6, 0.2, GROUND_Z_M + 0.3)], 0.5, sigma_m=0.005)
    assert len(harvester.fusion.open_targets()) == 3 and len(harvester.fusion) == 4
    errors = [min(np.linalg.norm(truth - t.position_m, axis=1)) for t in harvester.fusion.open_targets()]
    assert max(errors) < 0.005
    drive(harvester, harvester.start_stop(STOW_RAD, 0.0))
    assert harvester.figures.results["ok"] == 3 and harvester.figures.as_dict()["attempted"] == 3


def test_missed_captures_count_as_failed_attempts(harvester):
    see(harvester, [BOLLS["a"][0]])
    drive(harvester, harvester.start_stop(STOW_RAD, 0.0), capture=False)
    target = harvester.fusion.targets()[0]
    assert target.attempts == 1 and target.state == CONFIRMED
    assert harvester.figures.results["capture_missed"] == 1 and harvester.figures.results["ok"] == 0
    assert harvester.last_result[target.target_id].reason == "capture_missed"


def test_a_point_out_of_reach_is_unreachable_and_leaves_the_targets_alone(harvester):
    commands = harvester.start_pick(STOW_RAD, 0.0, point_frame_m=FAR)
    drive(harvester, commands)
    (result,) = harvester.last_result.values()
    assert result.target_id < 0 and result.reason == "unreachable"
    assert len(harvester.fusion) == 0


def test_a_cancelled_pick_stops_the_arm_and_keeps_the_target(harvester):
    see(harvester, [BOLLS["a"][0]])
    target_id = harvester.fusion.targets()[0].target_id
    commands = harvester.start_pick(STOW_RAD, 0.0, target_id=target_id)
    commands = harvester.on_event(RobotStopped(), 0.1)
    assert isinstance(commands[0], SendTrajectory) and commands[0].purpose == "transit"
    commands = harvester.cancel(0.5)
    assert CancelTrajectory() in commands and SetVacuum(False) in commands and not harvester.busy
    assert harvester.last_result[target_id].reason == "cancelled"
    assert harvester.fusion.target(target_id).state == CONFIRMED and harvester.fusion.target(target_id).attempts == 0


def test_bad_pick_requests_are_refused(harvester):
    with pytest.raises(ValueError, match="no boll target 7"):
        harvester.start_pick(STOW_RAD, 0.0, target_id=7)
    with pytest.raises(ValueError, match="3 finite numbers"):
        harvester.start_pick(STOW_RAD, 0.0, point_frame_m=(1.0, math.nan, 0.0))
    see(harvester, [BOLLS["a"][0]])
    harvester.start_stop(STOW_RAD, 0.0)
    with pytest.raises(RuntimeError, match="running"):
        harvester.start_pick(STOW_RAD, 0.0, target_id=0)


def test_the_outward_estimates():
    left = (0.3, 0.5, 0.4)                                          # base_link: x ahead, y left
    shoulder = (0.3452, 0.0, 0.4135)
    lateral = HarvestConfig(outward="lateral")
    np.testing.assert_allclose(estimate_outward(left, [], shoulder, lateral), [0.0, -1.0, 0.0])
    np.testing.assert_allclose(estimate_outward((0.3, -0.5, 0.4), [], shoulder, lateral), [0.0, 1.0, 0.0])
    radial = estimate_outward((0.3452 + 0.3, 0.4, 0.4), [], shoulder, HarvestConfig(outward="radial"))
    np.testing.assert_allclose(radial, [-0.6, -0.8, 0.0], atol=1e-12)
    # plant: the stem on the row line (0.9 m left), along the row at the centre of the plant's targets
    # (a plant at x 1.0 and its neighbour 0.7 m on; targets of the other row do not count)
    plant = HarvestConfig(outward="plant", row_offset_m=0.9, plant_half_spacing_m=0.35)
    targets = [(0.8, 0.6, 0.4), (1.2, 0.6, 0.5), (1.0, 0.55, 0.6), (1.7, 0.6, 0.4), (1.05, -0.6, 0.5)]
    out = estimate_outward((1.2, 0.6, 0.5), targets, shoulder, plant)
    expected = np.array([0.2, -0.3, 0.0]) / np.hypot(0.2, 0.3)
    np.testing.assert_allclose(out, expected, atol=1e-9)
    # alone: the stem straight across on the row line
    np.testing.assert_allclose(estimate_outward((1.2, 0.6, 0.5), [], shoulder, plant), [0.0, -1.0, 0.0])


def test_the_row_grid_estimate_puts_lopsided_plants_stems_on_the_regular_grid():
    """Five plants 0.7 m apart (stems at x = 0.25 + 0.7 k, 0.9 m left) whose bolls lean 8-10 cm to one side
    or the other along the row: the mean shift ('plant') follows the lean, the grid ('row_grid') finds the
    stem; alone, a boll's stem is straight across."""
    rng = np.random.default_rng(3)
    stems = 0.25 + 0.7 * np.arange(5)
    leans = np.array([0.1, -0.08, 0.06, -0.1, 0.02])        # no lean on the whole
    targets = np.array([(x + lean + rng.uniform(-0.12, 0.12), 0.9 + rng.uniform(-0.25, 0.05), 0.5)
                        for x, lean in zip(stems, leans) for _ in range(12)])
    grid = HarvestConfig(outward="row_grid", row_offset_m=0.9, plant_half_spacing_m=0.35, grid_window_m=3.0)
    plant = HarvestConfig(outward="plant", row_offset_m=0.9, plant_half_spacing_m=0.35)
    boll = np.array([stems[2] + 0.15, 0.8, 0.5])
    np.testing.assert_allclose(estimate_stem(boll, targets, grid), [stems[2], 0.9], atol=0.015)
    assert abs(estimate_stem(boll, targets, plant)[0] - stems[2]) > 0.05
    np.testing.assert_allclose(estimate_stem(boll, [], grid), [boll[0], 0.9])
    assert HarvestConfig().outward == "row_grid"
    with pytest.raises(ValueError, match="grid_window_m"):
        HarvestConfig(grid_window_m=0.0)


def test_transform_points_and_pose_checks():
    np.testing.assert_allclose(transform_points(BASE_T_ARM, [[1.0, 0.0, 0.0]]), [[0.3452, 1.0, 0.251]])
    with pytest.raises(ValueError, match="4x4"):
        transform_points(np.eye(3), [[0.0, 0.0, 0.0]])
    h = Harvester(lambda p, n, q, stems: None)
    with pytest.raises(RuntimeError, match="pose is not known"):
        h.in_reach()


@pytest.mark.parametrize("kwargs, word", [
    ({"reach_m": 0.0}, "reach_m"), ({"min_reach_m": 1.5}, "min_reach_m"), ({"stop_ahead_m": math.nan}, "stop_ahead_m"),
    ({"max_targets_per_stop": 0}, "max_targets_per_stop"), ({"outward": "up"}, "outward"),
    ({"row_offset_m": 0.0}, "row_offset_m"), ({"plant_half_spacing_m": math.inf}, "plant_half_spacing_m"),
    ({"detection_sigma_m": -0.01}, "detection_sigma_m"), ({"stopped_speed_m_s": True}, "stopped_speed_m_s"),
])
def test_bad_configs_are_refused_by_name(kwargs, word):
    with pytest.raises(ValueError, match=word):
        HarvestConfig(**kwargs)


def test_targets_not_seen_lately_neither_stop_the_robot_nor_are_picked(model):
    """An odometry jump leaves the targets seen before it 6 cm off their bolls: the bolls' new detections start
    new targets, and a stop picks those, not the stale ones."""
    h = Harvester(lambda p, n, q, stems: plan_approach(p, n, q, model, stems), HarvestConfig(outward="lateral",
                                                                                 max_target_age_s=2.0))
    h.update_pose(np.eye(4), ARM_T_BASE)
    a = np.array(BOLLS["a"][0])
    see(h, [a + (0.0, 0.06, 0.0)], times=(0.0, 0.1))        # before the jump
    assert h.want_stop(robot_stopped=True, now_s=1.0) and not h.want_stop(robot_stopped=True, now_s=2.5)
    see(h, [a], times=(3.0, 3.1))                             # after it: a new target
    assert len(h.fusion.open_targets()) == 2
    fresh = [t.target_id for t in h.in_reach(now_s=3.5)]
    assert len(fresh) == 1 and np.allclose(h.fusion.target(fresh[0]).position_m, a)
    h.start_stop(STOW_RAD, 3.5)
    h.on_event(RobotStopped(), 3.6)
    assert h.cycle.current_target_id == fresh[0]
    with pytest.raises(ValueError, match="max_target_age_s"):
        HarvestConfig(max_target_age_s=0.0)


def test_a_target_the_planner_failed_for_is_tried_again_from_elsewhere_without_counting_an_attempt(model):
    """Planned again at stops 0.2 m on; with retry_stops 0 it stops a driving robot again only from the next
    lane."""
    h = Harvester(lambda p, n, q, stems: plan_approach(p, n, q, model, stems), HarvestConfig(outward="lateral",
                                                                                 retry_distance_m=0.2, retry_stops=0))
    h.update_pose(np.eye(4), ARM_T_BASE)
    beyond = (0.3, 0.0, -0.5)                      # in reach of the shoulder; the nozzle cannot get there
    see(h, [beyond])
    assert h.want_stop(robot_stopped=True)
    drive(h, h.start_stop(STOW_RAD, 0.0))
    assert sum(h.figures.results[r] for r in PLANNING_FAILURES) == 1 and h.figures.results["ok"] == 0
    target = h.fusion.open_targets()[0]
    assert target.attempts == 0 and target.state == CONFIRMED      # the arm never moved for it
    assert not h.want_stop(robot_stopped=True)     # from the same place it would fail again
    moved = np.eye(4)
    moved[1, 3] = 0.1                              # 0.1 m on: still too close to where it failed
    h.update_pose(moved, ARM_T_BASE)
    assert not h.want_stop(robot_stopped=True)
    moved[1, 3] = -0.25                            # 0.25 m back
    h.update_pose(moved, ARM_T_BASE)
    assert not h.want_stop(robot_stopped=False)    # it does not stop a driving robot again ...
    assert h.want_stop(robot_stopped=True)         # ... but a stop there tries it again
    for _ in range(3):                             # failing again and again, it is never abandoned
        drive(h, h.start_stop(STOW_RAD, 1.0))
        moved[1, 3] = -0.25 - moved[1, 3]          # back and forth, 0.25 m each time
        h.update_pose(moved, ARM_T_BASE)
    assert sum(h.figures.results[r] for r in PLANNING_FAILURES) == 4
    assert h.fusion.target(target.target_id).state == CONFIRMED
    moved[:3, 3] = (-1.0, 0.0, 0.3)                # from the next lane: over reach_m (1 m) from the failures
    h.update_pose(moved, ARM_T_BASE)
    assert h.pickable() and h.want_stop(robot_stopped=False)


def test_a_target_the_planner_failed_for_stops_a_driving_robot_again_retry_stops_times(model):
    """Each retry once the shoulder moved retry_distance_m from the last failure; then only from the next lane."""
    h = Harvester(lambda p, n, q, stems: plan_approach(p, n, q, model, stems),
                  HarvestConfig(outward="lateral", retry_distance_m=0.2, retry_stops=2))
    pose = np.eye(4)
    h.update_pose(pose, ARM_T_BASE)
    see(h, [(0.3, 0.0, -0.5)])                     # in reach of the shoulder; the nozzle cannot get there
    for failures in (1, 2, 3):
        assert h.want_stop(robot_stopped=True)
        drive(h, h.start_stop(STOW_RAD, float(failures)))
        assert sum(h.figures.results[r] for r in PLANNING_FAILURES) == failures
        last = pose[1, 3]
        step = 0.25 if last == 0.0 else -0.25      # the target abeam, then 0.25 m behind, and back
        pose[1, 3] = last + 0.4 * step             # 0.1 m from the failure: too close
        h.update_pose(pose, ARM_T_BASE)
        assert not h.want_stop(robot_stopped=False)
        pose[1, 3] = last + step
        h.update_pose(pose, ARM_T_BASE)
        assert h.want_stop(robot_stopped=False) == (failures <= 2), failures
    pose[:3, 3] = (-1.0, 0.0, 0.3)                 # the next lane: over reach_m (1 m) from the last failure
    h.update_pose(pose, ARM_T_BASE)
    assert h.want_stop(robot_stopped=False)
    with pytest.raises(ValueError, match="retry_stops"):
        HarvestConfig(retry_stops=-1)


def test_the_estimated_stems_are_obstacles_of_the_plan(model):
    """'plant': a boll 0.2 m inside the row line; its stem (row line, plant centre) goes to the planner as a
    vertical capsule from the ground up, in the arm's base frame; off with stem_obstacles false."""
    seen_obstacles = []

    def planner(p, n, q, stems):
        seen_obstacles.append(stems)
        return plan_approach(p, n, q, model, stems)

    boll_base = np.array([0.5, 0.7, 0.3])                 # base_link; the row line at y 0.9
    boll_arm = transform_points(ARM_T_BASE, [boll_base])[0]
    for enabled in (True, False):
        seen_obstacles.clear()
        h = Harvester(planner, HarvestConfig(outward="plant", row_offset_m=0.9, stem_obstacles=enabled))
        h.update_pose(np.eye(4), ARM_T_BASE)              # the fixed frame is the arm's base frame
        see(h, [boll_arm])
        h.start_stop(STOW_RAD, 0.0)
        h.on_event(RobotStopped(), 0.1)
        if not enabled:
            assert seen_obstacles and all(o is None for o in seen_obstacles)
            continue
        stems = seen_obstacles[0]
        assert len(stems.radius_m) == 1
        foot, top = transform_points(BASE_T_ARM, [stems.start_m[0], stems.end_m[0]])
        np.testing.assert_allclose(foot, [0.5, 0.9, HarvestConfig().ground_z_m], atol=1e-9)
        np.testing.assert_allclose(top - foot, [0.0, 0.0, 1.0], atol=1e-9)
    with pytest.raises(ValueError, match="stem_obstacles"):
        HarvestConfig(stem_obstacles=1)


@pytest.mark.parametrize("radius_m", [0.03, 0.0])
def test_a_boll_on_anothers_approach_line_is_picked_before_it(model, monkeypatch, radius_m):
    """Boll 'a' with a neighbour 6 cm out on its approach line: the nozzle (vacuum on from the pre-grasp)
    would catch the neighbour first, so the neighbour goes first even where the given order (made to put
    'a' first here) says otherwise; with the check off the given order stands."""
    h = Harvester(lambda p, n, q, stems: plan_approach(p, n, q, model, stems), HarvestConfig(outward="lateral"),
                  order_config=PickOrderConfig(clear_approach_radius_m=radius_m))
    h.update_pose(np.eye(4), ARM_T_BASE)
    a = np.array(BOLLS["a"][0])
    ready = np.array(PickCycleConfig().bin_joints_rad)
    see(h, [a])
    neighbour = a - 0.06 * h.plan_from_here(a, ready).plan.approach_direction
    see(h, [a, neighbour])
    nearest_first = h.pickable
    monkeypatch.setattr(h, "pickable", lambda now_s=None: sorted(
        nearest_first(now_s), key=lambda t: not np.allclose(t.position_m, a, atol=1e-6)))
    h.start_stop(ready, 0.0)
    h.on_event(RobotStopped(), 0.1)
    first = h.fusion.target(h.cycle.current_target_id).position_m
    assert np.allclose(first, neighbour if radius_m > 0.0 else a, atol=1e-6)
