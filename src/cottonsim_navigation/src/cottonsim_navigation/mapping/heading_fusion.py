"""Odometry with the heading held by an absolute IMU yaw: a complementary filter for the mapper.

Why: wheel odometry fused with the gyro (the Husky's EKF, /odometry/filtered)
keeps its position well along a row, but its heading drifts with the gyro's
bias (about 1 deg per 100 s in the simulator), and a heading error bends every
row of the map. The IMU also reports an absolute orientation whose yaw is noisy
(white, ~0.3 deg) but drifts far more slowly (the hector model: a bias of
0.005 rad std with a one-hour correlation time). The SLAM scan matcher cannot
fix the heading inside crop rows reliably: the hedges seen at grazing angles
pull the match by a degree or more.

How: the filter tracks ``c = yaw_imu - yaw_odom``, the odometry's heading error
(plus the IMU's fixed reference). With ``track_rate`` (the default) it is a
second-order tracking loop (critically damped, natural frequency ``1 / tau_s``)
that also estimates the drift *rate* ``r`` of that error::

    e = (yaw_imu - yaw_odom) - c;   c += (r + 2 e / tau_s) dt;   r += e dt / tau_s^2

A steady gyro drift is then followed without lag. The first-order low-pass
(``track_rate=False``: ``c += e dt / tau_s``) lags a drift of rate ``r`` by
``r * tau_s``: on the simulator's mapping drive the EKF odometry's heading drifted
0.08 deg/s for minutes (its wheel and gyro yaw rates disagree in skid-steer
turns), and the 10 s low-pass left the SLAM heading 0.8-1.0 deg off, which drew
the later lanes of the map 0.3 m sideways. Offline over that drive (10 Hz IMU
samples at scan times, 0.3 deg white noise) the heading error against ground
truth was mean 0.55 deg / max 1.18 deg with the first-order 10 s filter and
0.075 / 0.32 deg with the second-order loop at 5 s. In both forms the first
samples are averaged (a running mean while it is the stronger smoothing), so
the IMU's noise at rest does not set the reference.

While the robot has not moved yet, the reference ``c_ref`` follows ``c``
(averaging the IMU at rest fixes the map frame's heading; the rate stays 0);
afterwards the corrected pose is the odometry pose turned by ``k = c - c_ref``:
its yaw is ``yaw_odom + k`` and each odometry displacement is rotated by ``k``
before it is added, so the fused pose starts equal to the odometry pose and its
heading is the IMU's (relative to the start). A gap of more than ``tau_s``
between IMU samples restarts the average (the rate estimate is kept).
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from cottonsim_common.angles import wrap_angle
from cottonsim_common.validation import require_bool


class HeadingFuser:
    """Complementary filter: odometry poses (x_m, y_m, yaw_rad) in, heading-corrected poses out.

    tau_s: time constant of the filter on the IMU - odometry yaw difference [s];
    still_m, still_rad: odometry motion from the first pose below which the robot counts as standing [m, rad];
    track_rate: also estimate the drift rate of that difference (second-order loop, no lag for a steady
        drift) instead of a first-order low-pass.
    """

    def __init__(self, tau_s: float = 5.0, still_m: float = 0.01, still_rad: float = 0.01,
                 track_rate: bool = True) -> None:
        for name, v in (("tau_s", tau_s), ("still_m", still_m), ("still_rad", still_rad)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        require_bool("track_rate", track_rate)
        self.track_rate = track_rate
        self._r = 0.0
        self.tau_s = float(tau_s)
        self.still_m = float(still_m)
        self.still_rad = float(still_rad)
        self._c: Optional[float] = None
        self._c_ref = 0.0
        self._n = 0
        self._first: Optional[np.ndarray] = None
        self._last_raw: Optional[np.ndarray] = None
        self._last_imu_t: Optional[float] = None
        self._moved = False
        self._k = 0.0
        self._fused: Optional[np.ndarray] = None

    @property
    def drift_rate_rad_s(self) -> float:
        """Estimated drift rate of the odometry heading against the IMU [rad/s] (0 without track_rate)."""
        return self._r

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
        if imu_yaw_rad is not None:
            diff = wrap_angle(float(imu_yaw_rad) - raw[2])
            gap = max(float(stamp_s) - self._last_imu_t, 0.0) if self._last_imu_t is not None else 0.0
            self._last_imu_t = float(stamp_s)
            if self._c is None or gap > self.tau_s:
                self._c, self._n = diff, 1
            else:
                self._n += 1
                e = wrap_angle(diff - self._c)
                w = 1.0 / self.tau_s
                if not self.track_rate:
                    self._c = wrap_angle(self._c + max(min(gap * w, 1.0), 1.0 / self._n) * e)
                elif 1.0 / self._n > 2.0 * w * gap:     # start: a running mean smooths more than the loop
                    self._c = wrap_angle(self._c + e / self._n + self._r * gap)
                else:
                    self._c = wrap_angle(self._c + (self._r + 2.0 * w * e) * gap)
                    self._r += w * w * e * gap
        if not self._moved:
            d = raw - self._first
            if math.hypot(d[0], d[1]) > self.still_m or abs(wrap_angle(d[2])) > self.still_rad:
                self._moved = True
            elif self._c is not None:
                self._c_ref = self._c
                self._r = 0.0
        k_prev = self._k
        self._k = wrap_angle(self._c - self._c_ref) if self._c is not None else 0.0
        k_mid = k_prev + 0.5 * wrap_angle(self._k - k_prev)
        c, s = math.cos(k_mid), math.sin(k_mid)
        dx, dy = raw[0] - self._last_raw[0], raw[1] - self._last_raw[1]
        self._fused = np.array([self._fused[0] + c * dx - s * dy, self._fused[1] + s * dx + c * dy,
                                wrap_angle(raw[2] + self._k)])
        self._last_raw = raw.copy()
        return self._fused.copy()
