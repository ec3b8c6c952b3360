"""Unit tests of the pure-Python URDF reader (cottonsim_world.robot.urdf_model).

Small hand-written URDFs whose transforms are computed by hand, plus the
error cases for malformed input.
"""
import math

import numpy as np
import pytest

from cottonsim_common.transforms import invert

from cottonsim_world.robot.urdf_model import (
    JointLimits,
    UrdfModel,
    axis_angle_matrix,
    pose_matrix,
    rpy_matrix,
)

# base -> arm (revolute about z, 1 m up) -> hand (fixed, 0.5 m along arm x)
# base -> cam (fixed, yawed +90 deg, at y = 0.2)
# base -> slider (prismatic along x)
TREE = """<?xml version="1.0"?>
<robot name="toy">
  <link name="base"/>
  <link name="arm"><visual><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.05 0.05"/></geometry></visual></link>
  <link name="hand"/>
  <link name="cam"><inertial><mass value="0.5"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="slider"/>
  <joint name="arm_joint" type="revolute">
    <parent link="base"/><child link="arm"/>
    <origin xyz="0 0 1" rpy="0 0 0"/><axis xyz="0 0 2"/>
    <limit lower="-1.5" upper="1.5" velocity="2" effort="10"/>
  </joint>
  <joint name="hand_joint" type="fixed">
    <parent link="arm"/><child link="hand"/><origin xyz="0.5 0 0"/>
  </joint>
  <joint name="cam_joint" type="fixed">
    <parent link="base"/><child link="cam"/><origin xyz="0 0.2 0" rpy="0 0 1.5707963267948966"/>
  </joint>
  <joint name="slide_joint" type="prismatic">
    <parent link="base"/><child link="slider"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.3" velocity="0.1" effort="100"/>
  </joint>
</robot>
"""


def rot_x(a):
    return axis_angle_matrix(np.array([1.0, 0, 0]), a)


def rot_y(a):
    return axis_angle_matrix(np.array([0, 1.0, 0]), a)


def rot_z(a):
    return axis_angle_matrix(np.array([0, 0, 1.0]), a)


@pytest.fixture(scope="module")
def toy():
    return UrdfModel.from_string(TREE)


def test_parses_links_joints_and_root(toy):
    assert toy.name == "toy"
    assert set(toy.links) == {"base", "arm", "hand", "cam", "slider"}
    assert list(toy.joints) == ["arm_joint", "hand_joint", "cam_joint", "slide_joint"]
    assert toy.root == "base"
    assert toy.links["cam"].mass_kg == 0.5
    assert toy.links["arm"].visuals[0].kind == "box"
    np.testing.assert_allclose(toy.links["arm"].visuals[0].origin[:3, 3], [0.1, 0, 0])
    # The axis is normalised.
    np.testing.assert_allclose(toy.joints["arm_joint"].axis, [0, 0, 1])
    assert toy.joint_limits("arm_joint") == JointLimits(-1.5, 1.5, 2.0, 10.0)
    assert [j.name for j in toy.movable_joints()] == ["arm_joint", "slide_joint"]
    assert toy.parent_joint("hand").name == "hand_joint"
    assert toy.parent_joint("base") is None


def test_rpy_is_fixed_axis_roll_then_pitch_then_yaw():
    r, p, y = 0.3, -0.7, 1.9
    np.testing.assert_allclose(rpy_matrix(r, p, y), rot_z(y) @ rot_y(p) @ rot_x(r), atol=1e-12)
    # Positive pitch turns +x downwards (REP-103).
    assert rpy_matrix(0, 0.1, 0)[2, 0] < 0


def test_transform_down_the_tree_with_joint_position(toy):
    q = 0.4
    t = toy.transform("base", "hand", {"arm_joint": q})
    # hand = 1 m up, then 0.5 m along the arm's x rotated by q about z.
    np.testing.assert_allclose(t[:3, 3], [0.5 * math.cos(q), 0.5 * math.sin(q), 1.0], atol=1e-12)
    np.testing.assert_allclose(t[:3, :3], rot_z(q), atol=1e-12)


def test_fixed_transform_and_inverse(toy):
    t = toy.fixed_transform("base", "cam")
    np.testing.assert_allclose(t[:3, 3], [0, 0.2, 0], atol=1e-12)
    # cam x axis points along base +y (yaw +90 deg).
    np.testing.assert_allclose(t[:3, 0], [0, 1, 0], atol=1e-12)
    back = toy.fixed_transform("cam", "base")
    np.testing.assert_allclose(back @ t, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(toy.fixed_transform("arm", "arm"), np.eye(4))


def test_transform_between_siblings_goes_through_common_ancestor(toy):
    q = -0.9
    t = toy.transform("cam", "hand", {"arm_joint": q})
    expected = invert(toy.fixed_transform("base", "cam")) @ toy.transform("base", "hand", {"arm_joint": q})
    np.testing.assert_allclose(t, expected, atol=1e-12)
    # Hand-computed: the hand in base is (0.5 cos q, 0.5 sin q, 1); the cam sits
    # at (0, 0.2, 0) yawed +90 deg, so cam x = base y - 0.2, cam y = -base x.
    np.testing.assert_allclose(t[:3, 3], [0.5 * math.sin(q) - 0.2, -0.5 * math.cos(q), 1.0], atol=1e-12)


def test_prismatic_joint_translates_along_axis(toy):
    t = toy.transform("base", "slider", {"slide_joint": 0.25})
    np.testing.assert_allclose(t[:3, 3], [0.25, 0, 0])


def test_movable_joint_on_path_needs_a_position(toy):
    with pytest.raises(ValueError, match="arm_joint"):
        toy.fixed_transform("base", "hand")
    with pytest.raises(ValueError, match="not finite"):
        toy.transform("base", "hand", {"arm_joint": float("nan")})


def test_unknown_link_and_joint(toy):
    with pytest.raises(ValueError, match="unknown link 'nope'"):
        toy.fixed_transform("base", "nope")
    with pytest.raises(ValueError, match="unknown joint"):
        toy.joint_limits("nope")
    with pytest.raises(ValueError, match="has no <limit>"):
        toy.joint_limits("hand_joint")


def _robot(body):
    return f'<robot name="bad">{body}</robot>'


@pytest.mark.parametrize(
    "xml, message",
    [
        ("", "empty"),
        ("<robot><link name='a'>", "not well-formed"),
        ("<model name='x'/>", "root element must be <robot>"),
        (_robot(""), "no links"),
        (_robot("<link name='a'/><link name='a'/>"), "duplicate link"),
        (_robot("<link name='a'/><link name='b'/><joint name='j' type='fixed'><child link='b'/></joint>"),
         "no <parent"),
        (_robot("<link name='a'/><joint name='j' type='fixed'><parent link='a'/><child link='zz'/></joint>"),
         "child link 'zz' is not defined"),
        (_robot("<link name='a'/><link name='b'/><joint name='j' type='hinge'><parent link='a'/><child link='b'/></joint>"),
         "type 'hinge'"),
        (_robot("<link name='a'/><link name='b'/><joint name='j' type='revolute'><parent link='a'/><child link='b'/></joint>"),
         "needs a <limit>"),
        (_robot("<link name='a'/><link name='b'/><joint name='j' type='fixed'><parent link='a'/><child link='b'/>"
                "<origin xyz='1 2'/></joint>"), "origin xyz must have 3 numbers"),
        (_robot("<link name='a'/><link name='b'/><joint name='j' type='fixed'><parent link='a'/><child link='b'/>"
                "<origin xyz='1 two 3'/></joint>"), "not numeric"),
        (_robot("<link name='a'/><link name='b'/><link name='c'/>"
                "<joint name='j1' type='fixed'><parent link='a'/><child link='c'/></joint>"
                "<joint name='j2' type='fixed'><parent link='b'/><child link='c'/></joint>"), "two parent joints"),
        (_robot("<link name='r'/><link name='a'/><link name='b'/>"
                "<joint name='j1' type='fixed'><parent link='a'/><child link='b'/></joint>"
                "<joint name='j2' type='fixed'><parent link='b'/><child link='a'/></joint>"), "cycle"),
        (_robot("<link name='a'/><link name='b'/>"), "exactly one root"),
        (_robot("<link name='a'><visual><geometry><torus/></geometry></visual></link>"), "unknown geometry"),
    ],
)
def test_malformed_urdf_raises_clear_error(xml, message):
    with pytest.raises(ValueError, match=message):
        UrdfModel.from_string(xml)


def test_from_file_errors_name_the_file(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        UrdfModel.from_file(tmp_path / "missing.urdf")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot>")
    with pytest.raises(ValueError, match="bad.urdf"):
        UrdfModel.from_file(bad)
    good = tmp_path / "good.urdf"
    good.write_text(TREE)
    assert UrdfModel.from_file(good).root == "base"


def test_pose_matrix_and_inverse_roundtrip():
    t = pose_matrix((1.0, -2.0, 0.5), (0.2, 0.3, -1.1))
    np.testing.assert_allclose(invert(t) @ t, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(t[:3, :3]), 1.0)
