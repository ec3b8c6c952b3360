"""Twist -> wheel speed controller of the Husky (husky_velocity_controller).

The real Husky and the original Gazebo model both run ROS'
``diff_drive_controller``: it takes /cmd_vel (linear x, angular z), clamps
the velocity and the acceleration, zeroes the command when none arrived for
``cmd_timeout_s`` and turns the twist into one angular velocity per side,
using the URDF track widened by ``wheel_separation_multiplier``. This module
is that behaviour as a pure class; the ODE world feeds its output to the
wheel motors.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional

from .husky_params import DriveLimits, HuskyParams


@dataclass(frozen=True)
class WheelTargets:
    """One controller output.

    left_rad_s / right_rad_s: wheel angular velocity targets [rad/s] (positive
    drives the robot forward); linear_x_m_s / angular_z_rad_s: the limited
    twist they realise in the controller's kinematic model.
    """

    left_rad_s: float
    right_rad_s: float
    linear_x_m_s: float
    angular_z_rad_s: float
    timed_out: bool


def _clamp(value: float, limit: float) -> float:
    return max(-limit, min(limit, value))


class DiffDriveController:
    """Rate-limited twist to per-side wheel speeds, with command time-out.

    Usage: call ``set_command(v, w, stamp_s)`` whenever a twist arrives and
    ``update(now_s)`` at the control rate; ``update`` returns WheelTargets.
    Non-finite commands are refused: ``set_command`` returns a reason string
    (also appended to ``rejections``) and the previous command stays.
    """

    def __init__(self, husky: HuskyParams = HuskyParams(), limits: DriveLimits = DriveLimits()):
        self._husky = husky
        self._limits = limits
        self._cmd_v = 0.0
        self._cmd_w = 0.0
        self._cmd_stamp_s: Optional[float] = None
        self._out_v = 0.0
        self._out_w = 0.0
        self._last_update_s: Optional[float] = None
        self.rejections: List[str] = []

    @property
    def effective_track_m(self) -> float:
        """Track used in the kinematics: URDF track x wheel_separation_multiplier [m]."""
        return self._husky.track_m * self._limits.wheel_separation_multiplier

    @property
    def effective_radius_m(self) -> float:
        return self._husky.wheel_radius_m * self._limits.wheel_radius_multiplier

    def set_command(self, linear_x: float, angular_z: float, stamp_s: float) -> Optional[str]:
        """Store a twist command [m/s, rad/s] received at stamp_s [s].

        Returns None when accepted, else a reason (the command is ignored).
        """
        for name, value in (("linear_x", linear_x), ("angular_z", angular_z), ("stamp_s", stamp_s)):
            try:
                ok = math.isfinite(float(value))
            except (TypeError, ValueError):
                ok = False
            if not ok:
                reason = f"cmd_vel rejected: {name} is not a finite number ({value!r})"
                self.rejections.append(reason)
                return reason
        self._cmd_v = float(linear_x)
        self._cmd_w = float(angular_z)
        self._cmd_stamp_s = float(stamp_s)
        return None

    def reset(self) -> None:
        """Forget the command and the limiter state (robot re-spawned)."""
        self._cmd_v = self._cmd_w = self._out_v = self._out_w = 0.0
        self._cmd_stamp_s = None
        self._last_update_s = None

    def update(self, now_s: float) -> WheelTargets:
        """Advance the limiter to now_s [s] and return the wheel targets."""
        if not math.isfinite(now_s):
            raise ValueError(f"now_s must be finite, got {now_s!r}")
        lim = self._limits
        timed_out = self._cmd_stamp_s is None or (now_s - self._cmd_stamp_s) > lim.cmd_timeout_s
        target_v = 0.0 if timed_out else _clamp(self._cmd_v, lim.max_linear_m_s)
        target_w = 0.0 if timed_out else _clamp(self._cmd_w, lim.max_angular_rad_s)
        dt = 0.0 if self._last_update_s is None else max(0.0, now_s - self._last_update_s)
        self._last_update_s = now_s
        # Like diff_drive_controller's SpeedLimiter: clamp the velocity, then
        # the change per period (acceleration); with dt = 0 (first call) the
        # output can not change.
        self._out_v += _clamp(target_v - self._out_v, lim.max_linear_acc_m_s2 * dt)
        self._out_w += _clamp(target_w - self._out_w, lim.max_angular_acc_rad_s2 * dt)
        half = 0.5 * self.effective_track_m
        r = self.effective_radius_m
        return WheelTargets(
            left_rad_s=(self._out_v - self._out_w * half) / r,
            right_rad_s=(self._out_v + self._out_w * half) / r,
            linear_x_m_s=self._out_v,
            angular_z_rad_s=self._out_w,
            timed_out=timed_out,
        )
