"""Wheel odometry of the Husky, as husky_velocity_controller publishes it.

``diff_drive_controller`` treats the four-wheeled Husky as a two-wheeled
differential drive: each side's speed is the mean of its two wheels, the
robot's forward speed is their mean and its yaw rate their difference over
the *effective* track (URDF track x wheel_separation_multiplier 1.875).
The pose is the integral of that twist (exact arc when turning, a
second-order Runge-Kutta step when nearly straight, like the controller's
Odometry class). Wheel slip from the ODE contacts shows up naturally as
odometry drift, as on the real robot.

Input: measured wheel angular velocities [rad/s] in the order FL, FR, RL,
RR (``RobotState.wheel_velocities_rad_s``) and the time since the last
update. Output: pose and twist with the covariance diagonals the Husky
publishes on /husky_velocity_controller/odom.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from cottonsim_common.transforms import yaw_to_quaternion
from cottonsim_common.validation import require_fields, require_finite_values

from .husky_params import DriveLimits, HuskyParams


_HUSKY, _LIMITS = HuskyParams(), DriveLimits()     # the defaults, declared once there


@dataclass(frozen=True)
class WheelOdometryConfig:
    """Kinematic parameters of the odometry (defaults: the Husky's, ``HuskyParams`` and ``DriveLimits``).

    wheel_radius_m, track_m: URDF values; wheel_separation_multiplier and
    wheel_radius_multiplier: control.yaml's corrections. Covariance
    diagonals are (x, y, z, roll, pitch, yaw) as in control.yaml.
    """

    wheel_radius_m: float = _HUSKY.wheel_radius_m
    track_m: float = _HUSKY.track_m
    wheel_separation_multiplier: float = _LIMITS.wheel_separation_multiplier
    wheel_radius_multiplier: float = _LIMITS.wheel_radius_multiplier
    pose_covariance_diagonal: Tuple[float, ...] = _LIMITS.pose_covariance_diagonal
    twist_covariance_diagonal: Tuple[float, ...] = _LIMITS.twist_covariance_diagonal

    def __post_init__(self) -> None:
        require_fields(self, "WheelOdometryConfig.",
                       positive=("wheel_radius_m", "track_m", "wheel_separation_multiplier", "wheel_radius_multiplier"))
        for name in ("pose_covariance_diagonal", "twist_covariance_diagonal"):
            require_finite_values(f"WheelOdometryConfig.{name}", getattr(self, name), 6, low=0.0)

    @classmethod
    def from_husky(cls, husky: HuskyParams = HuskyParams(), limits: DriveLimits = DriveLimits()) -> "WheelOdometryConfig":
        return cls(wheel_radius_m=husky.wheel_radius_m, track_m=husky.track_m,
                   wheel_separation_multiplier=limits.wheel_separation_multiplier,
                   wheel_radius_multiplier=limits.wheel_radius_multiplier,
                   pose_covariance_diagonal=tuple(limits.pose_covariance_diagonal),
                   twist_covariance_diagonal=tuple(limits.twist_covariance_diagonal))


@dataclass(frozen=True)
class OdometryEstimate:
    """Odometry in the odom frame, from the wheels or from the EKF (/odometry/filtered).

    x_m, y_m, yaw_rad: pose; linear_x_m_s, angular_z_rad_s: body twist;
    pose_covariance / twist_covariance: 6x6 (x, y, z, roll, pitch, yaw).
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
        return yaw_to_quaternion(self.yaw_rad)

    def transform_odom_to_base_link(self) -> Tuple[Tuple[float, float, float], Tuple[float, float, float, float]]:
        """(translation [m], rotation (x, y, z, w)) of the odom -> base_link TF."""
        return (self.x_m, self.y_m, 0.0), self.orientation_xyzw


def _four_floats(values) -> Tuple[float, float, float, float]:
    """FL, FR, RL, RR as Python floats (50 Hz on 4 numbers: plain floats beat numpy here)."""
    if isinstance(values, np.ndarray) and values.dtype == np.float64 and values.size == 4:
        out = values.reshape(-1).tolist()
    else:
        try:
            out = np.asarray(values, dtype=float).reshape(-1).tolist()
        except (TypeError, ValueError) as exc:
            raise ValueError(f"wheel velocities must be numbers, got {values!r}") from exc
        if len(out) != 4:
            raise ValueError(f"need 4 wheel velocities (FL, FR, RL, RR), got shape {np.shape(values)}")
    return out[0], out[1], out[2], out[3]


class WheelOdometry:
    """Integrates wheel speeds into an odometry pose and twist."""

    def __init__(self, config: WheelOdometryConfig = WheelOdometryConfig()):
        self.config = config
        self._pose_cov = np.diag(np.asarray(config.pose_covariance_diagonal, dtype=float))
        self._twist_cov = np.diag(np.asarray(config.twist_covariance_diagonal, dtype=float))
        self.rejections: List[str] = []
        self.reset()

    def reset(self, x_m: float = 0.0, y_m: float = 0.0, yaw_rad: float = 0.0) -> None:
        self._x, self._y, self._yaw = float(x_m), float(y_m), float(yaw_rad)
        self._v = self._w = 0.0

    def twist_from_wheels(self, wheel_velocities_rad_s) -> Tuple[float, float]:
        """(linear x [m/s], angular z [rad/s]) of FL, FR, RL, RR wheel speeds [rad/s]."""
        return self._twist(*_four_floats(wheel_velocities_rad_s))

    def _twist(self, fl: float, fr: float, rl: float, rr: float) -> Tuple[float, float]:
        r = self.config.wheel_radius_m * self.config.wheel_radius_multiplier
        left = 0.5 * (fl + rl) * r
        right = 0.5 * (fr + rr) * r
        ws = self.config.track_m * self.config.wheel_separation_multiplier
        return 0.5 * (left + right), (right - left) / ws

    def update(self, wheel_velocities_rad_s, dt_s: float) -> Optional[str]:
        """Integrate over dt_s [s]; returns None, or the reason the sample was ignored."""
        try:
            wv = _four_floats(wheel_velocities_rad_s)
        except ValueError as exc:
            wv, reason = None, f"wheel odometry: {exc}"
        else:
            if not all(math.isfinite(v) for v in wv):
                reason = f"wheel odometry: wheel velocities contain NaN or inf: {list(wv)}"
            elif not (isinstance(dt_s, (int, float)) and math.isfinite(dt_s) and dt_s >= 0):
                reason = f"wheel odometry: dt_s must be finite and >= 0, got {dt_s!r}"
            else:
                reason = None
        if reason is not None:
            self.rejections.append(reason)
            return reason
        v, w = self._twist(*wv)
        self._v, self._w = v, w
        dyaw = w * dt_s
        if abs(dyaw) < 1e-6:
            # second-order Runge-Kutta (heading at mid-step)
            mid = self._yaw + 0.5 * dyaw
            self._x += v * dt_s * math.cos(mid)
            self._y += v * dt_s * math.sin(mid)
        else:
            radius = v / w
            new_yaw = self._yaw + dyaw
            self._x += radius * (math.sin(new_yaw) - math.sin(self._yaw))
            self._y -= radius * (math.cos(new_yaw) - math.cos(self._yaw))
        self._yaw = (self._yaw + dyaw + math.pi) % (2.0 * math.pi) - math.pi
        return None

    def estimate(self) -> OdometryEstimate:
        return OdometryEstimate(self._x, self._y, self._yaw, self._v, self._w,
                                self._pose_cov.copy(), self._twist_cov.copy())
