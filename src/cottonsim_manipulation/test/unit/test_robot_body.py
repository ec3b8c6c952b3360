"""The robot's body boxes, read from the robot description, in the arm's base frame."""
import math

import numpy as np
import pytest

from cottonsim_manipulation.planning.robot_body import body_boxes_from_urdf, rpy_matrix

# Hand-derived from make_urdf.py's numbers: the arm's base frame (ur5e_base) is the top plate
# frame moved by (0.264, 0, 0.006) and turned +90 deg about z (mount yaw -90 deg, base_link ->
# base +180 deg): arm x = plate y (left), arm y = -plate x (backwards).
ARM_IN_PLATE = np.array([0.264, 0.0, 0.006])


def plate_to_arm(p):
    d = np.asarray(p) - ARM_IN_PLATE
    return np.array([d[1], -d[0], d[2]])


def box(body, name):
    i = body.names.index(name)
    return body.centre_m[i], body.rotation[i], body.half_extents_m[i]


def test_body_from_the_committed_urdf(body):
    names = set(body.names)
    assert {"base_link/0", "top_plate_link/0", "ur5e_control_box_link/0", "realsense_p_link/0",
            "velodyne_base_link/0", "gps_link/1", "front_left_wheel_link/0", "ground"} <= names
    # Nothing of the arm itself.
    assert not [n for n in names if n.startswith("ur5e_") and not n.startswith("ur5e_control_box")]
    # Control box: 0.35 x 0.45 x 0.15 m standing on the plate at plate (-0.12, 0, 0).
    centre, rot, half = box(body, "ur5e_control_box_link/0")
    np.testing.assert_allclose(centre, plate_to_arm([-0.12, 0.0, 0.075]), atol=1e-9)
    np.testing.assert_allclose(np.abs(rot @ np.diag(half) @ rot.T).sum(axis=1), [0.225, 0.175, 0.075], atol=1e-9)
    # Front camera: plate (0.415, 0, 0.095), in front of the arm (arm -y).
    centre, _, _ = box(body, "realsense_p_link/0")
    np.testing.assert_allclose(centre, plate_to_arm([0.415, 0.0, 0.095]), atol=1e-9)
    # The ground's top is the ground: 0.13228 + 0.245 + 0.006 m below the arm's base.
    centre, rot, half = box(body, "ground")
    assert centre[2] + half[2] == pytest.approx(-(0.13228 + 0.245 + 0.006), abs=1e-6)
    # Every box is a proper rotation.
    for r in body.rotation:
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-9)


def test_collision_source_and_no_ground(urdf_text):
    collision = body_boxes_from_urdf(urdf_text, source="collision", ground_link=None)
    assert "ground" not in collision.names
    # The URDF's collision shapes: the chassis (2 boxes), 4 wheels, the control box and the bin (floor, 4 walls).
    assert sorted(collision.names) == sorted(["base_link/0", "base_link/1", "ur5e_control_box_link/0"]
                                             + [f"cotton_bin/{i}" for i in range(5)]
                                             + [f"{w}_wheel_link/0" for w in ("front_left", "front_right",
                                                                               "rear_left", "rear_right")])
    # A wheel (cylinder radius 0.1651, width 0.1143) becomes its bounding box.
    _, _, half = box(collision, "front_left_wheel_link/0")
    np.testing.assert_allclose(sorted(half), sorted([0.1651, 0.1651, 0.1143 / 2]), atol=1e-9)


def test_rpy_matrix_is_the_urdf_convention():
    # R = Rz(yaw) Ry(pitch) Rx(roll): roll pi/2 turns y onto z.
    np.testing.assert_allclose(rpy_matrix(math.pi / 2, 0, 0) @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(rpy_matrix(0, math.pi / 2, 0) @ [1, 0, 0], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(rpy_matrix(0, 0, math.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    r = rpy_matrix(0.3, -0.2, 1.1)
    c = rpy_matrix(0, 0, 1.1) @ rpy_matrix(0, -0.2, 0) @ rpy_matrix(0.3, 0, 0)
    np.testing.assert_allclose(r, c, atol=1e-12)


def test_bad_descriptions_are_named():
    with pytest.raises(ValueError, match="not valid XML"):
        body_boxes_from_urdf("<robot><link></robot>")
    with pytest.raises(ValueError, match="no link 'ur5e_base'"):
        body_boxes_from_urdf('<robot name="r"><link name="a"/></robot>')
    bad_origin = ('<robot name="r"><link name="ur5e_base"/><link name="ur5e_base_link"/><link name="b"/>'
                  '<joint name="j" type="fixed"><parent link="ur5e_base_link"/><child link="ur5e_base"/></joint>'
                  '<joint name="k" type="fixed"><parent link="ur5e_base_link"/><child link="b"/>'
                  '<origin xyz="0 nan 0"/></joint></robot>')
    with pytest.raises(ValueError, match="joint k origin xyz"):
        body_boxes_from_urdf(bad_origin, ground_link=None)
    with pytest.raises(ValueError, match="source"):
        body_boxes_from_urdf("<robot/>", source="mesh")
