"""GPS + IMU localisation in the map frame: the map -> odom correction.

Why: in the original GPS mode robot_localization ran a second EKF in the
``map`` frame that fused the wheel/IMU odometry with the GPS position from
navsat_transform (/odometry/gps) and the IMU's absolute heading; its only
product the rest of the stack uses is the TF map -> odom. This module
replaces it by a complementary filter, which is all a planar robot with a
good odometry and an unbiased GPS needs:

* the odometry (odom -> base_link) supplies the fast, smooth motion;
* the GPS position and the IMU heading (both absolute, in the ENU map frame)
  slowly pull the map pose of base_link towards them.

The filter state is the transform ``T = map -> odom`` (x, y, yaw). The map
pose of the robot is ``T o odom_pose``. A GPS position ``g`` measured when the
odometry said ``o`` corrects it as

    e = T o o                                   (estimate at the fix's time)
    e.xy  <- e.xy + a_p (g - e.xy),            a_p = 1 - exp(-dt / position_time_constant_s)
    T     <- e o o^-1

and an IMU heading ``h`` (robot yaw in the map) as

    e.yaw <- e.yaw + a_y wrap(h - e.yaw),      a_y = 1 - exp(-dt / yaw_time_constant_s)

rotating T about the robot (its map position stays put). ``dt`` is the time
since the previous correction of the same kind, so the blending does not
depend on the sensor rates; a time constant of 0 trusts each measurement
fully. Because the caller pairs every measurement with the odometry pose at
the measurement's own stamp, a moving robot is not dragged back by latency.

The first GPS position, once a heading is known, sets T outright; before
that ``ready`` is False and no transform should be published.

Degraded and lost fixes (a farm loses its RTK fix under trees and next to
buildings):

* a fix whose position variance exceeds ``max_fix_variance_m2`` is refused
  (an SBAS or single-point fix is metres off: worse than the odometry);
* an accepted fix noisier than ``reference_fix_variance_m2`` corrects with a
  time constant scaled by variance / reference (a weight inversely
  proportional to its variance, as a Kalman gain would be);
* a fix farther from the estimate than ``jump_gate_m`` + 3 sigma of the fix is
  refused as a jump (multipath), unless no fix has been used for
  ``jump_gate_timeout_s``: then the estimate itself is suspect and the fix wins;
* without a usable fix T is held, so map -> base_link follows the odometry
  (wheels + IMU, the EKF's /odometry/filtered): dead reckoning. After
  ``dead_reckoning_limit_s`` without one, :meth:`GpsLocalizer.state` says
  ``gps_lost`` and ``localized`` is False until a fix is used again (the
  navigator pauses meanwhile); the first fix after a gap corrects with the
  weight of ``max_dt_s``.

:func:`robot_yaw_from_imu` turns an IMU orientation given for a rotated
sensor frame (imu_link) into the robot's (base_link's) yaw, as
robot_localization does with the static transform base_link <- imu_link;
:func:`enu_yaw` adds the yaw offset and magnetic declination.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from cottonsim_common.angles import wrap_angle
from cottonsim_common.pose import Pose2D, compose, inverse
from cottonsim_common.validation import require_fields, require_instance, require_unit_vector


@dataclass(frozen=True)
class GpsLocalizationConfig:
    """Parameters of the GPS/IMU complementary filter and its node.

    position_time_constant_s [s]: how fast the map position follows the GPS
        (0 = jump to every fix). Default 0.5.
    yaw_time_constant_s [s]: how fast the map heading follows the IMU (0 = jump).
        Default 1.0.
    yaw_offset [rad]: added to the IMU yaw so 0 means east (navsat_transform's
        parameter; the original 1.570796327 for an IMU reading 0 facing north).
    magnetic_declination_radians [rad]: added to the IMU yaw (original 0).
    max_dt_s [s]: longest gap between corrections used for the blending
        weight (a long gap gives at most this weight). Default 1.0.
    frequency [Hz]: rate at which the node publishes map -> odom. Default 30.
    transform_tolerance_s [s]: how far the published transform is
        post-dated, so that lookups at the newest odometry time succeed (amcl's
        transform_tolerance). Default 0.1.
    reference_fix_variance_m2 [m^2]: fixes with a position variance up to this
        use position_time_constant_s; noisier ones a time constant scaled by
        variance / this. Default 0.0025 (5 cm, an RTK fix; the simulator's
        fault-free fix is far below). A variance of 0 (unknown) counts as this.
    max_fix_variance_m2 [m^2]: fixes with a larger variance are refused.
        Default 0.25 (0.5 m): an RTK float fix (0.3 m) is used, SBAS (1 m) and
        single-point (2.5 m) fixes are not.
    jump_gate_m [m]: a fix farther than this + 3 sigma of the fix from the
        estimate is refused as a jump. Default 1.0.
    jump_gate_timeout_s [s]: when no fix has been used for this long, the
        jump gate is open (the estimate may be the one that is off). Default 5.0.
    dead_reckoning_limit_s [s]: after this long without a used fix the state is
        gps_lost (not localised). Default 20.0.
    status_frequency [Hz]: rate of the node's ~status. Default 5.
    """

    position_time_constant_s: float = 0.5
    yaw_time_constant_s: float = 1.0
    yaw_offset: float = 1.570796327
    magnetic_declination_radians: float = 0.0
    max_dt_s: float = 1.0
    frequency: float = 30.0
    transform_tolerance_s: float = 0.1
    reference_fix_variance_m2: float = 0.0025
    max_fix_variance_m2: float = 0.25
    jump_gate_m: float = 1.0
    jump_gate_timeout_s: float = 5.0
    dead_reckoning_limit_s: float = 20.0
    status_frequency: float = 5.0

    def __post_init__(self) -> None:
        require_fields(self, finite=("yaw_offset", "magnetic_declination_radians"),
                       non_negative=("position_time_constant_s", "yaw_time_constant_s", "transform_tolerance_s",
                                     "jump_gate_timeout_s"),
                       positive=("max_dt_s", "frequency", "reference_fix_variance_m2", "max_fix_variance_m2",
                                 "jump_gate_m", "dead_reckoning_limit_s", "status_frequency"))
        if self.max_fix_variance_m2 < self.reference_fix_variance_m2:
            raise ValueError(f"max_fix_variance_m2 ({self.max_fix_variance_m2}) must be >= reference_fix_variance_m2 "
                             f"({self.reference_fix_variance_m2})")


def _quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def robot_yaw_from_imu(q_world_imu: Sequence[float], q_base_imu: Sequence[float] = (0.0, 0.0, 0.0, 1.0)) -> float:
    """Yaw [rad] of base_link in the IMU's world frame.

    q_world_imu: orientation the IMU reports (its own frame in the world), xyzw.
    q_base_imu: rotation of the IMU frame in base_link (TF base_link <- imu_link), xyzw.
    The robot's orientation is q_world_imu * q_base_imu^-1; its yaw is returned.
    """
    qw = require_unit_vector("q_world_imu (x, y, z, w)", q_world_imu, 4, "the zero quaternion")
    qb = require_unit_vector("q_base_imu (x, y, z, w)", q_base_imu, 4, "the zero quaternion")
    qb_inv = np.array([-qb[0], -qb[1], -qb[2], qb[3]])
    x, y, z, w = _quat_multiply(qw, qb_inv)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def enu_yaw(imu_robot_yaw_rad: float, yaw_offset_rad: float, magnetic_declination_rad: float = 0.0) -> float:
    """Robot heading in ENU [rad, 0 = east] from the IMU's robot yaw plus the corrections."""
    return float(wrap_angle(imu_robot_yaw_rad + yaw_offset_rad + magnetic_declination_rad))


# GpsLocalizer.state values
STATE_WAITING = "waiting"                  # no fix used yet
STATE_GPS = "gps"                          # fixes in use
STATE_DEAD_RECKONING = "dead_reckoning"    # no usable fix for a while, within the limit
STATE_GPS_LOST = "gps_lost"                # no usable fix for longer than dead_reckoning_limit_s

# GpsLocalizer.update_gps outcomes besides "used"
REJECTED_VARIANCE = "variance"
REJECTED_JUMP = "jump"
REJECTED_NO_HEADING = "no_heading"        # the first fix waits for an IMU heading


def _blend_weight(dt_s: float, time_constant_s: float, max_dt_s: float) -> float:
    if time_constant_s <= 0.0:
        return 1.0
    dt = min(max(dt_s, 0.0), max_dt_s)
    return 1.0 - math.exp(-dt / time_constant_s)


class GpsLocalizer:
    """Complementary filter for map -> odom (see the module docstring).

    Call ``update_heading`` with each IMU heading and ``update_gps`` with each
    GPS position, each together with the odometry pose (odom -> base_link) at
    the measurement's stamp; read ``map_to_odom`` (None until ``ready``).
    Stamps are seconds on one clock and may arrive slightly out of order.
    """

    def __init__(self, config: GpsLocalizationConfig = GpsLocalizationConfig()):
        self.config = config
        self._map_to_odom: Optional[Pose2D] = None
        self._heading: Optional[float] = None         # latest IMU heading in the map
        self._heading_odom_yaw: Optional[float] = None
        self._last_gps_s: Optional[float] = None
        self._last_heading_s: Optional[float] = None
        self.gps_updates = 0
        self.heading_updates = 0
        self.rejected = {REJECTED_VARIANCE: 0, REJECTED_JUMP: 0}
        self.last_rejection: Optional[str] = None     # why the latest refused fix was refused

    @property
    def ready(self) -> bool:
        """True once the first GPS position (with a known heading) has set map -> odom."""
        return self._map_to_odom is not None

    @property
    def map_to_odom(self) -> Optional[Pose2D]:
        return self._map_to_odom

    def map_pose(self, odom_pose: Pose2D) -> Optional[Pose2D]:
        """The robot's map pose for an odometry pose, or None before the first fix."""
        if self._map_to_odom is None:
            return None
        return compose(self._map_to_odom, odom_pose)

    @staticmethod
    def _check(stamp_s: float, odom_pose: Pose2D, **values: float) -> None:
        require_instance("odom_pose", odom_pose, Pose2D)
        for name, v in dict(values, stamp_s=stamp_s).items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name} must be a finite number, got {v!r}")

    def update_heading(self, stamp_s: float, odom_pose: Pose2D, map_yaw_rad: float) -> None:
        """An absolute heading of the robot in the map [rad] (ENU yaw from the IMU)."""
        self._check(stamp_s, odom_pose, map_yaw_rad=map_yaw_rad)
        self.heading_updates += 1
        self._heading = float(map_yaw_rad)
        self._heading_odom_yaw = odom_pose.yaw_rad
        if self._map_to_odom is None:
            self._last_heading_s = stamp_s
            return
        dt = 0.0 if self._last_heading_s is None else stamp_s - self._last_heading_s
        if dt < 0.0:                                   # out of order: use it, weight from its own gap
            dt = 0.0
        self._last_heading_s = max(stamp_s, self._last_heading_s or stamp_s)
        a = _blend_weight(dt, self.config.yaw_time_constant_s, self.config.max_dt_s)
        est = compose(self._map_to_odom, odom_pose)
        new_yaw = est.yaw_rad + a * float(wrap_angle(map_yaw_rad - est.yaw_rad))
        self._map_to_odom = compose(Pose2D(est.x_m, est.y_m, float(wrap_angle(new_yaw))), inverse(odom_pose))

    def seconds_since_fix(self, now_s: float) -> float:
        """Sim time [s] since the newest fix used (inf before the first)."""
        return math.inf if self._last_gps_s is None else max(0.0, now_s - self._last_gps_s)

    def state(self, now_s: float) -> str:
        """waiting | gps | dead_reckoning | gps_lost at sim time ``now_s`` (module docstring).

        dead_reckoning starts when no fix has been used for more than max_dt_s (the
        fixes' usual spacing is far below it).
        """
        if self._map_to_odom is None:
            return STATE_WAITING
        age = self.seconds_since_fix(now_s)
        if age > self.config.dead_reckoning_limit_s:
            return STATE_GPS_LOST
        return STATE_DEAD_RECKONING if age > self.config.max_dt_s else STATE_GPS

    def localized(self, now_s: float) -> bool:
        """False only while gps_lost (before the first fix the filter is not ready, which is no loss)."""
        return self.state(now_s) != STATE_GPS_LOST

    def update_gps(self, stamp_s: float, odom_pose: Pose2D, x_m: float, y_m: float,
                   variance_m2: float = 0.0) -> bool:
        """A GPS position of base_link in the map [m] with its variance [m^2] (0 = unknown: nominal).

        Returns True when it was used. The first fix is used only once a heading is
        known (else False). A refused fix (variance above the gate, a jump) leaves the
        estimate alone; ``last_rejection`` and ``rejected`` say why.
        """
        self._check(stamp_s, odom_pose, x_m=x_m, y_m=y_m, variance_m2=variance_m2)
        if variance_m2 < 0.0:
            raise ValueError(f"variance_m2 must be >= 0 (0 = unknown), got {variance_m2!r}")
        self.last_rejection = None
        if variance_m2 > self.config.max_fix_variance_m2:
            self.rejected[REJECTED_VARIANCE] += 1
            self.last_rejection = REJECTED_VARIANCE
            return False
        if self._map_to_odom is None:
            if self._heading is None:
                self.last_rejection = REJECTED_NO_HEADING
                return False
            # the robot's map yaw now = heading measured + odometry turn since then
            yaw = self._heading + (odom_pose.yaw_rad - self._heading_odom_yaw)
            est = Pose2D(float(x_m), float(y_m), float(wrap_angle(yaw)))
            self._map_to_odom = compose(est, inverse(odom_pose))
            self._last_gps_s = stamp_s
            self.gps_updates += 1
            return True
        est = compose(self._map_to_odom, odom_pose)
        dt = max(0.0, stamp_s - self._last_gps_s) if self._last_gps_s is not None else 0.0
        variance = max(variance_m2, self.config.reference_fix_variance_m2)
        gate = self.config.jump_gate_m + 3.0 * math.sqrt(variance)
        if math.hypot(x_m - est.x_m, y_m - est.y_m) > gate and dt < self.config.jump_gate_timeout_s:
            self.rejected[REJECTED_JUMP] += 1
            self.last_rejection = REJECTED_JUMP
            return False
        self._last_gps_s = max(stamp_s, self._last_gps_s if self._last_gps_s is not None else stamp_s)
        time_constant = self.config.position_time_constant_s * (variance / self.config.reference_fix_variance_m2)
        a = _blend_weight(dt, time_constant, self.config.max_dt_s)
        corrected = Pose2D(est.x_m + a * (x_m - est.x_m), est.y_m + a * (y_m - est.y_m), est.yaw_rad)
        self._map_to_odom = compose(corrected, inverse(odom_pose))
        self.gps_updates += 1
        return True
