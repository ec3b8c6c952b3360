#!/usr/bin/env python3
"""Generate urdf/cottonsim_robot.urdf, the CottonSim robot description.

Debian ships no xacro, so the URDF is plain XML. Rather than editing that XML
by hand, this script holds every number once, by name, and writes the file.
The generated file is committed; a unit test
(cottonsim_world/test/unit/test_robot_description.py) regenerates it in memory
and fails when the committed copy is stale. After changing a number run:

    python src/cottonsim_description/scripts/make_urdf.py

The robot (CottonSim paper, Fig. 4 and Table 1):
* Clearpath Husky A200: numbers of Clearpath's husky_description (wheel radius,
  width and mass, wheelbase, track, top plate offset); the chassis is drawn
  with boxes of the published outer size 0.990 x 0.670 x 0.390 m.
* UR5e arm: the published UR5e kinematics (ROS-Industrial ur_description,
  default_kinematics.yaml) with its joint limits; link masses of the published
  model; inertias are approximated as solid cylinders (not the published ones).
* Three RealSense D435 cameras, a Velodyne VLP-16, an IMU, a GPS antenna on a
  mast with a Fixposition vision-RTK box, and the UR5e control box, mounted on
  the top plate at the poses of the paper's Table 1.
* A vacuum nozzle on the UR5e's flange with its tip frame, and the cotton bin on the control box
  (urdf_end_effector.py).

The URDF writer (shapes, inertias, XML) is urdf_writer.py.

Conventions (REP-103): x forward, y left, z up; URDF rpy is roll about x, then
pitch about y, then yaw about z, all about the fixed parent axes, i.e.
R = Rz(yaw) Ry(pitch) Rx(roll). A positive pitch turns +x towards -z (down).
"""
from __future__ import annotations

import argparse
import math
import pathlib
import sys
from dataclasses import dataclass
from typing import Optional, Sequence

# the generator's own modules sit beside it (also when a test loads this file by its path)
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from urdf_end_effector import add_cotton_bin, add_vacuum_nozzle  # noqa: E402
from urdf_writer import (ArmJoint, Inertial, UrdfWriter, Vec3, box, box_inertia, cyl, cyl_z,  # noqa: E402
                         cylinder_inertia)

# ---------------------------------------------------------------------------
# Clearpath Husky A200 (husky_description)
# ---------------------------------------------------------------------------
WHEEL_RADIUS_M = 0.1651
WHEEL_WIDTH_M = 0.1143
WHEEL_MASS_KG = 2.637
# Wheel inertia of husky_description [kg m^2] in the wheel link frame (spin
# axis y); larger about y than a solid disc because the mass sits in the tyre.
WHEEL_INERTIA_KGM2 = (0.02467, 0.04411, 0.02467)  # ixx, iyy, izz
WHEELBASE_M = 0.512
TRACK_M = 0.5708
# Height of the wheel axles above base_link.
WHEEL_VERTICAL_OFFSET_M = 0.03282
# base_link sits this high above the ground (base_footprint): 0.13228 m.
BASE_LINK_HEIGHT_M = WHEEL_RADIUS_M - WHEEL_VERTICAL_OFFSET_M
# Top plate frame relative to base_link (paper: X = 0.081 m, Z = 0.245 m).
TOP_PLATE_XYZ_M: Vec3 = (0.0812, 0.0, 0.245)

CHASSIS_MASS_KG = 46.034
CHASSIS_LENGTH_M = 0.990  # overall, bumper to bumper
CHASSIS_BODY_WIDTH_M = 0.570  # body between the wheels (0.670 m overall incl. wheels)
OVERALL_HEIGHT_M = 0.390  # ground to the top of the top-plate rails
LOWER_HULL_LENGTH_M = 0.800
LOWER_HULL_HEIGHT_M = 0.130  # from base_link up
UPPER_BODY_LENGTH_M = 0.700
BUMPER_DEPTH_M = (CHASSIS_LENGTH_M - LOWER_HULL_LENGTH_M) / 2.0  # 0.095
BUMPER_HEIGHT_M = 0.060
BUMPER_CENTRE_Z_M = 0.091  # husky_description front_bumper_link height
TOP_PLATE_THICKNESS_M = 0.006
TOP_PLATE_LENGTH_M = 0.790
RAIL_HEIGHT_M = OVERALL_HEIGHT_M - (BASE_LINK_HEIGHT_M + TOP_PLATE_XYZ_M[2])  # ~0.0127
RAIL_LENGTH_M = 0.700
RAIL_WIDTH_M = 0.025
RAIL_Y_M = 0.250

# ---------------------------------------------------------------------------
# Paper Table 1: poses relative to the top plate frame, x y z [m], r p y [deg]
# ---------------------------------------------------------------------------
# Pitch sign: REP-103 / URDF rotate about +y, and a positive pitch turns the
# camera's +x (its viewing direction) downwards. The paper says the primary
# camera points down and lists +5 deg, so Table 1 uses the REP-103 sign and
# all values are taken literally. Consequence for the side cameras: pitch
# -15 deg (applied before the +/-90 deg yaw) tilts them 15 deg UP, towards the
# bolls of the 1.0 m tall plants beside the robot (the cameras sit ~0.33 m
# above the ground). The IMU row (0, -90, 180) gives an imu_link whose x axis
# points up; it is kept as published (TF makes the data consistent).


@dataclass(frozen=True)
class Mount:
    """A pose relative to the top plate: xyz [m] and roll, pitch, yaw [deg]."""

    xyz_m: Vec3
    rpy_deg: Vec3

    @property
    def rpy_rad(self) -> Vec3:
        return tuple(math.radians(a) for a in self.rpy_deg)  # type: ignore[return-value]


PRIMARY_CAMERA = Mount((0.415, 0.000, 0.095), (0.0, 5.0, 0.0))
SECONDARY_CAMERA = Mount((-0.070, 0.300, -0.050), (0.0, -15.0, 90.0))
TERTIARY_CAMERA = Mount((-0.070, -0.300, -0.050), (0.0, -15.0, -90.0))
LIDAR = Mount((0.430, -0.125, 0.000), (0.0, 0.0, 90.0))
IMU = Mount((0.109, 0.000, -0.096), (0.0, -90.0, 180.0))
GPS = Mount((-0.354, 0.190, 0.513), (0.0, 0.0, 0.0))
UR5E_BASE = Mount((0.264, 0.000, 0.006), (0.0, 0.0, -90.0))

CAMERA_MOUNTS = (
    ("realsense_p", PRIMARY_CAMERA),
    ("realsense_secondary", SECONDARY_CAMERA),
    ("realsense_tertiary", TERTIARY_CAMERA),
)
# RealSense D435 body: 90 mm wide (across the view, link y), 25 mm deep
# (along the view, link x), 25 mm tall; 72 g.
CAMERA_BOX_M: Vec3 = (0.025, 0.090, 0.025)
CAMERA_MASS_KG = 0.072
# Optical frame (z forward, x right, y down) relative to the camera link.
OPTICAL_RPY_RAD: Vec3 = (-math.pi / 2.0, 0.0, -math.pi / 2.0)

# Velodyne VLP-16: the Table 1 pose is the bottom of the sensor
# (velodyne_base_link); the 'velodyne' frame is the optical centre above it.
VLP16_DIAMETER_M = 0.1033
VLP16_HEIGHT_M = 0.0717
VLP16_OPTICAL_CENTRE_Z_M = 0.0377
VLP16_MASS_KG = 0.83

IMU_BOX_M: Vec3 = (0.040, 0.040, 0.020)
IMU_MASS_KG = 0.05
GPS_ANTENNA_RADIUS_M = 0.075
GPS_ANTENNA_HEIGHT_M = 0.020
GPS_MAST_RADIUS_M = 0.012
GPS_MASS_KG = 0.8
VRTK_BOX_M: Vec3 = (0.080, 0.120, 0.060)  # decorative Fixposition vision-RTK
VRTK_HEIGHT_ON_MAST_M = 0.300  # centre of the box above the top plate

# UR5e control box: a flat, compact (OEM-style) box standing on the top plate
# behind the arm, clear of the GPS mast. Size and mass are approximate; the
# standard cabinet (475 x 423 x 268 mm) would cover most of the plate.
CONTROL_BOX_XYZ_M: Vec3 = (-0.120, 0.000, 0.000)
CONTROL_BOX_SIZE_M: Vec3 = (0.350, 0.450, 0.150)
CONTROL_BOX_MASS_KG = 8.0

# ---------------------------------------------------------------------------
# UR5e (ur_description, default_kinematics.yaml / physical_parameters.yaml)
# ---------------------------------------------------------------------------
UR5E_D1_M = 0.1625  # shoulder height
UR5E_A2_M = -0.425  # upper arm
UR5E_A3_M = -0.3922  # forearm
UR5E_D4_M = 0.1333  # wrist offsets
UR5E_D5_M = 0.0997
UR5E_D6_M = 0.0996
UR5E_PREFIX = "ur5e_"
UR5E_MASSES_KG = {
    "base_link": 4.0,
    "shoulder_link": 3.761,
    "upper_arm_link": 8.058,
    "forearm_link": 2.846,
    "wrist_1_link": 1.37,
    "wrist_2_link": 1.3,
    "wrist_3_link": 0.365,
}


UR5E_JOINTS = (
    ArmJoint("shoulder_pan_joint", -2 * math.pi, 2 * math.pi, math.pi, 150.0),
    ArmJoint("shoulder_lift_joint", -2 * math.pi, 2 * math.pi, math.pi, 150.0),
    ArmJoint("elbow_joint", -math.pi, math.pi, math.pi, 150.0),
    ArmJoint("wrist_1_joint", -2 * math.pi, 2 * math.pi, math.pi, 28.0),
    ArmJoint("wrist_2_joint", -2 * math.pi, 2 * math.pi, math.pi, 28.0),
    ArmJoint("wrist_3_joint", -2 * math.pi, 2 * math.pi, math.pi, 28.0),
)
# Approximate visual radii of the arm's housings and tubes [m].
UR5E_BASE_RADIUS_M = 0.0745
UR5E_BASE_HEIGHT_M = 0.090
UR5E_JOINT_RADIUS_M = 0.060
UR5E_UPPER_TUBE_RADIUS_M = 0.045
UR5E_UPPER_TUBE_OFFSET_M = 0.138  # tube offset along the lift axis
UR5E_FOREARM_RADIUS_M = 0.038
UR5E_FOREARM_OFFSET_M = 0.010
UR5E_WRIST_RADIUS_M = 0.045
UR5E_FLANGE_RADIUS_M = 0.032
UR5E_FLANGE_THICKNESS_M = 0.020

# ---------------------------------------------------------------------------
# Colours (rgba)
# ---------------------------------------------------------------------------
MATERIALS = {
    "husky_yellow": (1.0, 0.76, 0.0, 1.0),
    "dark_grey": (0.18, 0.18, 0.18, 1.0),
    "black": (0.05, 0.05, 0.05, 1.0),
    "aluminium": (0.62, 0.64, 0.66, 1.0),
    "ur_blue": (0.55, 0.70, 0.85, 1.0),
    "ur_grey": (0.80, 0.82, 0.84, 1.0),
    "camera_grey": (0.35, 0.35, 0.38, 1.0),
    "lidar_grey": (0.55, 0.55, 0.55, 1.0),
    "imu_green": (0.1, 0.5, 0.2, 1.0),
    "gps_white": (0.92, 0.92, 0.92, 1.0),
}


# ---------------------------------------------------------------------------
# The robot
# ---------------------------------------------------------------------------
def add_husky(w: UrdfWriter) -> None:
    """Husky A200 chassis, wheels, base_footprint and top plate."""
    w.comment("Clearpath Husky A200: base_link is the root; base_footprint lies on the ground below it")
    upper_height = TOP_PLATE_XYZ_M[2] - TOP_PLATE_THICKNESS_M - LOWER_HULL_HEIGHT_M
    upper_z = LOWER_HULL_HEIGHT_M + upper_height / 2.0
    bumper_x = LOWER_HULL_LENGTH_M / 2.0 + BUMPER_DEPTH_M / 2.0
    visuals = [
        box((LOWER_HULL_LENGTH_M, CHASSIS_BODY_WIDTH_M, LOWER_HULL_HEIGHT_M), (0, 0, LOWER_HULL_HEIGHT_M / 2.0), "dark_grey"),
        box((UPPER_BODY_LENGTH_M, CHASSIS_BODY_WIDTH_M, upper_height), (0, 0, upper_z), "husky_yellow"),
        box((BUMPER_DEPTH_M, CHASSIS_BODY_WIDTH_M, BUMPER_HEIGHT_M), (bumper_x, 0, BUMPER_CENTRE_Z_M), "black"),
        box((BUMPER_DEPTH_M, CHASSIS_BODY_WIDTH_M, BUMPER_HEIGHT_M), (-bumper_x, 0, BUMPER_CENTRE_Z_M), "black"),
    ]
    collisions = [
        box((CHASSIS_LENGTH_M, CHASSIS_BODY_WIDTH_M, LOWER_HULL_HEIGHT_M), (0, 0, LOWER_HULL_HEIGHT_M / 2.0)),
        box((UPPER_BODY_LENGTH_M, CHASSIS_BODY_WIDTH_M, upper_height + TOP_PLATE_THICKNESS_M),
            (0, 0, LOWER_HULL_HEIGHT_M + (upper_height + TOP_PLATE_THICKNESS_M) / 2.0)),
    ]
    # Inertia of a solid box of the chassis size; centre of mass mid-body.
    body_size = (CHASSIS_LENGTH_M, CHASSIS_BODY_WIDTH_M, TOP_PLATE_XYZ_M[2])
    inertial = box_inertia(CHASSIS_MASS_KG, body_size, (0.0, 0.0, TOP_PLATE_XYZ_M[2] / 2.0))
    # As husky_description does, the chassis mass sits on a fixed child link: KDL (and so
    # robot_state_publisher) does not support a root link with an inertia.
    w.link("base_link", visuals, collisions, massless=True)
    w.link("inertial_link", inertial=inertial)
    w.joint("inertial_joint", "fixed", "base_link", "inertial_link", (0, 0, 0))

    w.link("base_footprint")
    w.joint("base_footprint_joint", "fixed", "base_link", "base_footprint", (0, 0, -BASE_LINK_HEIGHT_M))

    tyre = cyl(WHEEL_RADIUS_M, WHEEL_WIDTH_M, rpy=(math.pi / 2.0, 0, 0), material="black")
    hub = cyl(WHEEL_RADIUS_M * 0.55, WHEEL_WIDTH_M + 0.002, rpy=(math.pi / 2.0, 0, 0), material="aluminium")
    wheel_inertial = Inertial(WHEEL_MASS_KG, (0, 0, 0), WHEEL_INERTIA_KGM2)
    for prefix, sx, sy in (("front_left", 1, 1), ("front_right", 1, -1), ("rear_left", -1, 1), ("rear_right", -1, -1)):
        link = f"{prefix}_wheel_link"
        w.link(link, [tyre, hub], [cyl(WHEEL_RADIUS_M, WHEEL_WIDTH_M, rpy=(math.pi / 2.0, 0, 0))], wheel_inertial)
        w.joint(
            f"{prefix}_wheel_joint", "continuous", "base_link", link,
            (sx * WHEELBASE_M / 2.0, sy * TRACK_M / 2.0, WHEEL_VERTICAL_OFFSET_M), axis=(0, 1, 0),
        )

    # The top plate frame is the Table 1 reference; its z = 0 is the plate's
    # upper surface. The plate itself is centred over the chassis.
    plate_dx = -TOP_PLATE_XYZ_M[0]
    plate = [box((TOP_PLATE_LENGTH_M, CHASSIS_BODY_WIDTH_M, TOP_PLATE_THICKNESS_M), (plate_dx, 0, -TOP_PLATE_THICKNESS_M / 2.0), "dark_grey")]
    for sy in (1.0, -1.0):
        plate.append(box((RAIL_LENGTH_M, RAIL_WIDTH_M, RAIL_HEIGHT_M), (plate_dx, sy * RAIL_Y_M, RAIL_HEIGHT_M / 2.0), "black"))
    w.link("top_plate_link", plate)
    w.joint("top_plate_joint", "fixed", "base_link", "top_plate_link", TOP_PLATE_XYZ_M)


def add_sensors(w: UrdfWriter) -> None:
    """Cameras, LiDAR, IMU and GPS at the paper's Table 1 poses."""
    w.comment("Sensors at the paper's Table 1 poses relative to top_plate_link (see make_urdf.py for sign conventions)")
    for ns, mount in CAMERA_MOUNTS:
        link = f"{ns}_link"
        w.link(link, [box(CAMERA_BOX_M, material="camera_grey")], [], box_inertia(CAMERA_MASS_KG, CAMERA_BOX_M))
        w.joint(f"{ns}_joint", "fixed", "top_plate_link", link, mount.xyz_m, mount.rpy_rad)
        optical = f"{ns}_color_optical_frame"
        w.link(optical)
        w.joint(f"{ns}_color_optical_joint", "fixed", link, optical, rpy=OPTICAL_RPY_RAD)

    radius = VLP16_DIAMETER_M / 2.0
    w.link(
        "velodyne_base_link",
        [cyl_z(radius, 0.0, VLP16_HEIGHT_M, material="lidar_grey"),
         cyl_z(radius * 1.01, 0.018, 0.054, material="black")],  # the dark window band
        [],
        cylinder_inertia(VLP16_MASS_KG, radius, VLP16_HEIGHT_M, com=(0, 0, VLP16_HEIGHT_M / 2.0)),
    )
    w.joint("velodyne_base_mount_joint", "fixed", "top_plate_link", "velodyne_base_link", LIDAR.xyz_m, LIDAR.rpy_rad)
    w.link("velodyne")
    w.joint("velodyne_base_scan_joint", "fixed", "velodyne_base_link", "velodyne", (0, 0, VLP16_OPTICAL_CENTRE_Z_M))

    w.link("imu_link", [box(IMU_BOX_M, material="imu_green")], [], box_inertia(IMU_MASS_KG, IMU_BOX_M))
    w.joint("imu_joint", "fixed", "top_plate_link", "imu_link", IMU.xyz_m, IMU.rpy_rad)

    # gps_link is the antenna's phase centre on top of a mast that stands on
    # the top plate; the vision-RTK box is fixed on the mast (decorative).
    mast_bottom = -GPS.xyz_m[2]
    mast_top = -GPS_ANTENNA_HEIGHT_M
    vrtk_z = mast_bottom + VRTK_HEIGHT_ON_MAST_M
    w.link(
        "gps_link",
        [
            cyl_z(GPS_ANTENNA_RADIUS_M, -GPS_ANTENNA_HEIGHT_M, 0.0, material="gps_white"),
            cyl_z(GPS_MAST_RADIUS_M, mast_bottom, mast_top, material="aluminium"),
            box(VRTK_BOX_M, (GPS_MAST_RADIUS_M + VRTK_BOX_M[0] / 2.0, 0, vrtk_z), "black"),
        ],
        [],
        cylinder_inertia(GPS_MASS_KG, GPS_ANTENNA_RADIUS_M, GPS_ANTENNA_HEIGHT_M),
    )
    w.joint("gps_joint", "fixed", "top_plate_link", "gps_link", GPS.xyz_m, GPS.rpy_rad)

    cb_size = CONTROL_BOX_SIZE_M
    w.link(
        "ur5e_control_box_link",
        [box(cb_size, (0, 0, cb_size[2] / 2.0), "ur_grey")],
        [box(cb_size, (0, 0, cb_size[2] / 2.0))],
        box_inertia(CONTROL_BOX_MASS_KG, cb_size, (0, 0, cb_size[2] / 2.0)),
    )
    w.joint("ur5e_control_box_joint", "fixed", "top_plate_link", "ur5e_control_box_link", CONTROL_BOX_XYZ_M)


def add_ur5e(w: UrdfWriter) -> None:
    """The UR5e arm with the published kinematics.

    Frames follow ROS-Industrial's ur_description: ur5e_base is the UR
    controller's base frame (the DH base, ur5e_base_link turned by pi about
    z); each joint origin is the DH step a_(i-1), alpha_(i-1), d_i of the
    UR5e table, so ur5e_wrist_3_link is DH frame 6 and ur5e_tool0 coincides
    with it (z out of the flange). ur5e_flange has x out of the flange.
    """
    p = UR5E_PREFIX
    w.comment("UR5e arm (published kinematics and limits; inertias approximated as cylinders)")
    half_pi = math.pi / 2.0
    joints = {j.name: j for j in UR5E_JOINTS}

    w.link(
        p + "base_link",
        [cyl_z(UR5E_BASE_RADIUS_M, 0.0, UR5E_BASE_HEIGHT_M, material="ur_grey")],
        [],
        cylinder_inertia(UR5E_MASSES_KG["base_link"], UR5E_BASE_RADIUS_M, UR5E_BASE_HEIGHT_M,
                         com=(0, 0, UR5E_BASE_HEIGHT_M / 2.0)),
    )
    w.joint(p + "base_mount_joint", "fixed", "top_plate_link", p + "base_link", UR5E_BASE.xyz_m, UR5E_BASE.rpy_rad)
    w.link(p + "base")
    w.joint(p + "base_fixed_joint", "fixed", p + "base_link", p + "base", rpy=(0, 0, math.pi))

    # Shoulder (pan about z); its frame sits d1 above the base.
    shoulder_low = UR5E_BASE_HEIGHT_M - UR5E_D1_M
    shoulder_high = UR5E_JOINT_RADIUS_M
    w.link(
        p + "shoulder_link",
        [cyl_z(UR5E_JOINT_RADIUS_M, shoulder_low, shoulder_high, material="ur_blue")],
        [],
        cylinder_inertia(UR5E_MASSES_KG["shoulder_link"], UR5E_JOINT_RADIUS_M, shoulder_high - shoulder_low,
                         com=(0, 0, (shoulder_low + shoulder_high) / 2.0)),
    )
    w.joint(p + "shoulder_pan_joint", "revolute", p + "base_link", p + "shoulder_link",
            (0, 0, UR5E_D1_M), (0, 0, math.pi), (0, 0, 1), joints["shoulder_pan_joint"])

    # Upper arm: z along the lift axis; the tube runs along -x, offset along z.
    tube_len = -UR5E_A2_M
    w.link(
        p + "upper_arm_link",
        [
            cyl_z(UR5E_JOINT_RADIUS_M, 0.0, UR5E_UPPER_TUBE_OFFSET_M + UR5E_JOINT_RADIUS_M, material="ur_blue"),
            cyl(UR5E_UPPER_TUBE_RADIUS_M, tube_len, (UR5E_A2_M / 2.0, 0, UR5E_UPPER_TUBE_OFFSET_M), (0, half_pi, 0), "ur_grey"),
        ],
        [],
        cylinder_inertia(UR5E_MASSES_KG["upper_arm_link"], UR5E_UPPER_TUBE_RADIUS_M, tube_len, "x",
                         com=(UR5E_A2_M / 2.0, 0, UR5E_UPPER_TUBE_OFFSET_M)),
    )
    w.joint(p + "shoulder_lift_joint", "revolute", p + "shoulder_link", p + "upper_arm_link",
            rpy=(half_pi, 0, 0), axis=(0, 0, 1), limit=joints["shoulder_lift_joint"])

    fore_len = -UR5E_A3_M
    w.link(
        p + "forearm_link",
        [
            cyl_z(UR5E_WRIST_RADIUS_M + 0.005, -0.01, UR5E_UPPER_TUBE_OFFSET_M + UR5E_UPPER_TUBE_RADIUS_M, material="ur_blue"),
            cyl(UR5E_FOREARM_RADIUS_M, fore_len, (UR5E_A3_M / 2.0, 0, UR5E_FOREARM_OFFSET_M), (0, half_pi, 0), "ur_grey"),
            cyl_z(UR5E_FOREARM_RADIUS_M, 0.0, UR5E_D4_M - UR5E_WRIST_RADIUS_M, x=UR5E_A3_M, material="ur_grey"),
        ],
        [],
        cylinder_inertia(UR5E_MASSES_KG["forearm_link"], UR5E_FOREARM_RADIUS_M, fore_len, "x",
                         com=(UR5E_A3_M / 2.0, 0, UR5E_FOREARM_OFFSET_M)),
    )
    w.joint(p + "elbow_joint", "revolute", p + "upper_arm_link", p + "forearm_link",
            (UR5E_A2_M, 0, 0), axis=(0, 0, 1), limit=joints["elbow_joint"])

    wrist_len = 2.0 * UR5E_WRIST_RADIUS_M
    w.link(
        p + "wrist_1_link",
        [cyl_z(UR5E_WRIST_RADIUS_M, -UR5E_WRIST_RADIUS_M, UR5E_WRIST_RADIUS_M, material="ur_blue")],
        [],
        cylinder_inertia(UR5E_MASSES_KG["wrist_1_link"], UR5E_WRIST_RADIUS_M, wrist_len),
    )
    w.joint(p + "wrist_1_joint", "revolute", p + "forearm_link", p + "wrist_1_link",
            (UR5E_A3_M, 0, UR5E_D4_M), axis=(0, 0, 1), limit=joints["wrist_1_joint"])

    # Wrist 2: DH alpha_4 = +pi/2 then d5 along the new z.
    w.link(
        p + "wrist_2_link",
        [cyl_z(UR5E_WRIST_RADIUS_M, -(UR5E_D5_M - UR5E_WRIST_RADIUS_M), UR5E_WRIST_RADIUS_M, material="ur_blue")],
        [],
        cylinder_inertia(UR5E_MASSES_KG["wrist_2_link"], UR5E_WRIST_RADIUS_M, wrist_len),
    )
    w.joint(p + "wrist_2_joint", "revolute", p + "wrist_1_link", p + "wrist_2_link",
            (0, -UR5E_D5_M, 0), (half_pi, 0, 0), (0, 0, 1), joints["wrist_2_joint"])

    # Wrist 3: DH alpha_5 = -pi/2 then d6 along the new z (the tool axis).
    w3_low = -(UR5E_D6_M - UR5E_WRIST_RADIUS_M)
    w.link(
        p + "wrist_3_link",
        [
            cyl_z(UR5E_WRIST_RADIUS_M, w3_low, -UR5E_FLANGE_THICKNESS_M, material="ur_blue"),
            cyl_z(UR5E_FLANGE_RADIUS_M, -UR5E_FLANGE_THICKNESS_M, 0.0, material="aluminium"),
        ],
        [],
        cylinder_inertia(UR5E_MASSES_KG["wrist_3_link"], UR5E_FLANGE_RADIUS_M, -w3_low, com=(0, 0, w3_low / 2.0)),
    )
    w.joint(p + "wrist_3_joint", "revolute", p + "wrist_2_link", p + "wrist_3_link",
            (0, UR5E_D6_M, 0), (-half_pi, 0, 0), (0, 0, 1), joints["wrist_3_joint"])

    # ROS-Industrial's flange (x out of the flange) and tool0 (z out, = DH 6).
    w.link(p + "flange")
    w.joint(p + "flange_joint", "fixed", p + "wrist_3_link", p + "flange", rpy=(0, -half_pi, -half_pi))
    w.link(p + "tool0")
    w.joint(p + "tool0_joint", "fixed", p + "flange", p + "tool0", rpy=(half_pi, 0, half_pi))


def build_urdf() -> str:
    """The whole robot description as URDF text (deterministic)."""
    w = UrdfWriter("cottonsim_robot", MATERIALS)
    add_husky(w)
    add_sensors(w)
    add_ur5e(w)
    add_vacuum_nozzle(w, UR5E_PREFIX)
    add_cotton_bin(w, "ur5e_control_box_link")
    return w.to_string()


DEFAULT_OUTPUT = pathlib.Path(__file__).resolve().parents[1] / "urdf" / "cottonsim_robot.urdf"


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=pathlib.Path, default=DEFAULT_OUTPUT,
                        help=f"where to write the URDF (default {DEFAULT_OUTPUT})")
    parser.add_argument("--check", action="store_true",
                        help="do not write; exit 1 when the file differs from what would be generated")
    args = parser.parse_args(argv)
    text = build_urdf()
    if args.check:
        current = args.output.read_text() if args.output.exists() else ""
        if current != text:
            print(f"{args.output} is out of date; run {pathlib.Path(__file__).name}", file=sys.stderr)
            return 1
        print(f"{args.output} is up to date")
        return 0
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
