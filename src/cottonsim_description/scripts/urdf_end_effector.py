"""The harvesting end effector for make_urdf.py: a vacuum nozzle on the UR5e's flange.

A straight tube along tool0's z (out of the flange) on a short mounting
adapter; its tip frame <prefix>nozzle_tip sits on the tube's end with tool0's
orientation, so its z axis points out of the nozzle. The simulator captures
bolls at that frame (cottonsim_world.robot.vacuum) and the arm's collision
model (cottonsim_manipulation.planning.collision.ArmCollisionConfig) uses the
same length and radius.
"""
from __future__ import annotations

from urdf_writer import UrdfWriter, cyl_z, cylinder_inertia

NOZZLE_LENGTH_M = 0.15          # flange to tip, along tool0's z
NOZZLE_RADIUS_M = 0.02          # the tube
NOZZLE_MASS_KG = 0.3
ADAPTER_RADIUS_M = 0.032        # the flange's radius
ADAPTER_LENGTH_M = 0.015
NOZZLE_MATERIAL = ("nozzle_orange", (0.95, 0.45, 0.1, 1.0))


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
