"""UR5e forward and closed-form inverse kinematics (cottonsim_common.kinematics.ur5e)."""
import math

import numpy as np
import pytest

from cottonsim_common.kinematics.ur5e import (
    BRANCHES,
    UR5E_LOWER_LIMITS_RAD,
    UR5E_UPPER_LIMITS_RAD,
    IkConfig,
    Ur5eKinematics,
    branch_of,
    forward_kinematics,
    inverse_kinematics,
    inverse_kinematics_batch,
    link_frames,
    wrap_into_limits,
)

PI = math.pi
LOWER = np.array(UR5E_LOWER_LIMITS_RAD)
UPPER = np.array(UR5E_UPPER_LIMITS_RAD)
KIN = Ur5eKinematics()


def rotation_angle(r_a, r_b):
    """Angle of the rotation between two rotation matrices [rad] (accurate for small angles)."""
    d = r_a.T @ r_b
    skew = np.array([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]]) / 2.0
    return math.atan2(np.linalg.norm(skew), (np.trace(d) - 1.0) / 2.0)


def assert_pose_matches(q, pose, tol_m=1e-6, tol_rad=1e-6):
    got = forward_kinematics(q)
    assert np.linalg.norm(got[:3, 3] - pose[:3, 3]) <= tol_m, (q, got[:3, 3], pose[:3, 3])
    assert rotation_angle(got[:3, :3], pose[:3, :3]) <= tol_rad, q


def test_dh_table_is_the_published_ur5e():
    assert KIN.dh_table() == (
        (0.0, PI / 2, 0.1625),
        (-0.425, 0.0, 0.0),
        (-0.3922, 0.0, 0.0),
        (0.0, PI / 2, 0.1333),
        (0.0, -PI / 2, 0.0997),
        (0.0, 0.0, 0.0996),
    )
    assert UR5E_LOWER_LIMITS_RAD == (-2 * PI, -2 * PI, -PI, -2 * PI, -2 * PI, -2 * PI)
    assert KIN.max_reach_m == pytest.approx(0.425 + 0.3922 + math.hypot(0.1333 + 0.0996, 0.0997))


def test_link_frames_chain_up_to_forward_kinematics():
    rng = np.random.default_rng(1)
    qs = rng.uniform(LOWER, UPPER, (20, 6))
    frames = link_frames(qs)
    assert frames.shape == (20, 7, 4, 4)
    for q, f in zip(qs, frames):
        np.testing.assert_allclose(f[6], forward_kinematics(q), atol=1e-12)
        np.testing.assert_allclose(link_frames(q), f, atol=1e-12)
        np.testing.assert_allclose(f[0], np.eye(4))
        # Frame 1 sits on the shoulder at height d1 whatever the joints.
        np.testing.assert_allclose(f[1][:3, 3], [0, 0, 0.1625], atol=1e-12)
    with pytest.raises(ValueError, match="shape"):
        link_frames(np.zeros((3, 5)))
    with pytest.raises(ValueError, match="NaN"):
        link_frames([0, 0, np.nan, 0, 0, 0])


def test_round_trip_on_thousands_of_random_configurations_every_branch():
    """FK then IK with the configuration as reference gives it back first; every solution is exact."""
    rng = np.random.default_rng(2024)
    seen = {b: 0 for b in BRANCHES}
    solution_counts = []
    for _ in range(3000):
        q = rng.uniform(LOWER, UPPER)
        pose = forward_kinematics(q)
        result = inverse_kinematics(pose, q)
        assert result.ok, (q, result.status)
        np.testing.assert_allclose(result.solutions[0], q, atol=1e-8)
        assert result.distances[0] < 1e-8
        assert result.branches[0] == branch_of(q)
        seen[branch_of(q)] += 1
        solution_counts.append(len(result.solutions))
        assert np.all(np.diff(result.distances) >= 0.0)
        assert np.all(result.solutions >= LOWER) and np.all(result.solutions <= UPPER)
        for sol, label in zip(result.solutions, result.branches):
            assert_pose_matches(sol, pose)
            assert branch_of(sol) == label
        assert len(set(result.branches)) == len(result.branches)
    # Every one of the 8 branches is hit often. Poses far from the base have all 8 solutions;
    # for others the second shoulder solution puts the wrist out of the elbow's reach (4).
    assert min(seen.values()) > 300, seen
    assert set(solution_counts) <= {2, 4, 6, 8}
    assert np.mean(np.array(solution_counts) == 8) > 0.5


def test_round_trip_with_an_unrelated_reference_wraps_nearest_it():
    rng = np.random.default_rng(7)
    for _ in range(1000):
        q = rng.uniform(LOWER, UPPER)
        ref = rng.uniform(LOWER, UPPER)
        pose = forward_kinematics(q)
        result = inverse_kinematics(pose, ref)
        assert result.ok
        for sol in result.solutions:
            assert_pose_matches(sol, pose)
            # Each joint is on the turn nearest the reference unless that turn leaves its limits.
            for j in range(6):
                other = sol[j] - 2 * PI * np.sign(sol[j] - ref[j])
                assert abs(sol[j] - ref[j]) <= abs(other - ref[j]) + 1e-9 or not (LOWER[j] <= other <= UPPER[j])
        # q itself (modulo whole turns) is among the solutions.
        diffs = np.abs(np.mod(result.solutions - q + PI, 2 * PI) - PI).max(axis=1)
        assert diffs.min() < 1e-8


def test_batch_matches_single_solves():
    rng = np.random.default_rng(5)
    qs = rng.uniform(LOWER, UPPER, (200, 6))
    poses = link_frames(qs)[:, 6]
    ref = np.array([0.1, -1.0, 1.0, -1.5, -1.57, 0.0])
    batch, singular = inverse_kinematics_batch(poses, ref)
    assert batch.shape == (200, 8, 6) and singular.shape == (200, 3)
    for pose, sols in zip(poses, batch):
        single = inverse_kinematics(pose, ref)
        finite = sols[np.all(np.isfinite(sols), axis=1)]
        for s in single.solutions:
            assert np.abs(finite - s).max(axis=1).min() < 1e-12


@pytest.mark.parametrize("q5", [0.0, 1e-12, -3e-8, PI, PI - 1e-10])
def test_wrist_singularity_gives_a_consistent_solution(q5):
    """Axes 4 and 6 aligned: no NaN, q6 stays at the reference, q4 takes the rotation."""
    q = np.array([0.4, -1.1, 1.3, -0.9, q5, 0.8])
    pose = forward_kinematics(q)
    ref = np.array([0.3, -1.0, 1.2, -1.0, 0.0, -0.5])
    result = inverse_kinematics(pose, ref)
    assert result.ok and "wrist" in result.singular
    assert np.all(np.isfinite(result.solutions))
    singular = [sol for sol in result.solutions if abs(math.sin(sol[4])) < 1e-7]
    assert len(singular) == 2  # elbow up and down; the two wrist branches coincide
    for sol in result.solutions:
        assert_pose_matches(sol, pose)
    for sol in singular:
        assert sol[5] == pytest.approx(-0.5, abs=1e-12)
        assert sol[4] == pytest.approx(0.0 if abs(q5) < 1 else PI, abs=1e-12)
    # The other shoulder solution is not at the singularity: 4 more at most.
    assert len(result.solutions) <= 6


def test_near_but_not_at_the_wrist_singularity_is_exact():
    q = np.array([0.4, -1.1, 1.3, -0.9, 1e-5, 0.8])
    pose = forward_kinematics(q)
    result = inverse_kinematics(pose, q)
    assert "wrist" not in result.singular
    np.testing.assert_allclose(result.solutions[0], q, atol=1e-8)


def shoulder_singular_configuration(q3):
    """Joints that put the wrist point p05 on the base cylinder r = d4 (shoulder singularity)."""
    a2, a3 = KIN.a2_m, KIN.a3_m
    # Frame 3 straight above the shoulder: a2 cos q2 + a3 cos(q2 + q3) = 0.
    q2 = math.atan2(a2 + a3 * math.cos(q3), a3 * math.sin(q3))
    q4 = -PI - q2 - q3  # z4 vertical: p05 = p03 + d4 z3 + d5 z4 stays above the base, d4 aside
    return np.array([0.3, q2, q3, q4, 0.9, 0.2])


@pytest.mark.parametrize("q3", [0.7, -0.7, 1.5])
def test_shoulder_singularity_gives_a_consistent_solution(q3):
    q = shoulder_singular_configuration(q3)
    frames = link_frames(q)
    assert math.hypot(*frames[5][:2, 3]) == pytest.approx(KIN.d4_m, abs=1e-12)
    pose = forward_kinematics(q)
    result = inverse_kinematics(pose, q)
    assert result.ok and "shoulder" in result.singular
    assert np.all(np.isfinite(result.solutions))
    for sol in result.solutions:
        assert_pose_matches(sol, pose)
    np.testing.assert_allclose(result.solutions[0], q, atol=1e-6)
    # The two shoulder branches coincide: at most 4 distinct solutions.
    assert len(result.solutions) <= 4


def test_inside_the_base_cylinder_and_out_of_reach_are_unreachable():
    q = shoulder_singular_configuration(0.7)
    pose = forward_kinematics(q)
    p05 = link_frames(q)[5][:3, 3]
    inside = pose.copy()
    # Move the whole pose 1 cm towards the base axis: the wrist point is then at r = d4 - 1 cm.
    inside[:2, 3] -= 0.01 * p05[:2] / np.linalg.norm(p05[:2])
    assert inverse_kinematics(inside).status == "unreachable"
    far = np.eye(4)
    far[:3, 3] = [1.5, 0.2, 0.4]
    result = inverse_kinematics(far)
    assert result.status == "unreachable" and not result.ok and result.best is None
    assert result.solutions.shape == (0, 6)
    # A wrist point on the base axis is inside the cylinder.
    axis_pose = np.eye(4)
    axis_pose[:3, 3] = [0.0, 0.0, 0.5 + KIN.d6_m]
    assert inverse_kinematics(axis_pose).status == "unreachable"


def test_stretched_elbow_is_solved_on_the_edge_and_beyond_is_unreachable():
    q = np.array([0.2, -0.8, 0.0, -1.0, 1.2, 0.3])  # q3 = 0: upper arm and forearm in line
    pose = forward_kinematics(q)
    result = inverse_kinematics(pose, q)
    assert result.ok and "elbow" in result.singular
    np.testing.assert_allclose(result.solutions[0], q, atol=1e-6)
    for sol in result.solutions:
        assert_pose_matches(sol, pose)
    # 1 mm further along the arm's direction is beyond the stretched arm.
    beyond = pose.copy()
    shoulder = np.array([0.0, 0.0, KIN.d1_m])
    direction = link_frames(q)[3][:3, 3] - link_frames(q)[1][:3, 3]
    beyond[:3, 3] += 1e-3 * direction / np.linalg.norm(direction)
    assert np.linalg.norm(beyond[:3, 3] - shoulder) > np.linalg.norm(pose[:3, 3] - shoulder)
    assert inverse_kinematics(beyond, q).status == "unreachable"


def test_joint_limits_filter_solutions():
    q = np.array([0.2, -1.2, 1.4, -1.5, -1.4, 0.1])
    pose = forward_kinematics(q)
    narrow = IkConfig(lower_limits_rad=(-0.5, -2.0, 0.0, -3.0, -3.0, -3.0), upper_limits_rad=(0.5, 0.0, 3.0, 0.0, 0.0, 3.0))
    result = inverse_kinematics(pose, np.zeros(6), config=narrow)
    assert result.ok
    np.testing.assert_allclose(result.solutions[0], q, atol=1e-8)
    for sol in result.solutions:
        assert np.all(sol >= np.array(narrow.lower_limits_rad)) and np.all(sol <= np.array(narrow.upper_limits_rad))
    tiny = IkConfig(lower_limits_rad=(2.0,) + narrow.lower_limits_rad[1:], upper_limits_rad=(2.5,) + narrow.upper_limits_rad[1:])
    assert inverse_kinematics(pose, config=tiny).status == "out_of_limits"


def test_wrap_into_limits_takes_the_nearest_turn_inside():
    lower, upper = LOWER, UPPER
    q = np.array([3.0, -3.0, 3.0, -0.1, 6.0, -6.2])
    ref = np.array([-3.0, 3.0, 0.0, 6.2, 0.0, 0.0])
    got = wrap_into_limits(q, ref, lower, upper)
    np.testing.assert_allclose(got, [3.0 - 2 * PI, -3.0 + 2 * PI, 3.0, -0.1 + 2 * PI, 6.0 - 2 * PI, -6.2 + 2 * PI])
    # No turn puts 2 rad inside limits of +-1 rad: NaN.
    narrow = np.where(np.arange(6) == 2, 1.0, upper)
    got = wrap_into_limits(np.array([0, 0, 2.0, 0, 0, 0]), np.zeros(6), -narrow, narrow)
    assert np.isnan(got[2]) and np.all(got[[0, 1, 3, 4, 5]] == 0.0)


def test_bad_input_is_rejected_with_a_clear_error():
    pose = forward_kinematics(np.zeros(6))
    with pytest.raises(ValueError, match="4x4"):
        inverse_kinematics(np.eye(3))
    nan_pose = pose.copy()
    nan_pose[0, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        inverse_kinematics(nan_pose)
    skew = pose.copy()
    skew[:3, :3] *= 1.1
    with pytest.raises(ValueError, match="orthonormal"):
        inverse_kinematics(skew)
    with pytest.raises(ValueError, match="reference joints"):
        inverse_kinematics(pose, [0, 0, 0])
    with pytest.raises(ValueError, match="reference joints"):
        inverse_kinematics_batch(pose[None], [0, 0, np.nan, 0, 0, 0])
    with pytest.raises(ValueError, match="lower"):
        IkConfig(lower_limits_rad=(1.0,) * 6, upper_limits_rad=(0.0,) * 6)
    with pytest.raises(ValueError, match="joint_weights"):
        IkConfig(joint_weights=(1, 1, 1, 1, 1, 0))
    with pytest.raises(ValueError, match="wrist_singular_sin"):
        IkConfig(wrist_singular_sin=0.5)
    with pytest.raises(ValueError, match="a2_m"):
        Ur5eKinematics(a2_m=0.0)
