"""Approach plans to a boll: pose, straight approach and retreat, collision-free, reasons for failure."""
import math

import numpy as np
import pytest
from hand_built_scene import GROUND_Z_M, STOW_RAD, plant_row

from cottonsim_common.kinematics.ur5e import forward_kinematics, inverse_kinematics_batch, link_frames
from cottonsim_common.vacuum_capture import check_capture, nozzle_tip
from cottonsim_manipulation.planning.approach import (
    ApproachConfig,
    approach_directions,
    plan_approach,
    tilted_up,
    tool_rotations,
)
from cottonsim_common.capsules import CapsuleSet
from cottonsim_manipulation.planning.collision import ArmCollisionModel
from cottonsim_manipulation.planning.trajectory import TrajectoryConfig

NOZZLE_M = 0.15


def tip_and_axis(q):
    return nozzle_tip(forward_kinematics(q), NOZZLE_M)


def assert_plan_is_sound(result, boll, outward, model, obstacles, config=ApproachConfig()):
    assert result.ok, result.detail
    plan = result.plan
    n = outward / np.linalg.norm(outward)
    direction = -plan.approach_direction
    # The nozzle ends at the boll, pointing into it along the (tilted) approach direction.
    tip, axis = tip_and_axis(plan.q_grasp_rad)
    np.testing.assert_allclose(tip, boll, atol=1e-6)
    np.testing.assert_allclose(axis, plan.approach_direction, atol=1e-6)
    assert np.dot(direction, n) >= math.cos(config.max_deviation_rad) - 1e-9
    assert check_capture(tip, axis, boll, direction).captured
    tip, _ = tip_and_axis(plan.q_pregrasp_rad)
    np.testing.assert_allclose(tip, boll + config.pregrasp_distance_m * direction, atol=1e-6)
    tip, _ = tip_and_axis(plan.q_retreat_rad)
    np.testing.assert_allclose(tip, boll + config.retreat_distance_m * direction, atol=1e-6)
    # The trajectories join up, and approach and retreat keep the tip on their line.
    np.testing.assert_allclose(plan.transit.waypoints_rad[-1], plan.approach.waypoints_rad[0])
    np.testing.assert_allclose(plan.approach.waypoints_rad[-1], plan.retreat.waypoints_rad[0])
    for traj in (plan.approach, plan.retreat):
        _, q, _, _ = traj.sampled()
        f = link_frames(q)[:, 6]
        tips = f[:, :3, 3] + NOZZLE_M * f[:, :3, 2]
        off = tips - boll
        along = off @ direction
        perp = np.linalg.norm(off - along[:, None] * direction, axis=1)
        assert perp.max() <= config.max_line_deviation_m + 1e-3
    # Collision-free when checked at a four times finer step than the planner's.
    for traj in (plan.transit, plan.approach, plan.retreat):
        assert model.first_collision(traj, obstacles, step_rad=config.collision_step_rad / 4) is None
    assert plan.duration_s > 0.0 and plan.joint_travel_rad > 0.0


def test_a_boll_on_the_lane_facing_side_of_a_plant(model):
    plants = plant_row()
    boll = np.array([0.9 - 0.2, 0.05, GROUND_Z_M + 0.6])
    outward = np.array([-1.0, 0.2, 0.0])
    result = plan_approach(boll, outward, STOW_RAD, model, plants)
    assert_plan_is_sound(result, boll, outward, model, plants)
    # Horizontal approach works here: no tilt needed.
    np.testing.assert_allclose(-result.plan.approach_direction, outward / np.linalg.norm(outward), atol=1e-9)


def test_most_bolls_of_a_plant_face_are_planned_soundly(model):
    plants = plant_row()
    planned = 0
    cases = [(h, dy, dx) for h in (0.35, 0.5, 0.65, 0.8, 0.95) for dy in (-0.2, 0.0, 0.2) for dx in (0.15, 0.25)]
    for h, dy, dx in cases:
        boll = np.array([0.9 - dx, dy, GROUND_Z_M + h])
        outward = np.array([-1.0, 0.5 * dy, 0.0])
        result = plan_approach(boll, outward, STOW_RAD, model, plants)
        assert result.reason in ("ok", "collision")
        if result.ok:
            planned += 1
            assert_plan_is_sound(result, boll, outward, model, plants)
    assert planned >= 0.8 * len(cases)


def test_a_boll_facing_along_the_row_past_a_stem_is_reached_with_a_yawed_approach(model):
    # The boll faces along the row (+y, arm frame) towards the next plant, whose 6 cm thick stem
    # stands 12 cm ahead of it: every approach in the outward direction's vertical plane hits it.
    boll = np.array([0.75, 0.05, GROUND_Z_M + 0.5])
    outward = np.array([0.0, 1.0, 0.0])
    stem = CapsuleSet.from_list([((0.75, 0.17, GROUND_Z_M), (0.75, 0.17, GROUND_Z_M + 2.0), 0.03, "next/stem")])
    without_yaw = plan_approach(boll, outward, STOW_RAD, model, stem, ApproachConfig(yaw_samples_rad=(0.0,)))
    assert without_yaw.reason == "collision" and "next/stem" in without_yaw.detail
    result = plan_approach(boll, outward, STOW_RAD, model, stem)
    assert_plan_is_sound(result, boll, outward, model, stem)
    assert result.plan.yaw_rad != 0.0 and result.plan.yaw_rad in ApproachConfig().yaw_samples_rad
    # turned about the vertical, towards the lane (arm -x), and still inside the capture cone
    tip, axis = tip_and_axis(result.plan.q_grasp_rad)
    assert result.plan.approach_direction[0] > 0.0
    assert check_capture(tip, axis, boll, outward).captured


def test_approach_directions_least_deviation_first_inside_the_capture_cone():
    outward = np.array([0.0, 1.0, 0.0])
    assert ApproachConfig().max_deviation_rad == pytest.approx(math.radians(35.0))   # 10 deg inside the cone
    defaults = approach_directions(outward, ApproachConfig())
    assert len(defaults) == 9 and max(d.deviation_rad for d in defaults) <= math.radians(35.0)
    cfg = ApproachConfig(tilt_samples_rad=(0.0, 0.35, 0.7), yaw_samples_rad=(0.0, 0.4, -0.4, 0.7, -0.7),
                         max_deviation_rad=math.radians(45.0))                  # the whole capture cone
    directions = approach_directions(outward, cfg)
    deviations = [d.deviation_rad for d in directions]
    assert deviations == sorted(deviations) and deviations[0] == 0.0
    assert max(deviations) <= cfg.max_deviation_rad + 1e-9
    # 15 combinations; (+-0.4, 0.7) at 45.2 deg and (+-0.7, 0.7) at 54 deg lie outside the cone
    assert len(directions) == 11
    assert {(d.yaw_rad, d.tilt_rad) for d in directions} == {
        (y, t) for y in cfg.yaw_samples_rad for t in cfg.tilt_samples_rad} - {(0.4, 0.7), (-0.4, 0.7), (0.7, 0.7),
                                                                               (-0.7, 0.7)}
    for d in directions:
        assert np.linalg.norm(d.vector) == pytest.approx(1.0)
        assert math.acos(np.clip(d.vector @ outward, -1, 1)) == pytest.approx(d.deviation_rad)
        assert math.asin(d.vector[2]) == pytest.approx(d.tilt_rad)
        assert math.atan2(-d.vector[0], d.vector[1]) == pytest.approx(d.yaw_rad)       # turned about +z
    # the planner's previous order when there is no yaw: the tilts in turn
    only_tilts = approach_directions(outward, ApproachConfig(yaw_samples_rad=(0.0,)))
    assert [(d.yaw_rad, d.tilt_rad) for d in only_tilts] == [(0.0, 0.0), (0.0, 0.3), (0.0, 0.6)]


def test_the_least_travel_candidate_is_chosen_without_obstacles():
    model = ArmCollisionModel()
    boll = np.array([0.6, 0.1, 0.1])
    outward = np.array([-1.0, 0.0, 0.0])
    cfg = ApproachConfig(tilt_samples_rad=(0.0,))
    result = plan_approach(boll, outward, STOW_RAD, model, None, cfg)
    assert result.ok
    # Brute force: every roll and branch, chains taken at the pre-grasp only.
    rolls = np.arange(cfg.roll_samples) * 2 * math.pi / cfg.roll_samples
    rot = tool_rotations(-outward, rolls)
    poses = np.tile(np.eye(4), (len(rolls), 1, 1))
    poses[:, :3, :3] = rot
    poses[:, :3, 3] = boll + (cfg.pregrasp_distance_m + NOZZLE_M) * outward
    q, _ = inverse_kinematics_batch(poses, STOW_RAD)
    transit = np.nansum(np.abs(q - STOW_RAD), axis=2)
    transit[~np.all(np.isfinite(q), axis=2)] = np.inf
    chosen = np.abs(result.plan.q_pregrasp_rad - STOW_RAD).sum()
    # The approach and retreat add little; the chosen transit is within them of the best.
    assert chosen <= transit.min() + 0.5
    assert result.plan.joint_travel_rad >= chosen


def test_unreachable_boll():
    model = ArmCollisionModel()
    result = plan_approach([1.8, 0.0, 0.2], [-1.0, 0.0, 0.0], STOW_RAD, model)
    assert result.reason == "unreachable" and result.plan is None
    assert "no arm configuration" in result.detail


def test_ik_failed_when_the_limits_exclude_every_configuration():
    model = ArmCollisionModel()
    narrow = TrajectoryConfig(lower_limits_rad=(1.4, -6.28, -3.14, -6.28, -6.28, -6.28),
                              upper_limits_rad=(1.7, 6.28, 3.14, 6.28, 6.28, 6.28))
    # Shoulder pan near pi/2 puts the arm's plane along y: it cannot reach a boll along +x.
    q0 = np.array([1.57, -2.2, 2.4, -1.77, -1.57, 0.0])
    result = plan_approach([0.6, 0.0, 0.1], [-1.0, 0.0, 0.0], q0, model, None, trajectory_config=narrow)
    assert result.reason == "ik_failed", result.detail


def test_collision_when_a_fence_stands_before_the_boll():
    model = ArmCollisionModel()
    boll = np.array([0.65, 0.0, 0.0])
    fence = [((0.62, y, -0.6), (0.62, y, 0.6), 0.02, f"post{i}") for i, y in enumerate(np.arange(-0.6, 0.61, 0.04))]
    fence += [((0.62, -0.6, z), (0.62, 0.6, z), 0.02, f"rail{i}") for i, z in enumerate(np.arange(-0.6, 0.61, 0.04))]
    result = plan_approach(boll, [-1.0, 0.0, 0.0], STOW_RAD, model, CapsuleSet.from_list(fence))
    assert result.reason == "collision" and result.plan is None
    assert "obstacle" in result.detail and result.candidates > 0


def test_tilted_up_and_tool_rotations():
    d = tilted_up(np.array([-1.0, 0.0, 0.0]), math.radians(30))
    np.testing.assert_allclose(d, [-math.cos(math.radians(30)), 0, math.sin(math.radians(30))], atol=1e-12)
    np.testing.assert_allclose(tilted_up(np.array([0, 0, 1.0]), 0.5), [0, 0, 1.0])
    rot = tool_rotations(np.array([0.0, 1.0, 0.0]), np.array([0.0, 1.0, 2.0]))
    for r in rot:
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        np.testing.assert_allclose(r[:, 2], [0, 1, 0], atol=1e-12)


def test_bad_input_is_rejected():
    model = ArmCollisionModel()
    with pytest.raises(ValueError, match="boll position"):
        plan_approach([0.5, np.nan, 0.0], [-1, 0, 0], STOW_RAD, model)
    with pytest.raises(ValueError, match="outward direction must not be zero"):
        plan_approach([0.5, 0.0, 0.0], [0, 0, 0], STOW_RAD, model)
    with pytest.raises(ValueError, match="outside the joint limits"):
        plan_approach([0.5, 0.0, 0.0], [-1, 0, 0], [0, 0, 4.0, 0, 0, 0], model)
    with pytest.raises(ValueError, match="current joints"):
        plan_approach([0.5, 0.0, 0.0], [-1, 0, 0], [0, 0, 0], model)
    with pytest.raises(ValueError, match="approach_steps"):
        ApproachConfig(approach_steps=1)
    with pytest.raises(ValueError, match="tilt_samples_rad"):
        ApproachConfig(tilt_samples_rad=(0.0, 2.0))
    for yaws in ((), (0.0, 2.0), [0.0, 0.4], (0.0, "0.4"), (0.0, float("nan")), (True,)):
        with pytest.raises(ValueError, match="yaw_samples_rad"):
            ApproachConfig(yaw_samples_rad=yaws)
    for deviation in (-0.1, 4.0, float("inf"), "0.5"):
        with pytest.raises(ValueError, match="max_deviation_rad"):
            ApproachConfig(max_deviation_rad=deviation)
    with pytest.raises(ValueError, match="every combination of tilt_samples_rad and yaw_samples_rad"):
        ApproachConfig(tilt_samples_rad=(0.7,), yaw_samples_rad=(0.7, -0.7))
    with pytest.raises(ValueError, match="pregrasp_distance_m"):
        ApproachConfig(pregrasp_distance_m=-0.1)


def test_a_via_point_takes_the_swings_to_and_from_the_bin_outside_the_plant(model):
    plants = plant_row()
    boll = np.array([0.9 - 0.2, 0.05, GROUND_Z_M + 0.6])
    outward = np.array([-1.0, 0.2, 0.0])
    config = ApproachConfig(via_distance_m=0.25)
    result = plan_approach(boll, outward, STOW_RAD, model, plants, config)
    assert result.ok, result.detail
    plan = result.plan
    direction = -plan.approach_direction
    # transit: start -> via -> pre-grasp; the retreat ends back at the via, where the move to the bin starts
    assert len(plan.transit.waypoints_rad) == 3
    np.testing.assert_allclose(plan.transit.waypoints_rad[0], STOW_RAD)
    for q in (plan.transit.waypoints_rad[1], plan.q_retreat_rad):
        tip, _ = tip_and_axis(q)
        np.testing.assert_allclose(tip, boll + 0.25 * direction, atol=1e-6)
    np.testing.assert_allclose(plan.retreat.waypoints_rad[-1], plan.q_retreat_rad)
    tip, _ = tip_and_axis(plan.q_pregrasp_rad)
    np.testing.assert_allclose(tip, boll + config.pregrasp_distance_m * direction, atol=1e-6)
    tip, _ = tip_and_axis(plan.q_grasp_rad)
    np.testing.assert_allclose(tip, boll, atol=1e-6)
    for traj in (plan.transit, plan.approach, plan.retreat):
        assert model.first_collision(traj, plants, step_rad=config.collision_step_rad / 4) is None
    # without the via (or one no farther out than the pre-grasp) the transit is one move
    for via in (0.0, 0.1):
        plain = plan_approach(boll, outward, STOW_RAD, model, plants, ApproachConfig(via_distance_m=via))
        assert len(plain.plan.transit.waypoints_rad) == 2
    with pytest.raises(ValueError, match="via <= 0.5 m"):
        ApproachConfig(via_distance_m=0.6)
