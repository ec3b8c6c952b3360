"""Planar EKF fusing wheel odometry and IMU: the Husky's /odometry/filtered.

Clearpath runs robot_localization's ekf_localization_node on the Husky
(husky_control/config/localization.yaml): two_d_mode, 50 Hz, world_frame =
odom, fusing the wheel odometry's forward speed and yaw rate and the IMU's
yaw rate (optionally its yaw). This class is that filter cut down to the
states a planar robot needs:

    state s = [x, y, yaw, vx, vyaw]    (odom frame; vx, vyaw in base_link)

Motion model (constant velocity, over dt):
    x += vx cos(yaw) dt,  y += vx sin(yaw) dt,  yaw += vyaw dt
with process noise ``process_noise_diag * dt`` (robot_localization scales
its process noise by dt the same way). Each measurement is linear in the
state (it picks vx, vyaw or yaw), so the update is a standard Kalman update
with the yaw innovation wrapped to (-pi, pi].

The outputs are a pose and twist with 6x6 covariances in the
(x, y, z, roll, pitch, yaw) order of nav_msgs/Odometry, and the odom ->
base_link transform. Non-finite inputs are refused with a reason (returned
and appended to ``rejections``); the filter state is never touched by them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

X, Y, YAW, VX, VYAW = range(5)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class OdometryEkfConfig:
    """EKF parameters.

    frequency_hz: how often the caller runs predict (robot_localization: 50).
    process_noise_diag: per-second process noise of x, y, yaw, vx, vyaw
        (robot_localization's 2D defaults: 0.05, 0.05, 0.06, 0.025, 0.02).
    initial_covariance_diag: of the start state (robot_localization: 1e-9).
    max_dt_s: a predict longer than this is refused (clock jump) [s].
    """

    frequency_hz: float = 50.0
    process_noise_diag: Tuple[float, float, float, float, float] = (0.05, 0.05, 0.06, 0.025, 0.02)
    initial_covariance_diag: Tuple[float, float, float, float, float] = (1e-9, 1e-9, 1e-9, 1e-9, 1e-9)
    max_dt_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("frequency_hz", "max_dt_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"OdometryEkfConfig.{name} must be a finite number > 0, got {v!r}")
        for name in ("process_noise_diag", "initial_covariance_diag"):
            values = getattr(self, name)
            if len(values) != 5 or not all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0
                                           for v in values):
                raise ValueError(f"OdometryEkfConfig.{name} must be 5 finite numbers > 0, got {values!r}")


@dataclass(frozen=True)
class FilteredOdometry:
    """One /odometry/filtered output (odom frame, child base_link).

    pose_covariance / twist_covariance: 6x6 in (x, y, z, roll, pitch, yaw);
    the unobserved 3D entries get a tiny variance (two_d_mode).
    orientation_xyzw: quaternion of yaw.
    """

    x_m: float
    y_m: float
    yaw_rad: float
    linear_x_m_s: float
    angular_z_rad_s: float
    pose_covariance: np.ndarray
    twist_covariance: np.ndarray

    @property
    def orientation_xyzw(self) -> Tuple[float, float, float, float]:
        return (0.0, 0.0, math.sin(self.yaw_rad / 2.0), math.cos(self.yaw_rad / 2.0))

    def transform_odom_to_base_link(self) -> Tuple[Tuple[float, float, float], Tuple[float, float, float, float]]:
        """(translation [m], rotation (x, y, z, w)) of the odom -> base_link TF."""
        return (self.x_m, self.y_m, 0.0), self.orientation_xyzw


class OdometryEkf:
    """5-state planar EKF: predict(dt), update_wheel_odometry, update_imu."""

    def __init__(self, config: OdometryEkfConfig = OdometryEkfConfig()):
        self.config = config
        self._q = np.diag(np.asarray(config.process_noise_diag, dtype=float))
        self.rejections: List[str] = []
        self.reset()

    def reset(self, x_m: float = 0.0, y_m: float = 0.0, yaw_rad: float = 0.0) -> None:
        self.state = np.array([x_m, y_m, _wrap(yaw_rad), 0.0, 0.0], dtype=float)
        self.covariance = np.diag(np.asarray(self.config.initial_covariance_diag, dtype=float))

    def _reject(self, reason: str) -> str:
        self.rejections.append(reason)
        return reason

    @staticmethod
    def _bad_numbers(**values) -> Optional[str]:
        for name, value in values.items():
            arr = np.asarray(value, dtype=float)
            if not np.all(np.isfinite(arr)):
                return f"{name} contains NaN or inf ({np.asarray(value).tolist()})"
        return None

    # ------------------------------------------------------------- predict
    def predict(self, dt_s: float) -> Optional[str]:
        """Propagate the state by dt_s [s]; returns None or the reason it was refused."""
        try:
            dt = float(dt_s)
        except (TypeError, ValueError):
            return self._reject(f"predict: dt_s is not a number ({dt_s!r})")
        if not math.isfinite(dt) or dt < 0 or dt > self.config.max_dt_s:
            return self._reject(f"predict: dt_s must be finite and in [0, {self.config.max_dt_s}] s, got {dt_s!r}")
        s = self.state
        c, si = math.cos(s[YAW]), math.sin(s[YAW])
        f = np.eye(5)
        f[X, YAW] = -s[VX] * si * dt
        f[X, VX] = c * dt
        f[Y, YAW] = s[VX] * c * dt
        f[Y, VX] = si * dt
        f[YAW, VYAW] = dt
        s[X] += s[VX] * c * dt
        s[Y] += s[VX] * si * dt
        s[YAW] = _wrap(s[YAW] + s[VYAW] * dt)
        self.covariance = f @ self.covariance @ f.T + self._q * dt
        return None

    # ------------------------------------------------------------- updates
    def _update(self, rows: Sequence[int], z: np.ndarray, r: np.ndarray) -> None:
        h = np.zeros((len(rows), 5))
        for i, row in enumerate(rows):
            h[i, row] = 1.0
        innovation = z - h @ self.state
        for i, row in enumerate(rows):
            if row == YAW:
                innovation[i] = _wrap(innovation[i])
        p = self.covariance
        s_mat = h @ p @ h.T + r
        k = np.linalg.solve(s_mat.T, (p @ h.T).T).T
        self.state = self.state + k @ innovation
        self.state[YAW] = _wrap(self.state[YAW])
        # Joseph form keeps the covariance symmetric positive definite.
        i_kh = np.eye(5) - k @ h
        self.covariance = i_kh @ p @ i_kh.T + k @ r @ k.T

    @staticmethod
    def _variance(cov, name: str) -> Tuple[Optional[float], Optional[str]]:
        try:
            v = float(cov)
        except (TypeError, ValueError):
            return None, f"{name} must be a number, got {cov!r}"
        if not math.isfinite(v) or v <= 0:
            return None, f"{name} must be a finite variance > 0, got {cov!r}"
        return v, None

    def update_wheel_odometry(self, v_m_s: float, w_rad_s: float, cov: Sequence[float]) -> Optional[str]:
        """Fuse wheel odometry forward speed v [m/s] and yaw rate w [rad/s].

        cov: variances (var_v, var_w), or the 6x6 / 36-element twist
        covariance of nav_msgs/Odometry (entries [0,0] and [5,5] are used).
        """
        bad = self._bad_numbers(v_m_s=v_m_s, w_rad_s=w_rad_s)
        if bad:
            return self._reject(f"wheel odometry rejected: {bad}")
        arr = np.asarray(cov, dtype=float).reshape(-1)
        if arr.size == 36:
            arr = np.array([arr[0], arr[35]])
        if arr.size != 2:
            return self._reject(f"wheel odometry rejected: cov must be (var_v, var_w) or 6x6, got {arr.size} values")
        var_v, err_v = self._variance(arr[0], "wheel odometry var_v")
        var_w, err_w = self._variance(arr[1], "wheel odometry var_w")
        if err_v or err_w:
            return self._reject(f"wheel odometry rejected: {err_v or err_w}")
        self._update([VX, VYAW], np.array([float(v_m_s), float(w_rad_s)]), np.diag([var_v, var_w]))
        return None

    def update_imu(self, yaw_rate_rad_s: float, cov: float, yaw: Optional[float] = None,
                   yaw_cov: Optional[float] = None) -> Optional[str]:
        """Fuse the IMU yaw rate [rad/s] (variance cov) and optionally its yaw [rad].

        yaw_cov: variance of yaw [rad^2]; required when yaw is given.
        """
        bad = self._bad_numbers(yaw_rate_rad_s=yaw_rate_rad_s) or (
            self._bad_numbers(yaw=yaw) if yaw is not None else None)
        if bad:
            return self._reject(f"IMU rejected: {bad}")
        var_r, err = self._variance(cov, "IMU yaw-rate cov")
        if err:
            return self._reject(f"IMU rejected: {err}")
        if yaw is None:
            self._update([VYAW], np.array([float(yaw_rate_rad_s)]), np.array([[var_r]]))
            return None
        var_y, err = self._variance(yaw_cov, "IMU yaw_cov")
        if err:
            return self._reject(f"IMU rejected: {err}")
        self._update([YAW, VYAW], np.array([float(yaw), float(yaw_rate_rad_s)]), np.diag([var_y, var_r]))
        return None

    # -------------------------------------------------------------- output
    def output(self) -> FilteredOdometry:
        """Current estimate as /odometry/filtered contents."""
        p = self.covariance
        tiny = 1e-9
        pose = np.diag([0.0, 0.0, tiny, tiny, tiny, 0.0])
        pose[np.ix_([0, 1, 5], [0, 1, 5])] = p[np.ix_([X, Y, YAW], [X, Y, YAW])]
        twist = np.diag([0.0, tiny, tiny, tiny, tiny, 0.0])
        twist[np.ix_([0, 5], [0, 5])] = p[np.ix_([VX, VYAW], [VX, VYAW])]
        s = self.state
        return FilteredOdometry(float(s[X]), float(s[Y]), float(s[YAW]), float(s[VX]), float(s[VYAW]),
                                pose, twist)
