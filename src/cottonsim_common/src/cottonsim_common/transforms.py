"""Rigid-body transforms and quaternions (numpy only), the one place for each.

Conventions: quaternions are (x, y, z, w) as in ROS messages (REP-103: x
forward, y left, z up, yaw counter-clockwise about z); a pose is a 4x4
homogeneous matrix ``a_T_b`` that maps points from frame b into frame a (so
``world_T_sensor = world_T_base @ base_T_sensor``). Code that talks to an
engine with another order (ODE's w, x, y, z) converts at that boundary.
"""
from __future__ import annotations

import math
from typing import Sequence, Tuple

import numpy as np


def quaternion_to_matrix(q_xyzw: Sequence[float]) -> np.ndarray:
    """Unit quaternion (x, y, z, w) -> 3x3 rotation matrix (normalises the input)."""
    x, y, z, w = (float(v) for v in q_xyzw)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if n == 0.0 or not math.isfinite(n):
        raise ValueError(f"quaternion {tuple(q_xyzw)} has no valid norm")
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def matrix_to_quaternion(rotation: np.ndarray) -> Tuple[float, float, float, float]:
    """3x3 rotation matrix -> unit quaternion (x, y, z, w) with w >= 0."""
    m = np.asarray(rotation, dtype=float)[:3, :3]
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        w, x, y, z = 0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        w, x, y, z = (m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        w, x, y, z = (m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        w, x, y, z = (m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return (x / n, y / n, z / n, w / n)


def pose_matrix(position: Sequence[float], q_xyzw: Sequence[float]) -> np.ndarray:
    """Position [m] + quaternion -> 4x4 homogeneous transform."""
    t = np.eye(4)
    t[:3, :3] = quaternion_to_matrix(q_xyzw)
    t[:3, 3] = np.asarray(position, dtype=float)
    return t


def transform_points(transform: np.ndarray, points_m) -> np.ndarray:
    """Points (N, 3) [m] of frame b expressed in frame a by the 4x4 ``a_T_b``: p_a = R p_b + t.

    NaN rows stay NaN; a transform that is not a finite 4x4 matrix raises ValueError.
    """
    t = np.asarray(transform, dtype=float)
    if t.shape != (4, 4) or not np.all(np.isfinite(t)):
        raise ValueError(f"the transform must be a finite 4x4 matrix, got shape {t.shape}")
    p = np.asarray(points_m, dtype=float).reshape(-1, 3)
    return p @ t[:3, :3].T + t[:3, 3]


def invert(transform: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (R^T, -R^T t)."""
    out = np.eye(4)
    r = transform[:3, :3]
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ transform[:3, 3]
    return out


def yaw_of(transform_or_quaternion) -> float:
    """Yaw [rad] (rotation about z, REP-103) of a 4x4/3x3 matrix or an (x, y, z, w) quaternion."""
    a = np.asarray(transform_or_quaternion, dtype=float)
    if a.shape == (4,):
        x, y, z, w = a
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return math.atan2(a[1, 0], a[0, 0])


def yaw_to_quaternion(yaw_rad: float) -> Tuple[float, float, float, float]:
    """A rotation about z as a quaternion (x, y, z, w)."""
    h = 0.5 * float(yaw_rad)
    return (0.0, 0.0, math.sin(h), math.cos(h))


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """Yaw [rad] of a quaternion (x, y, z, w), normalised first; roll and pitch are ignored.

    Raises ValueError for a zero-length or non-finite quaternion.
    """
    vals = (x, y, z, w)
    if not all(math.isfinite(v) for v in vals):
        raise ValueError(f"quaternion has non-finite components: {vals}")
    n = math.sqrt(sum(v * v for v in vals))
    if n < 1e-12:
        raise ValueError("quaternion has zero length")
    return yaw_of(np.array(vals) / n)
