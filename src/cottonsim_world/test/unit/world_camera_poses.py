"""Camera poses for the sensor tests: world_T_optical from a position, a heading and a downward tilt."""
import math

import numpy as np

# columns: the optical frame's x (right), y (down), z (forward) in the camera body frame (x forward, z up)
BODY_R_OPTICAL = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], float)


def optical_pose(x, y, z, yaw, pitch_down=0.0):
    """world_T_optical (4x4) of a camera at (x, y, z) [m] looking along yaw [rad], tilted down by pitch_down [rad]."""
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch_down), math.sin(pitch_down)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    t = np.eye(4)
    t[:3, :3] = rz @ ry @ BODY_R_OPTICAL
    t[:3, 3] = (x, y, z)
    return t
