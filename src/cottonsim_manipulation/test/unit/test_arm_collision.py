"""Capsule collision checks: distances, the arm's capsules, plants, the robot's body, itself, paths."""
import math

import numpy as np
import pytest
from hand_built_scene import STOW_RAD, hand_plant, plant_row

from cottonsim_common.kinematics.ur5e import forward_kinematics, inverse_kinematics, link_frames
from cottonsim_common.capsules import CapsuleSet, point_segment_distance, segment_segment_distance
from cottonsim_common.kinematics.arm_capsules import ARM_LINKS, ArmCollisionConfig
from cottonsim_manipulation.planning.collision import (ArmCollisionModel, BoxSet, path_is_collision_free,
                                                      segment_box_distance)
from cottonsim_manipulation.planning.trajectory import plan_trajectory


def brute_segment_distance(p1, q1, p2, q2, n=801):
    s = np.linspace(0, 1, n)[:, None]
    a = p1 + s * (q1 - p1)
    b = p2 + s * (q2 - p2)
    return np.min(np.linalg.norm(a[:, None] - b[None], axis=2))


def test_segment_distances_match_brute_force():
    rng = np.random.default_rng(4)
    cases = [rng.normal(size=(4, 3)) for _ in range(150)]
    base = rng.normal(size=(4, 3))
    cases.append(np.array([base[0], base[1], base[0] + [0, 0, 1.0], base[1] + [0, 0, 1.0]]))  # parallel
    cases.append(np.array([base[0], base[0], base[2], base[3]]))                               # a point
    cases.append(np.array([base[0], base[0], base[2], base[2]]))                               # two points
    cases.append(np.array([[0, 0, 0], [1, 0, 0], [0.5, -1, 0], [0.5, 1, 0]]))                  # crossing: 0
    for p1, q1, p2, q2 in cases:
        got = segment_segment_distance(p1, q1, p2, q2)
        # The brute force samples the segments: it can only be above the truth, by < a step.
        assert got <= brute_segment_distance(p1, q1, p2, q2) + 1e-12
        assert got >= brute_segment_distance(p1, q1, p2, q2) - 5e-3
    assert segment_segment_distance(*cases[-1]) == pytest.approx(0.0, abs=1e-12)
    # Vectorised over leading axes.
    many = np.array(cases[:10])
    np.testing.assert_allclose(segment_segment_distance(many[:, 0], many[:, 1], many[:, 2], many[:, 3]),
                               [segment_segment_distance(*c) for c in cases[:10]])
    assert point_segment_distance(np.array([0, 1.0, 0]), np.zeros(3), np.array([2.0, 0, 0])) == pytest.approx(1.0)


def point_box_distance(x, centre, rot, half):
    local = (x - centre) @ rot
    return np.linalg.norm(np.maximum(np.abs(local) - half, 0.0), axis=-1)


def test_segment_box_distance_matches_brute_force():
    rng = np.random.default_rng(9)
    for _ in range(100):
        a = rng.normal(size=3)
        axis = a / np.linalg.norm(a)
        angle = rng.uniform(-math.pi, math.pi)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        rot = np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k
        centre, half = rng.normal(size=3), rng.uniform(0.05, 0.6, 3)
        p, q = rng.normal(size=3) * 1.5, rng.normal(size=3) * 1.5
        got = segment_box_distance(p, q, centre, rot, half)
        pts = p + np.linspace(0, 1, 4001)[:, None] * (q - p)
        brute = point_box_distance(pts, centre, rot, half).min()
        assert got == pytest.approx(brute, abs=2e-4)
        assert got <= brute + 1e-9
    # A segment through a box is at distance 0.
    assert segment_box_distance(np.array([-1.0, 0, 0]), np.array([1.0, 0, 0]), np.zeros(3), np.eye(3),
                                np.array([0.1, 0.1, 0.1])) == 0.0


def test_bounding_tests_never_hide_a_contact(body):
    """The broad phases give the same clearances as computing every pair exactly."""
    model = ArmCollisionModel(body=body)
    rng = np.random.default_rng(12)
    q = rng.uniform(-math.pi, math.pi, (300, 6))
    starts = rng.uniform(-0.9, 0.9, (40, 3))
    ends = starts + rng.normal(0.0, 0.3, (40, 3))
    obstacles = CapsuleSet(starts, ends, rng.uniform(0.0, 0.05, 40))
    obstacle, body_c, _ = model.clearances(q, obstacles)
    start, end = model.capsules(q)
    grown = model.config.radii_m + model.config.padding_m
    exact = segment_segment_distance(start[:, :, None], end[:, :, None], starts[None, None], ends[None, None])
    exact = exact - grown[None, :, None] - obstacles.radius_m[None, None]
    finite = np.isfinite(obstacle)
    np.testing.assert_allclose(obstacle[finite], exact[finite], atol=1e-12)
    assert np.all(exact[~finite] > 0.0)                      # only clear pairs were skipped
    assert (exact < 0).sum() > 100                          # and the case has contacts to find
    links = model.body_links
    box_exact = segment_box_distance(start[:, links, None], end[:, links, None], body.centre_m[None, None],
                                     body.rotation[None, None], body.half_extents_m[None, None])
    box_exact = box_exact - grown[links][None, :, None]
    finite = np.isfinite(body_c)
    np.testing.assert_allclose(body_c[finite], box_exact[finite], atol=1e-6)
    assert np.all(box_exact[~finite] > 0.0)
    assert (box_exact < 0).sum() > 100


def test_arm_capsules_sit_on_the_dh_frames():
    model = ArmCollisionModel()
    cfg = model.config
    q = np.array([0.3, -1.0, 1.2, -0.4, 0.8, 0.1])
    start, end = model.capsules(q)
    f = link_frames(q)
    assert start.shape == end.shape == (1, len(ARM_LINKS), 3)
    idx = {name: i for i, name in enumerate(ARM_LINKS)}
    np.testing.assert_allclose(end[0, idx["base"]], [0, 0, 0.1625])
    np.testing.assert_allclose(end[0, idx["shoulder"]], f[1][:3, 3] + cfg.shoulder_offset_m * f[1][:3, 2])
    # The upper-arm tube runs parallel to the DH upper arm, 0.425 m long.
    tube = end[0, idx["upper_arm"]] - start[0, idx["upper_arm"]]
    assert np.linalg.norm(tube) == pytest.approx(0.425)
    np.testing.assert_allclose(start[0, idx["wrist_2"]], f[4][:3, 3])
    np.testing.assert_allclose(end[0, idx["wrist_2"]], f[5][:3, 3])
    flange = forward_kinematics(q)
    np.testing.assert_allclose(start[0, idx["nozzle"]], flange[:3, 3])
    np.testing.assert_allclose(end[0, idx["nozzle"]], flange[:3, 3] + 0.12 * flange[:3, 2])  # 0.15 - 0.03 allowance


def test_a_stem_through_the_forearm_is_found_and_a_clear_one_passes():
    model = ArmCollisionModel()
    q = np.array([0.2, -1.3, 1.6, -1.9, -1.5, 0.0])
    start, end = model.capsules(q)
    mid = (start[0, ARM_LINKS.index("forearm")] + end[0, ARM_LINKS.index("forearm")]) / 2
    stem = CapsuleSet.from_list([(mid - [0, 0, 0.5], mid + [0, 0, 0.5], 0.008, "stem")])
    contacts = model.contacts(q, stem)
    assert any(c.link == "forearm" and c.other == "stem" and c.kind == "obstacle" for c in contacts)
    assert model.in_collision(q, stem)[0]
    # 5 cm beside the tube's surface (radius 38 mm + 10 mm padding + 8 mm stem): clear.
    side = np.cross(end[0, 4] - start[0, 4], [0, 0, 1.0])
    away = mid + (0.038 + 0.01 + 0.008 + 0.05) * side / np.linalg.norm(side)
    far_stem = CapsuleSet.from_list([(away - [0, 0, 0.5], away + [0, 0, 0.5], 0.008, "stem")])
    assert not model.in_collision(q, far_stem)[0]
    obstacle, _, _ = model.clearances(q, far_stem)
    assert np.min(obstacle) == pytest.approx(0.05, abs=0.03)


def test_hand_built_plant_blocks_a_sweep_through_it():
    model = ArmCollisionModel()
    plants = plant_row()
    # Nozzle tip at the middle plant's stem height 0.4 m above the ground: inside the canopy.
    into = np.eye(4)
    into[:3, :3] = [[0, 0, 1], [0, -1, 0], [1, 0, 0]]                     # tool z along +x
    into[:3, 3] = [0.9 - 0.15 + 0.02, 0.0, -0.383 + 0.45]                 # tip 2 cm past the stem
    q_in = inverse_kinematics(into, STOW_RAD).best
    assert q_in is not None
    hits = model.contacts(q_in, plants)
    assert any(c.kind == "obstacle" and c.other.startswith("p1/") for c in hits)
    # The stow pose is clear; the path into the plant is not, and the hit comes after the start.
    assert not model.in_collision(STOW_RAD, plants)[0]
    contact = model.first_collision(np.stack([STOW_RAD, q_in]), plants, step_rad=0.02)
    assert contact is not None and contact.sample > 0
    assert not path_is_collision_free(plan_trajectory([STOW_RAD, q_in]), plants, 0.02, model)
    # Without the plants the same path is free.
    assert path_is_collision_free(np.stack([STOW_RAD, q_in]), None, 0.02, model)


def test_self_collision_of_a_folded_arm():
    model = ArmCollisionModel()
    folded = np.array([0.0, -1.0, math.pi, 0.0, 0.0, 0.0])   # forearm folded back onto the upper arm
    hits = model.contacts(folded)
    assert any(c.kind == "self" for c in hits), hits
    assert not model.in_collision(np.array([0.0, -1.0, 1.5, -1.5, -1.5, 0.0]))[0]
    # Neighbouring capsules touch by construction and are never reported.
    for c in model.contacts(np.random.default_rng(0).uniform(-3, 3, (200, 6))):
        if c.kind == "self":
            assert abs(ARM_LINKS.index(c.link) - ARM_LINKS.index(c.other)) >= 3


def test_body_boxes_block_the_nozzle_into_the_robot(model):
    # Flange 0.1 m above the control box (behind the arm, arm +y), nozzle pointing down into it.
    down = np.eye(4)
    down[:3, :3] = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]
    down[:3, 3] = [0.0, 0.38, 0.15 + 0.1]
    q = inverse_kinematics(down, STOW_RAD).best
    hits = model.contacts(q)
    assert any(c.kind == "body" and c.link == "nozzle" and c.other.startswith("ur5e_control_box_link") for c in hits)
    # The same pose 0.3 m higher is clear of the body.
    down[2, 3] += 0.3
    assert not model.in_collision(inverse_kinematics(down, STOW_RAD).best)[0]
    assert not model.in_collision(STOW_RAD)[0]


def test_path_check_samples_finely_enough_to_see_a_thin_branch():
    model = ArmCollisionModel()
    # The nozzle sweeps sideways past a branch across its path: both ends clear, the middle not.
    q0 = np.array([0.0, -1.2, 1.4, -1.8, -1.57, 0.0])
    q1 = q0 + [0.5, 0, 0, 0, 0, 0]
    mid = np.array(model.capsules(q0 + [0.25, 0, 0, 0, 0, 0]))[:, 0, ARM_LINKS.index("nozzle")].mean(axis=0)
    branch = CapsuleSet.from_list([(mid - [0, 0, 0.05], mid + [0, 0, 0.05], 0.004, "branch")])
    assert not model.in_collision(np.stack([q0, q1]), branch).any()
    assert not model.path_is_collision_free(np.stack([q0, q1]), branch, step_rad=0.02)


def test_inputs_are_validated():
    with pytest.raises(ValueError, match="CapsuleSet needs"):
        CapsuleSet(np.zeros((2, 3)), np.zeros((3, 3)), np.zeros(2))
    with pytest.raises(ValueError, match="NaN"):
        CapsuleSet(np.full((1, 3), np.nan), np.zeros((1, 3)), np.ones(1))
    with pytest.raises(ValueError, match="radius_m"):
        CapsuleSet(np.zeros((1, 3)), np.zeros((1, 3)), -np.ones(1))
    with pytest.raises(ValueError, match="rotation matrices"):
        BoxSet(np.zeros((1, 3)), 2 * np.eye(3)[None], np.ones((1, 3)))
    with pytest.raises(ValueError, match="max corner"):
        BoxSet.axis_aligned([((0, 0, 0), (-1, 1, 1), "bad")])
    with pytest.raises(ValueError, match="padding_m"):
        ArmCollisionConfig(padding_m=-0.1)
    with pytest.raises(ValueError, match="nozzle_tip_allowance_m"):
        ArmCollisionConfig(nozzle_length_m=0.02, nozzle_tip_allowance_m=0.03)
    with pytest.raises(ValueError, match="obstacles must be a CapsuleSet"):
        ArmCollisionModel().contacts(np.zeros(6), [((0, 0, 0), (0, 0, 1), 0.1, "x")])
    with pytest.raises(ValueError, match="body must be a BoxSet"):
        ArmCollisionModel(body=CapsuleSet.empty())
    with pytest.raises(ValueError, match="NaN"):
        ArmCollisionModel().in_collision(np.array([0, 0, np.nan, 0, 0, 0]))
    plant = CapsuleSet.from_list(hand_plant(0.9, 0.0))
    shift = np.eye(4)
    shift[0, 3] = 1.0
    moved = plant.transformed(shift)
    np.testing.assert_allclose(moved.start_m[:, 0], plant.start_m[:, 0] + 1.0)
