"""The harvesting parts for make_urdf.py: a vacuum nozzle on the UR5e's flange and the cotton bin.

A straight tube along tool0's z (out of the flange) on a short mounting
adapter; its tip frame <prefix>nozzle_tip sits on the tube's end with tool0's
orientation, so its z axis points out of the nozzle. The simulator captures
bolls at that frame (cottonsim_world.robot.vacuum) and the arm's collision
model (cottonsim_manipulation.planning.collision.ArmCollisionConfig) uses the
same length and radius.

The bin is an open box (a floor and four walls) standing on the UR5e's
control box, behind the arm; the simulator drops a boll released with the
nozzle tip over it into the bin (VacuumConfig.bin_centre_m / bin_half_size_m,
in base_link: the opening and up to 0.175 m above the rim), and the arm's
planner avoids its walls (they are body boxes like the rest of the robot).
"""
from __future__ import annotations

from urdf_writer import UrdfWriter, box, box_inertia, cyl_z, cylinder_inertia

NOZZLE_LENGTH_M = 0.15          # flange to tip, along tool0's z
NOZZLE_RADIUS_M = 0.02          # the tube
NOZZLE_MASS_KG = 0.3
ADAPTER_RADIUS_M = 0.032        # the flange's radius
ADAPTER_LENGTH_M = 0.015
NOZZLE_MATERIAL = ("nozzle_orange", (0.95, 0.45, 0.1, 1.0))

BIN_SIZE_M = (0.22, 0.40, 0.12)      # outer length (x), width (y), height (z): ~10 l; low and at the rear
                                     # of the control box, so that the upper arm clears it reaching backwards
BIN_WALL_M = 0.005
BIN_XYZ_ON_CONTROL_BOX_M = (-0.026, 0.0, 0.15)   # the floor's centre on the control box's top
BIN_MASS_KG = 1.0
BIN_MATERIAL = ("bin_green", (0.25, 0.45, 0.30, 1.0))


def add_vacuum_nozzle(w: UrdfWriter, prefix: str) -> None:
    """Links <prefix>vacuum_nozzle (fixed on <prefix>tool0) and its tip frame <prefix>nozzle_tip."""
    w.comment("Vacuum nozzle on the flange; its tip frame has z out of the nozzle (the boll capture point)")
    material = w.add_material(*NOZZLE_MATERIAL)
    tube = cyl_z(NOZZLE_RADIUS_M, 0.0, NOZZLE_LENGTH_M, material=material)
    w.link(
        prefix + "vacuum_nozzle",
        [cyl_z(ADAPTER_RADIUS_M, 0.0, ADAPTER_LENGTH_M, material="aluminium"), tube],
        [cyl_z(NOZZLE_RADIUS_M, 0.0, NOZZLE_LENGTH_M)],
        cylinder_inertia(NOZZLE_MASS_KG, NOZZLE_RADIUS_M, NOZZLE_LENGTH_M, com=(0, 0, NOZZLE_LENGTH_M / 2.0)),
    )
    w.joint(prefix + "vacuum_nozzle_joint", "fixed", prefix + "tool0", prefix + "vacuum_nozzle")
    w.link(prefix + "nozzle_tip")
    w.joint(prefix + "nozzle_tip_joint", "fixed", prefix + "vacuum_nozzle", prefix + "nozzle_tip",
            (0, 0, NOZZLE_LENGTH_M))


def add_cotton_bin(w: UrdfWriter, parent: str) -> None:
    """Link cotton_bin (an open box, floor at its origin) fixed on top of `parent` (the control box)."""
    w.comment("Cotton bin on the control box: the arm releases picked bolls over its opening")
    material = w.add_material(*BIN_MATERIAL)
    length, width, height = BIN_SIZE_M
    t = BIN_WALL_M
    parts = [((length, width, t), (0.0, 0.0, t / 2.0))]
    for sign in (-1.0, 1.0):
        parts.append(((t, width, height), (sign * (length - t) / 2.0, 0.0, height / 2.0)))
        parts.append(((length, t, height), (0.0, sign * (width - t) / 2.0, height / 2.0)))
    w.link("cotton_bin", [box(size, xyz, material) for size, xyz in parts], [box(size, xyz) for size, xyz in parts],
           box_inertia(BIN_MASS_KG, BIN_SIZE_M, (0.0, 0.0, height / 2.0)))
    w.joint("cotton_bin_joint", "fixed", parent, "cotton_bin", BIN_XYZ_ON_CONTROL_BOX_M)
