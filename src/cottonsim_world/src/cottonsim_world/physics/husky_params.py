"""Geometry, mass and drive limits of the Clearpath Husky A200.

Two frozen dataclasses, shared by the ODE dynamics (``physics.ode_world``),
the drive controller (``physics.diff_drive``) and the wheel odometry
(``physics.wheel_odometry``), so every part of the simulator uses one set of
numbers.

Sources
-------
* Overall size 0.990 x 0.670 x 0.390 m, 75 kg payload: the CottonSim paper
  (section 2.4) and Clearpath's data sheet.
* Wheel radius 0.1651 m, width 0.1143 m, mass 2.637 kg, wheelbase 0.512 m,
  track 0.5708 m, base_link 0.13228 m above the ground, wheel axles 0.03282 m
  above base_link, chassis mass 46.034 kg with its inertia tensor, and the
  two collision boxes of the chassis: Clearpath's ``husky_description``
  (``urdf/husky.urdf.xacro``, noetic-devel), which the original CottonSim
  used unchanged.
* Drive limits, time-out and odometry covariances: Clearpath's
  ``husky_control/config/control.yaml`` (noetic-devel), the parameters of
  ``husky_velocity_controller`` (a ``diff_drive_controller``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple

from cottonsim_common.validation import require_fields, require_finite_values, require_positive


@dataclass(frozen=True)
class HuskyParams:
    """Rigid-body model of the Husky A200 base (no arm, no sensors).

    Frames: base_link sits on the chassis' bottom plane, centred between the
    wheels, ``base_link_height_m`` above flat ground; x forward, y left, z up.
    Chassis boxes are given as (centre in base_link [m], full size [m]).
    """

    # Overall dimensions (paper / data sheet) [m]; the collision boxes below
    # are the URDF's, which are slightly smaller (wheels stick out the sides).
    overall_length_m: float = 0.990
    overall_width_m: float = 0.670
    overall_height_m: float = 0.390

    # husky.urdf.xacro, link base_link, <inertial>: mass 46.034 kg,
    # ixx 0.6022, iyy 1.7386, izz 2.0296 kg m^2 (small products of inertia
    # dropped). The URDF puts the centre of mass at (-0.00065, -0.085, 0.062);
    # we keep only the height so the model is left/right symmetric and drives
    # straight; the sideways offset in the URDF comes from the mesh, not from
    # a measured robot.
    chassis_mass_kg: float = 46.034
    chassis_inertia_kg_m2: Tuple[float, float, float] = (0.6022, 1.7386, 2.0296)
    chassis_com_height_m: float = 0.062          # above base_link

    # Collision boxes of base_link in the URDF: lower body and upper body.
    lower_box_centre_m: Tuple[float, float, float] = (0.0, 0.0, 0.061875)
    lower_box_size_m: Tuple[float, float, float] = (0.9874, 0.5709, 0.12375)
    upper_box_centre_m: Tuple[float, float, float] = (0.0, 0.0, 0.175625)
    upper_box_size_m: Tuple[float, float, float] = (0.78992, 0.5709, 0.10375)

    wheel_radius_m: float = 0.1651
    wheel_width_m: float = 0.1143
    wheel_mass_kg: float = 2.637
    wheelbase_m: float = 0.512                   # front axle to rear axle
    track_m: float = 0.5708                      # left wheel centre to right wheel centre
    base_link_height_m: float = 0.13228          # base_link above the ground at rest
    wheel_axle_z_m: float = 0.03282              # axle height relative to base_link

    def __post_init__(self) -> None:
        require_fields(self, positive=("overall_length_m", "overall_width_m", "overall_height_m", "chassis_mass_kg",
                                       "wheel_radius_m", "wheel_width_m", "wheel_mass_kg", "wheelbase_m", "track_m",
                                       "base_link_height_m"))
        for name in ("chassis_inertia_kg_m2", "lower_box_size_m", "upper_box_size_m"):
            values = getattr(self, name)
            if len(values) != 3:
                raise ValueError(f"{name} must have 3 entries, got {values!r}")
            for v in values:
                require_positive(name, v)
        for name in ("lower_box_centre_m", "upper_box_centre_m"):
            values = getattr(self, name)
            if len(values) != 3 or not all(math.isfinite(v) for v in values):
                raise ValueError(f"{name} must be 3 finite numbers, got {values!r}")
        if not math.isfinite(self.wheel_axle_z_m) or not math.isfinite(self.chassis_com_height_m):
            raise ValueError("wheel_axle_z_m and chassis_com_height_m must be finite")
        if self.track_m <= self.wheel_width_m:
            raise ValueError(f"track_m ({self.track_m}) must exceed wheel_width_m ({self.wheel_width_m})")
        # The wheels must carry the chassis: the lower box may not reach the ground.
        if self.base_link_height_m + self.lower_box_centre_m[2] - self.lower_box_size_m[2] / 2 <= 0.0:
            raise ValueError("lower_box_centre_m / lower_box_size_m put the chassis into the ground")

    @property
    def total_mass_kg(self) -> float:
        return self.chassis_mass_kg + 4.0 * self.wheel_mass_kg

    def wheel_positions_base_link(self) -> Tuple[Tuple[float, float, float], ...]:
        """Wheel centres in base_link [m], order FL, FR, RL, RR."""
        hx, hy, z = self.wheelbase_m / 2.0, self.track_m / 2.0, self.wheel_axle_z_m
        return ((hx, hy, z), (hx, -hy, z), (-hx, hy, z), (-hx, -hy, z))


WHEEL_NAMES: Tuple[str, str, str, str] = (
    "front_left_wheel", "front_right_wheel", "rear_left_wheel", "rear_right_wheel")


@dataclass(frozen=True)
class DriveLimits:
    """Limits of ``husky_velocity_controller`` (husky_control/config/control.yaml).

    wheel_separation_multiplier: control.yaml sets 1.875 ("wheel_separation_
    multiplier: 1.875" in husky/husky noetic-devel husky_control/config/
    control.yaml; changelog 0.0.2 "Update wheel separation multiplier for
    slippage"). The diff_drive_controller multiplies the URDF track by it both
    when turning a twist into wheel speeds and in its odometry, which models
    the skid-steer robot as a wider two-wheel robot: a skidding 4-wheel base
    turns slower than its wheels suggest. ``physics.ode_world`` reproduces
    that under-rotation with isotropic force-dependent slip; see its
    docstring for the measured ratio.

    Covariances: control.yaml publishes pose/twist covariance diagonals
    [0.001, 0.001, 0.001, 0.001, 0.001, 0.03] (x, y, z, roll, pitch, yaw).
    """

    max_linear_m_s: float = 1.0
    max_linear_acc_m_s2: float = 3.0
    max_angular_rad_s: float = 2.0
    max_angular_acc_rad_s2: float = 6.0
    cmd_timeout_s: float = 0.25
    control_rate_hz: float = 50.0
    wheel_separation_multiplier: float = 1.875
    wheel_radius_multiplier: float = 1.0
    pose_covariance_diagonal: Tuple[float, ...] = (0.001, 0.001, 0.001, 0.001, 0.001, 0.03)
    twist_covariance_diagonal: Tuple[float, ...] = (0.001, 0.001, 0.001, 0.001, 0.001, 0.03)

    def __post_init__(self) -> None:
        require_fields(self, positive=("max_linear_m_s", "max_linear_acc_m_s2", "max_angular_rad_s",
                                       "max_angular_acc_rad_s2", "cmd_timeout_s", "control_rate_hz",
                                       "wheel_separation_multiplier", "wheel_radius_multiplier"))
        for name in ("pose_covariance_diagonal", "twist_covariance_diagonal"):
            require_finite_values(name, getattr(self, name), 6, low=0.0)
