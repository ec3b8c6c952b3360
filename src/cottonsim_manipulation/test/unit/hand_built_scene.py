"""A hand-built scene for the manipulation tests: the robot's body from the committed URDF and
cotton plants as capsules beside the robot (everything in the arm's base frame)."""
import math
import pathlib

import numpy as np

from cottonsim_common.capsules import CapsuleSet

ROOT = pathlib.Path(__file__).resolve().parents[4]
URDF = ROOT / "src/cottonsim_description/urdf/cottonsim_robot.urdf"
# The arm's base frame is 0.383 m above the ground (base_link 0.13228 m, top plate 0.245 m,
# arm mount 0.006 m); its x axis points to the robot's left, y backwards, z up.
GROUND_Z_M = -(0.13228 + 0.245 + 0.006)
# A stow pose over the robot, clear of the body.
STOW_RAD = np.array([math.pi / 2, -2.2, 2.4, -1.77, -math.pi / 2, 0.0])


def hand_plant(x_m, y_m, name="plant", height_m=0.93):
    """A cotton plant as capsules: a 16 mm stem and ten 8 mm branches spiralling up it."""
    ground = GROUND_Z_M
    caps = [((x_m, y_m, ground), (x_m, y_m, ground + height_m), 0.008, f"{name}/stem")]
    for k in range(10):
        h = ground + 0.15 + 0.07 * k
        angle = k * 2.4
        length = 0.1 + 0.2 * math.sin(math.pi * (k + 1) / 11)
        tip = (x_m + length * math.cos(angle), y_m + length * math.sin(angle), h + 0.05)
        caps.append(((x_m, y_m, h), tip, 0.004, f"{name}/branch{k}"))
    return caps


def plant_row():
    """Three plants of a row 0.9 m to the robot's left (arm +x), 0.7 m apart."""
    return CapsuleSet.from_list(hand_plant(0.9, -0.7, "p0") + hand_plant(0.9, 0.0, "p1") + hand_plant(0.9, 0.7, "p2"))
