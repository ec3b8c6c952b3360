"""Angles: the one wrap into [-pi, pi) and the signed difference of two headings.

Every package wraps angles through this module, so a heading means the same
number everywhere (odometry, filters, planners, exported routes). Scalars stay
floats and numpy arrays stay arrays. ``wrap_angle_scalar`` is plain float
arithmetic so numba kernels can compile it (``njit(wrap_angle_scalar)``).
"""
from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi


def wrap_angle_scalar(angle_rad: float) -> float:
    """One angle [rad] wrapped into [-pi, pi) (float arithmetic only)."""
    return (angle_rad + math.pi) % TWO_PI - math.pi


def wrap_angle(angle_rad):
    """Angles [rad] wrapped into [-pi, pi); a scalar gives a float, an array an array."""
    if np.ndim(angle_rad) == 0:
        return wrap_angle_scalar(float(angle_rad))
    return (np.asarray(angle_rad, dtype=float) + np.pi) % TWO_PI - np.pi


def shortest_angular_distance(from_rad, to_rad):
    """Signed smallest rotation [rad] taking ``from_rad`` to ``to_rad`` (ROS angles::)."""
    if np.ndim(from_rad) == 0 and np.ndim(to_rad) == 0:
        return wrap_angle_scalar(float(to_rad) - float(from_rad))
    return wrap_angle(np.asarray(to_rad, dtype=float) - np.asarray(from_rad, dtype=float))
