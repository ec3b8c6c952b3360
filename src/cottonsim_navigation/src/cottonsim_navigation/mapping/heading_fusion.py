"""Odometry with the heading held by an absolute IMU yaw: a complementary filter for the mapper.

Why: wheel odometry fused with the gyro (the Husky's EKF, /odometry/filtered)
keeps its position well along a row, but its heading drifts with the gyro's
bias (about 1 deg per 100 s in the simulator), and a heading error bends every
row of the map. The IMU also reports an absolute orientation whose yaw is noisy
(white, ~0.3 deg) but drifts far more slowly (the hector model: a bias of
0.005 rad std with a one-hour correlation time). The SLAM scan matcher cannot
fix the heading inside crop rows reliably: the hedges seen at grazing angles
pull the match by a degree or more.

How: the filter tracks ``c = yaw_imu - yaw_odom`` with a first-order low-pass
(time constant ``tau_s``; a running mean over the first samples), so the
IMU's white noise averages out while the gyro's slow drift is followed. While
the robot has not moved yet, the reference ``c_ref`` follows ``c`` (averaging
the IMU at rest fixes the map frame's heading); afterwards the corrected pose
is the odometry pose turned by ``k = c - c_ref``: its yaw is ``yaw_odom + k``
and each odometry displacement is rotated by ``k`` before it is added, so the
fused pose starts equal to the odometry pose and its heading is the IMU's
(relative to the start).
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ..core.geometry import normalize_angle


class HeadingFuser:
    """Complementary filter: odometry poses (x_m, y_m, yaw_rad) in, heading-corrected poses out.

    tau_s: time constant of the low-pass on the IMU - odometry yaw difference [s];
    still_m, still_rad: odometry motion from the first pose below which the robot counts as standing [m, rad].
    """

    def __init__(self, tau_s: float = 10.0, still_m: float = 0.01, still_rad: float = 0.01) -> None:
        for name, v in (("tau_s", tau_s), ("still_m", still_m), ("still_rad", still_rad)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        self.tau_s = float(tau_s)
        self.still_m = float(still_m)
        self.still_rad = float(still_rad)
        self._c: Optional[float] = None
        self._c_ref = 0.0
        self._n = 0
        self._first: Optional[np.ndarray] = None
        self._last_raw: Optional[np.ndarray] = None
        self._last_t = 0.0
        self._moved = False
        self._k = 0.0
        self._fused: Optional[np.ndarray] = None

    @property
    def correction_rad(self) -> float:
        """Current heading correction k added to the odometry yaw [rad]."""
        return self._k

    def update(self, odom_pose, imu_yaw_rad: Optional[float], stamp_s: float) -> np.ndarray:
        """Feed one odometry pose with the IMU yaw at the same time (None: no IMU sample); return the fused pose."""
        raw = np.asarray(odom_pose, dtype=float).reshape(-1)
        if raw.shape != (3,) or not np.all(np.isfinite(raw)):
            raise ValueError(f"odom_pose must be 3 finite values (x_m, y_m, yaw_rad), got {odom_pose!r}")
        if imu_yaw_rad is not None and not (isinstance(imu_yaw_rad, (int, float)) and math.isfinite(imu_yaw_rad)):
            raise ValueError(f"imu_yaw_rad must be a finite number or None, got {imu_yaw_rad!r}")
        if not (isinstance(stamp_s, (int, float)) and math.isfinite(stamp_s)):
            raise ValueError(f"stamp_s must be a finite number, got {stamp_s!r}")
        if self._fused is None:
            self._first = raw.copy()
            self._last_raw = raw.copy()
            self._fused = raw.copy()
            self._last_t = float(stamp_s)
        dt = max(float(stamp_s) - self._last_t, 0.0)
        self._last_t = max(self._last_t, float(stamp_s))
        if imu_yaw_rad is not None:
            diff = normalize_angle(float(imu_yaw_rad) - raw[2])
            if self._c is None:
                self._c, self._n = diff, 1
            else:
                self._n += 1
                alpha = max(min(dt / self.tau_s, 1.0), 1.0 / self._n)
                self._c = normalize_angle(self._c + alpha * normalize_angle(diff - self._c))
        if not self._moved:
            d = raw - self._first
            if math.hypot(d[0], d[1]) > self.still_m or abs(normalize_angle(d[2])) > self.still_rad:
                self._moved = True
            elif self._c is not None:
                self._c_ref = self._c
        k_prev = self._k
        self._k = normalize_angle(self._c - self._c_ref) if self._c is not None else 0.0
        k_mid = k_prev + 0.5 * normalize_angle(self._k - k_prev)
        c, s = math.cos(k_mid), math.sin(k_mid)
        dx, dy = raw[0] - self._last_raw[0], raw[1] - self._last_raw[1]
        self._fused = np.array([self._fused[0] + c * dx - s * dy, self._fused[1] + s * dx + c * dy,
                                normalize_angle(raw[2] + self._k)])
        self._last_raw = raw.copy()
        return self._fused.copy()
