"""Unit tests of the UR5e forward kinematics and position follower."""
import math

import numpy as np
import pytest

from cottonsim_world.robot.ur5e import (
    JOINT_NAMES,
    Ur5eArm,
    Ur5eKinematics,
    forward_kinematics,
)
from cottonsim_world.robot.urdf_model import JointLimits, UrdfModel, axis_angle_matrix

D1, A2, A3, D4, D5, D6 = 0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996
PI = math.pi


def test_fk_zero_pose_hand_derived():
    # q = 0: the arm lies stretched out along base -x; the wrist offsets d4 and
    # d6 both point along base -y and d5 points down.
    t = forward_kinematics(np.zeros(6))
    np.testing.assert_allclose(t[:3, 3], [A2 + A3, -(D4 + D6), D1 - D5], atol=1e-12)
    np.testing.assert_allclose(t[:3, 3], [-0.8172, -0.2329, 0.0628], atol=1e-12)
    # tool0 z (out of the flange) points along base -y, tool0 x along base +x.
    np.testing.assert_allclose(t[:3, 2], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(t[:3, 0], [1, 0, 0], atol=1e-12)


def test_fk_upright_pose_hand_derived():
    # shoulder_lift = -pi/2 turns the upper arm and forearm straight up,
    # wrist_1 = -pi/2 then points d5 up as well.
    t = forward_kinematics([0, -PI / 2, 0, -PI / 2, 0, 0])
    np.testing.assert_allclose(t[:3, 3], [0, -(D4 + D6), D1 - A2 - A3 + D5], atol=1e-12)
    np.testing.assert_allclose(t[:3, 2], [0, -1, 0], atol=1e-12)


def test_fk_invariants():
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-PI, PI, 6)
        t = forward_kinematics(q)
        # A proper rigid transform.
        np.testing.assert_allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-12)
        assert np.linalg.det(t[:3, :3]) == pytest.approx(1.0)
        # Shoulder pan rotates the whole pose about base z.
        theta = rng.uniform(-PI, PI)
        turned = forward_kinematics(q + np.array([theta, 0, 0, 0, 0, 0]))
        rz = np.eye(4)
        rz[:3, :3] = axis_angle_matrix(np.array([0, 0, 1.0]), theta)
        np.testing.assert_allclose(turned, rz @ t, atol=1e-12)
        # Wrist 3 spins the tool about its own z: position and z axis stay.
        spun = forward_kinematics(q + np.array([0, 0, 0, 0, 0, theta]))
        np.testing.assert_allclose(spun[:3, 3], t[:3, 3], atol=1e-12)
        np.testing.assert_allclose(spun[:3, 2], t[:3, 2], atol=1e-12)
        # The flange never leaves the reach sphere around the shoulder.
        reach = abs(A2) + abs(A3) + math.hypot(D4 + D6, D5)
        assert np.linalg.norm(t[:3, 3] - [0, 0, D1]) <= reach + 1e-9


def test_fk_rejects_bad_input():
    with pytest.raises(ValueError, match="6 values"):
        forward_kinematics([0, 0, 0])
    with pytest.raises(ValueError, match="NaN"):
        forward_kinematics([0, 0, float("nan"), 0, 0, 0])
    with pytest.raises(ValueError, match="a2_m"):
        Ur5eKinematics(a2_m=float("inf"))


def test_urdf_chain_matches_dh(robot_model):
    rng = np.random.default_rng(11)
    for q in [np.zeros(6), *rng.uniform(-2 * PI, 2 * PI, (4, 6))]:
        positions = {"ur5e_" + name: value for name, value in zip(JOINT_NAMES, q)}
        urdf_pose = robot_model.transform("ur5e_base", "ur5e_tool0", positions)
        # 1e-8: the URDF stores angles with 10 significant digits.
        np.testing.assert_allclose(urdf_pose, forward_kinematics(q), atol=1e-8)


def make_arm(**kwargs):
    limits = [JointLimits(-2 * PI, 2 * PI, PI, 150.0)] * 3 + [JointLimits(-2 * PI, 2 * PI, PI, 28.0)] * 3
    limits[2] = JointLimits(-PI, PI, PI, 150.0)
    return Ur5eArm(limits, **kwargs)


def test_follower_moves_at_velocity_limit_and_stops_on_target():
    arm = make_arm()
    arm.command([1.0, -0.5, 0.0, 0.0, 0.0, 0.1])
    dt = 0.1
    arm.step(dt)
    # pi rad/s * 0.1 s = 0.314 rad per step at most.
    np.testing.assert_allclose(arm.positions, [PI * dt, -PI * dt, 0, 0, 0, 0.1], atol=1e-12)
    np.testing.assert_allclose(arm.velocities, [PI, -PI, 0, 0, 0, 1.0], atol=1e-12)
    steps = 1
    while not arm.at_target():
        arm.step(dt)
        steps += 1
        assert steps < 100
    # 1.0 rad at 0.314 rad/step -> ceil(3.18) = 4 steps.
    assert steps == math.ceil(1.0 / (PI * dt))
    np.testing.assert_allclose(arm.positions, [1.0, -0.5, 0, 0, 0, 0.1], atol=1e-12)
    arm.step(dt)
    np.testing.assert_allclose(arm.velocities, 0.0)


def test_follower_clamps_targets_to_position_limits():
    arm = make_arm()
    clamped = arm.command([0, 0, 4.0, 0, 0, -10.0])
    assert clamped[2] == pytest.approx(PI)  # elbow limited to +/-pi
    assert clamped[5] == pytest.approx(-2 * PI)
    for _ in range(100):
        arm.step(0.05)
    assert arm.positions[2] == pytest.approx(PI)
    assert np.all(np.abs(arm.positions) <= 2 * PI + 1e-12)


def test_follower_dict_command_and_errors():
    arm = make_arm(initial_positions=[0.1, 0, 0, 0, 0, 0])
    arm.command({"wrist_2_joint": 0.2})
    np.testing.assert_allclose(arm.targets, [0.1, 0, 0, 0, 0.2, 0])
    with pytest.raises(ValueError, match="unknown UR5e joint"):
        arm.command({"elbow": 1.0})
    with pytest.raises(ValueError, match="NaN"):
        arm.command([0, 0, 0, float("nan"), 0, 0])
    with pytest.raises(ValueError, match="dt_s"):
        arm.step(0.0)
    with pytest.raises(ValueError, match="dt_s"):
        arm.step(float("nan"))
    with pytest.raises(ValueError, match="outside the position limits"):
        make_arm(initial_positions=[0, 0, 4.0, 0, 0, 0])
    with pytest.raises(ValueError, match="6 JointLimits"):
        Ur5eArm([JointLimits(-1, 1, 1, 1)])
    with pytest.raises(ValueError, match="velocity must be > 0"):
        Ur5eArm([JointLimits(-1, 1, 0.0, 1)] * 6)


def test_arm_from_urdf_uses_the_published_limits(robot_model):
    arm = Ur5eArm.from_urdf(robot_model)
    lowers = [lim.lower for lim in arm.limits]
    np.testing.assert_allclose(lowers, [-2 * PI, -2 * PI, -PI, -2 * PI, -2 * PI, -2 * PI], atol=1e-8)
    np.testing.assert_allclose([lim.velocity for lim in arm.limits], [PI] * 6, atol=1e-8)
    np.testing.assert_allclose([lim.effort for lim in arm.limits], [150, 150, 150, 28, 28, 28])
    np.testing.assert_allclose(arm.tool_pose(), forward_kinematics(np.zeros(6)))


@pytest.fixture(scope="module")
def robot_model():
    import pathlib

    root = pathlib.Path(__file__).resolve().parents[4]
    return UrdfModel.from_file(root / "src/cottonsim_description/urdf/cottonsim_robot.urdf")
