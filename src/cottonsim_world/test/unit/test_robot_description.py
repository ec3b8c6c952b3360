"""Checks of the robot description (cottonsim_description/urdf/cottonsim_robot.urdf).

The URDF parses, names every frame the rest of the system uses, puts the
sensors where the paper's Table 1 says (composed base_link -> top_plate_link ->
sensor and compared with hand-computed numbers), has the Husky's wheel
geometry, is loadable by pybullet, and is what make_urdf.py generates.
"""
import importlib.util
import math
import pathlib
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from cottonsim_world.robot.urdf_model import UrdfModel

ROOT = pathlib.Path(__file__).resolve().parents[4]
DESCRIPTION = ROOT / "src" / "cottonsim_description"
URDF_PATH = DESCRIPTION / "urdf" / "cottonsim_robot.urdf"
TOP_PLATE = np.array([0.0812, 0.0, 0.245])
DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def model():
    return UrdfModel.from_file(URDF_PATH)


def load_generator():
    spec = importlib.util.spec_from_file_location("make_urdf", DESCRIPTION / "scripts" / "make_urdf.py")
    module = importlib.util.module_from_spec(spec)
    # Registered before running: its dataclasses look their module up by name.
    sys.modules[spec.name] = module
    try:
        spec.loader.exec_module(module)
    finally:
        del sys.modules[spec.name]
    return module


def test_generated_file_is_up_to_date():
    assert URDF_PATH.read_text() == load_generator().build_urdf(), (
        "cottonsim_robot.urdf is stale: run python src/cottonsim_description/scripts/make_urdf.py"
    )


FRAMES = [
    "base_link", "base_footprint", "top_plate_link",
    "front_left_wheel_link", "front_right_wheel_link", "rear_left_wheel_link", "rear_right_wheel_link",
    "realsense_p_link", "realsense_p_color_optical_frame",
    "realsense_secondary_link", "realsense_secondary_color_optical_frame",
    "realsense_tertiary_link", "realsense_tertiary_color_optical_frame",
    "velodyne_base_link", "velodyne", "imu_link", "gps_link", "ur5e_control_box_link",
    "ur5e_base_link", "ur5e_base", "ur5e_shoulder_link", "ur5e_upper_arm_link", "ur5e_forearm_link",
    "ur5e_wrist_1_link", "ur5e_wrist_2_link", "ur5e_wrist_3_link", "ur5e_flange", "ur5e_tool0",
    "ur5e_vacuum_nozzle", "ur5e_nozzle_tip",
]


def test_every_named_frame_exists_and_base_link_is_root(model):
    missing = [f for f in FRAMES if f not in model.links]
    assert not missing
    assert model.root == "base_link"
    movable = {j.name: j.type for j in model.movable_joints()}
    assert movable == {
        **{f"{w}_wheel_joint": "continuous" for w in ("front_left", "front_right", "rear_left", "rear_right")},
        **{f"ur5e_{n}": "revolute" for n in ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                                             "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")},
    }


def test_base_link_height_and_top_plate(model):
    t = model.fixed_transform("base_footprint", "base_link")
    np.testing.assert_allclose(t[:3, 3], [0, 0, 0.1651 - 0.03282], atol=1e-12)
    np.testing.assert_allclose(t[:3, :3], np.eye(3))
    t = model.fixed_transform("base_link", "top_plate_link")
    np.testing.assert_allclose(t[:3, 3], TOP_PLATE, atol=1e-12)


def test_wheels_match_the_husky(model):
    zero = {f"{w}_wheel_joint": 0.0 for w in ("front_left", "front_right", "rear_left", "rear_right")}
    for name, sx, sy in (("front_left", 1, 1), ("front_right", 1, -1), ("rear_left", -1, 1), ("rear_right", -1, -1)):
        joint = model.joints[f"{name}_wheel_joint"]
        assert joint.parent == "base_link" and joint.child == f"{name}_wheel_link"
        np.testing.assert_allclose(joint.axis, [0, 1, 0])
        t = model.transform("base_footprint", f"{name}_wheel_link", zero)
        # Wheel centre: half the wheelbase / track out, one radius above ground.
        np.testing.assert_allclose(t[:3, 3], [sx * 0.256, sy * 0.2854, 0.1651], atol=1e-12)
        link = model.links[f"{name}_wheel_link"]
        assert link.mass_kg == pytest.approx(2.637)
        (col,) = link.collisions
        assert col.kind == "cylinder"
        assert col.size == pytest.approx((0.1651, 0.1143))
        # The cylinder's axis (its z) lies along the spin axis y.
        np.testing.assert_allclose(np.abs(col.origin[:3, 2]), [0, 1, 0], atol=1e-9)
    base = model.links["base_link"]
    assert base.mass_kg == 0.0          # the root carries no inertia (KDL); the chassis mass is on inertial_link
    assert 40.0 < model.links["inertial_link"].mass_kg < 50.0
    assert model.parent_joint("inertial_link").type == "fixed"
    assert base.collisions and base.visuals


def test_chassis_outer_size(model):
    """Visual boxes of base_link span 0.990 m long and the top is 0.390 m above ground."""
    base_height = 0.1651 - 0.03282
    xs = []
    for g in model.links["base_link"].visuals:
        assert g.kind == "box"
        xs += [g.origin[0, 3] - g.size[0] / 2, g.origin[0, 3] + g.size[0] / 2]
    assert max(xs) - min(xs) == pytest.approx(0.990)
    tops = [base_height + TOP_PLATE[2] + g.origin[2, 3] + g.size[2] / 2 for g in model.links["top_plate_link"].visuals]
    assert max(tops) == pytest.approx(0.390, abs=1e-3)


def rpy_axes(roll, pitch, yaw):
    """Hand-written Rz(yaw) Ry(pitch) Rx(roll), independent of urdf_model."""
    cx, sx, cy, sy, cz, sz = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


# Paper Table 1 (relative to the top plate): x y z [m], roll pitch yaw [deg].
TABLE1 = {
    "realsense_p_link": ((0.415, 0.000, 0.095), (0, 5, 0)),
    "realsense_secondary_link": ((-0.070, 0.300, -0.050), (0, -15, 90)),
    "realsense_tertiary_link": ((-0.070, -0.300, -0.050), (0, -15, -90)),
    "velodyne_base_link": ((0.430, -0.125, 0.000), (0, 0, 90)),
    "imu_link": ((0.109, 0.000, -0.096), (0, -90, 180)),
    "gps_link": ((-0.354, 0.190, 0.513), (0, 0, 0)),
    "ur5e_base_link": ((0.264, 0.000, 0.006), (0, 0, -90)),
}


@pytest.mark.parametrize("frame", sorted(TABLE1))
def test_sensor_poses_follow_table_1(model, frame):
    xyz, rpy_deg = TABLE1[frame]
    t = model.fixed_transform("base_link", frame)
    np.testing.assert_allclose(t[:3, 3], TOP_PLATE + np.array(xyz), atol=1e-9)
    np.testing.assert_allclose(t[:3, :3], rpy_axes(*(a * DEG for a in rpy_deg)), atol=1e-9)


def test_primary_camera_looks_forward_5_deg_down(model):
    t = model.fixed_transform("base_link", "realsense_p_color_optical_frame")
    # Position: top plate (0.0812, 0, 0.245) + (0.415, 0, 0.095).
    np.testing.assert_allclose(t[:3, 3], [0.4962, 0.0, 0.340], atol=1e-9)
    s, c = math.sin(5 * DEG), math.cos(5 * DEG)
    np.testing.assert_allclose(t[:3, 2], [c, 0, -s], atol=1e-9)  # optical z: forward, 5 deg down
    np.testing.assert_allclose(t[:3, 0], [0, -1, 0], atol=1e-9)  # optical x: image right = robot right
    np.testing.assert_allclose(t[:3, 1], [-s, 0, -c], atol=1e-9)  # optical y: image down


def test_side_cameras_look_sideways_and_are_0_6_m_apart(model):
    left = model.fixed_transform("base_link", "realsense_secondary_color_optical_frame")
    right = model.fixed_transform("base_link", "realsense_tertiary_color_optical_frame")
    assert np.linalg.norm(left[:3, 3] - right[:3, 3]) == pytest.approx(0.600)
    s, c = math.sin(15 * DEG), math.cos(15 * DEG)
    # Table 1 pitch -15 deg (REP-103 sign, as the primary camera's +5 = down)
    # tilts the side cameras 15 deg up while they look left / right.
    np.testing.assert_allclose(left[:3, 2], [0, c, s], atol=1e-9)
    np.testing.assert_allclose(right[:3, 2], [0, -c, s], atol=1e-9)


def test_velodyne_optical_centre_and_axes(model):
    t = model.fixed_transform("base_link", "velodyne")
    np.testing.assert_allclose(t[:3, 3], TOP_PLATE + [0.430, -0.125, 0.0377], atol=1e-9)
    np.testing.assert_allclose(t[:3, 0], [0, 1, 0], atol=1e-9)  # yaw +90: velodyne x = robot left
    np.testing.assert_allclose(t[:3, 2], [0, 0, 1], atol=1e-9)
    (body, _band) = model.links["velodyne_base_link"].visuals
    assert body.kind == "cylinder"
    assert body.size == pytest.approx((0.1033 / 2, 0.0717))


def test_camera_body_visual(model):
    for ns in ("realsense_p", "realsense_secondary", "realsense_tertiary"):
        (vis,) = model.links[f"{ns}_link"].visuals
        assert vis.kind == "box"
        assert sorted(vis.size) == pytest.approx([0.025, 0.025, 0.09])
        assert vis.size[1] == pytest.approx(0.09)  # wide across the view (link y)


def test_every_physical_link_has_a_visual(model):
    frames_only = {
        "base_footprint", "inertial_link", "velodyne", "ur5e_base", "ur5e_flange", "ur5e_tool0",
        "ur5e_nozzle_tip", "realsense_p_color_optical_frame", "realsense_secondary_color_optical_frame",
        "realsense_tertiary_color_optical_frame",
    }
    without = {name for name, link in model.links.items() if not link.visuals}
    assert without == frames_only


def test_ur5e_joint_limits(model):
    expected = {
        "shoulder_pan_joint": (2 * math.pi, 150), "shoulder_lift_joint": (2 * math.pi, 150),
        "elbow_joint": (math.pi, 150), "wrist_1_joint": (2 * math.pi, 28),
        "wrist_2_joint": (2 * math.pi, 28), "wrist_3_joint": (2 * math.pi, 28),
    }
    for name, (limit, effort) in expected.items():
        lim = model.joint_limits("ur5e_" + name)
        assert (lim.lower, lim.upper) == pytest.approx((-limit, limit))
        assert lim.velocity == pytest.approx(math.pi)
        assert lim.effort == effort
    masses = sum(model.links["ur5e_" + n].mass_kg for n in (
        "base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link"))
    assert masses == pytest.approx(21.5, abs=0.5)  # UR5e weighs 20.6 kg (+ mounting)


def test_ur5e_zero_pose_in_the_top_plate(model):
    zeros = {j.name: 0.0 for j in model.movable_joints()}
    t = model.transform("top_plate_link", "ur5e_tool0", zeros)
    # Hand-computed: DH base = ur5e_base_link yawed -90 + 180 = +90 deg, so DH
    # x -> plate +y and DH y -> plate -x; DH tool at (-0.8172, -0.2329, 0.0628).
    np.testing.assert_allclose(t[:3, 3], [0.264 + 0.2329, -0.8172, 0.006 + 0.0628], atol=1e-8)


def test_pybullet_loads_the_urdf():
    import pybullet as p

    client = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(URDF_PATH), physicsClientId=client)
        assert p.getNumJoints(body, physicsClientId=client) == 31
        names = {p.getJointInfo(body, i, physicsClientId=client)[12].decode() for i in range(31)}
        assert {"front_left_wheel_link", "realsense_p_color_optical_frame", "ur5e_tool0", "ur5e_nozzle_tip",
                 "cotton_bin"} <= names
        # Every link but the root carries its own inertial: pybullet's total mass of the
        # links equals the URDF's (a link without one would silently weigh 1 kg in pybullet;
        # the massless root gets that default, so it is left out here).
        masses = [p.getDynamicsInfo(body, i, physicsClientId=client)[0] for i in range(0, 31)]
        model = UrdfModel.from_file(URDF_PATH)
        assert sum(masses) == pytest.approx(sum(link.mass_kg for link in model.links.values()))
        assert 80.0 < sum(masses) < 95.0  # Husky ~50 kg + UR5e ~21 kg + control box and sensors
    finally:
        p.disconnect(client)


def test_launch_files_are_valid_xml():
    desc = ET.parse(DESCRIPTION / "launch" / "description.launch").getroot()
    params = {e.get("name"): e.get("textfile") for e in desc.iter("param")}
    assert params["robot_description"] == "$(find cottonsim_description)/urdf/cottonsim_robot.urdf"
    assert any(n.get("pkg") == "robot_state_publisher" for n in desc.iter("node"))
    assert any(a.get("name") == "use_sim_time" for a in desc.iter("arg"))
    disp = ET.parse(DESCRIPTION / "launch" / "display.launch").getroot()
    assert any(i.get("file", "").endswith("description.launch") for i in disp.iter("include"))
    assert any(n.get("pkg") == "rviz" for n in disp.iter("node"))


def test_rviz_config_has_the_displays():
    import yaml

    cfg = yaml.safe_load((DESCRIPTION / "rviz" / "cottonsim.rviz").read_text())
    manager = cfg["Visualization Manager"]
    topics = {d.get("Topic", d.get("Image Topic")) for d in manager["Displays"]}
    classes = {d["Class"] for d in manager["Displays"]}
    assert {"rviz/RobotModel", "rviz/TF", "rviz/PointCloud2", "rviz/LaserScan", "rviz/Image", "rviz/Map",
            "rviz/Path", "rviz/Odometry"} <= classes
    assert {"/points", "/scan", "/realsense_p/color/image_raw", "/map", "/move_base/NavfnROS/plan",
            "/odometry/filtered"} <= topics
    assert manager["Global Options"]["Fixed Frame"] == "odom"


def test_nozzle_tip_is_the_collision_models_nozzle_end(model):
    """The tip frame lies on tool0's z axis, as far out as the planner's nozzle capsule reaches, with tool0's axes."""
    from cottonsim_common.kinematics.arm_capsules import ArmCollisionConfig

    tool0_T_tip = model.fixed_transform("ur5e_tool0", "ur5e_nozzle_tip")
    assert np.allclose(tool0_T_tip[:3, :3], np.eye(3), atol=1e-12)
    assert np.allclose(tool0_T_tip[:3, 3], [0.0, 0.0, ArmCollisionConfig().nozzle_length_m], atol=1e-12)
    tube = max(model.links["ur5e_vacuum_nozzle"].visuals, key=lambda v: v.size[1])
    assert tube.size[0] == pytest.approx(ArmCollisionConfig().nozzle_radius_m)
