"""An IMU mounted in the robot at a fixed rotation: its samples in its own axes.

The IMU model (``imu_model.ImuModel``) measures in base_link axes; a real
IMU mounted as the URDF's imu_link reports in imu_link axes. ``ImuMount``
expresses a sample there: rates and specific force rotate with
R_base_imu^T, covariances with R^T C R, and the orientation becomes that of
imu_link in the world (q_world_base * q_base_imu); consumers use TF
base_link <- imu_link.
"""
from __future__ import annotations

import math
from typing import Dict

import numpy as np

from cottonsim_common.transforms import matrix_to_quaternion

from .imu_model import ImuMeasurement


class ImuMount:
    """The rotation base_link <- imu_link (3x3) and the samples expressed in imu_link axes."""

    def __init__(self, r_base_imu: np.ndarray) -> None:
        self._rotation = np.asarray(r_base_imu, dtype=float)
        # plain floats for the 50 Hz IMU path (numpy per-call overhead)
        self._rows = tuple(tuple(float(v) for v in row) for row in self._rotation)
        self._q_base_imu = tuple(float(v) for v in matrix_to_quaternion(self._rotation))
        self._cov_cache: Dict[bytes, np.ndarray] = {}

    def in_imu_axes(self, m: ImuMeasurement) -> ImuMeasurement:
        """The sample ``m`` (base_link axes) in imu_link axes (see the module docstring).

        Runs at the IMU rate on 3-vectors: plain floats, and the (constant) covariances
        are rotated once and cached.
        """
        (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = self._rows

        def rotate(v):   # R^T v
            x, y, z = v.tolist() if isinstance(v, np.ndarray) else v
            return np.array((a00 * x + a10 * y + a20 * z, a01 * x + a11 * y + a21 * z, a02 * x + a12 * y + a22 * z))

        def cov(c):
            c = np.asarray(c, dtype=float)
            key = c.tobytes()
            out = self._cov_cache.get(key)
            if out is None:
                r = self._rotation
                out = (r.T @ c.reshape(3, 3) @ r).reshape(9)
                if len(self._cov_cache) < 64:
                    self._cov_cache[key] = out
            return out.copy()

        # Hamilton product q_world_base * q_base_imu, sign chosen with w >= 0
        ax, ay, az, aw = m.orientation_xyzw.tolist() if isinstance(m.orientation_xyzw, np.ndarray) \
            else m.orientation_xyzw
        bx, by, bz, bw = self._q_base_imu
        q = (aw * bx + ax * bw + ay * bz - az * by,
             aw * by - ax * bz + ay * bw + az * bx,
             aw * bz + ax * by - ay * bx + az * bw,
             aw * bw - ax * bx - ay * by - az * bz)
        n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        if q[3] < 0.0:
            n = -n
        return ImuMeasurement(
            stamp_s=m.stamp_s, orientation_xyzw=np.array((q[0] / n, q[1] / n, q[2] / n, q[3] / n)),
            angular_velocity_rad_s=rotate(m.angular_velocity_rad_s),
            linear_acceleration_m_s2=rotate(m.linear_acceleration_m_s2),
            orientation_covariance=cov(m.orientation_covariance),
            angular_velocity_covariance=cov(m.angular_velocity_covariance),
            linear_acceleration_covariance=cov(m.linear_acceleration_covariance))
