"""The GPS map frame: a local ENU tangent plane at the datum, and a navsat_transform core.

Why ENU and not UTM: the robot's heading comes from the IMU, which reads
true north (ENU: yaw 0 = east, pi/2 = north). A UTM map's axes follow the
UTM *grid*, whose north is turned against true north by the meridian
convergence gamma ~ (lon - central meridian) * sin(lat): 0.08 deg at the
default farm (49.9 N, 8.9 E), 1.1 deg at Lubbock, Texas (33.4 N, 101 W,
zone 14), up to ~3 deg at a zone's edge far north (~6 deg in the widened
Svalbard zones). A map whose positions come from UTM but whose heading
comes from the IMU is therefore tilted by gamma: the robot drives at gamma
to every lane and swerves back after each GPS correction.
robot_localization's navsat_transform corrects its IMU heading by gamma for
that reason. UTM distances are also off by the grid scale factor (0.9996 on
the central meridian, up to 1.001 at a zone edge).

Here the map is the local tangent plane at the datum instead, so none of
that arises: a fix's point on the WGS84 ellipsoid (height 0) is expressed in
the datum's east / north / up axes (via Earth-centred, Earth-fixed
coordinates) and "up" is dropped:

    p = ecef(lat, lon, 0);  (east, north) = (E . (p - p0), N . (p - p0))

At the datum the axes are exactly east and true north and the scale is
exactly 1, in any hemisphere, at any distance from a central meridian, and a
farm that straddles a UTM zone edge is one continuous frame (there are no
zones). Over a farm the frame stays flat to far below a centimetre: a point
d away lies d^2 / (2 R) below the plane (0.8 mm at 100 m), and true north
at d east of the datum is turned by ~ d tan(lat) / R against the map's y
axis (the meridians converge; 0.001 deg at 100 m at 50 deg, 0.0085 deg at
84 deg). The inverse, :meth:`EnuTangentPlane.from_enu`, intersects the
datum's normal through (east, north) with the ellipsoid in closed form,
so the round trip is exact to float precision (~1e-9 m).

Datums are accepted where UTM is defined, 80 S .. 84 N: robot_localization
works in UTM and cannot place a datum beyond it either, and beyond ~85 deg
the meridians converge by more than 0.01 deg across a 100 m farm, so true
north (the IMU's) no longer has one direction in any flat map of it.
Fixes and map points farther than ``MAX_DISTANCE_FROM_DATUM_M`` (100 km)
from the datum are refused: a farm's map, not a continent's (a waypoint
file of another farm, or a glitched fix at 0/0, gives a clear error).

:class:`NavsatTransform` anchors this plane to the robot's map the way
robot_localization's navsat_transform does for the planar case: the first
fix (or a datum parameter) is the robot's map position, and the map's
heading is the IMU's ENU heading there:

    map = R(rot) * enu + robot_xy,   rot = robot_map_yaw - enu_yaw,
    enu_yaw = imu_yaw + magnetic_declination + yaw_offset

so a map anchored with ``robot_map_yaw = enu_yaw`` (navsat_transform_node,
the GPS waypoint navigator) *is* the ENU frame at the datum, and an IMU
heading is a map heading as it is (:meth:`NavsatTransform.map_yaw_from_enu`
converts in general). ``yaw_offset`` corrects an IMU whose zero is not east
(the original: pi/2, an IMU reading 0 when facing north). Altitude is
dropped when zero_altitude (the original: true).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

from cottonsim_common.validation import require_fields
from cottonsim_navigation.geodesy.utm import UTM_MAX_LATITUDE_DEG, UTM_MIN_LATITUDE_DEG, check_latlon

WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
WGS84_B_M = WGS84_A_M * (1.0 - WGS84_F)
MAX_DISTANCE_FROM_DATUM_M = 100_000.0


def _ecef(lat_deg: float, lon_deg: float) -> Tuple[float, float, float]:
    """Earth-centred, Earth-fixed position [m] of a point on the WGS84 ellipsoid (height 0)."""
    phi, lam = math.radians(lat_deg), math.radians(lon_deg)
    s = math.sin(phi)
    prime_vertical = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * s * s)
    return (prime_vertical * math.cos(phi) * math.cos(lam), prime_vertical * math.cos(phi) * math.sin(lam),
            prime_vertical * (1.0 - WGS84_E2) * s)


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _wdot(a, b) -> float:
    """a . W b with W = diag(1/a^2, 1/a^2, 1/b^2): the ellipsoid's quadratic form."""
    return (a[0] * b[0] + a[1] * b[1]) / WGS84_A_M ** 2 + a[2] * b[2] / WGS84_B_M ** 2


class EnuTangentPlane:
    """(lat, lon) [deg] <-> (east, north) [m] in the WGS84 tangent plane at an origin.

    ``origin_lat_deg`` must lie in UTM's 80 S .. 84 N (see the module
    docstring); points farther than ``MAX_DISTANCE_FROM_DATUM_M`` from the
    origin are refused with ValueError.
    """

    def __init__(self, origin_lat_deg: float, origin_lon_deg: float):
        lat, lon = check_latlon(origin_lat_deg, origin_lon_deg)
        if not UTM_MIN_LATITUDE_DEG <= lat <= UTM_MAX_LATITUDE_DEG:
            raise ValueError(f"the GPS datum's latitude must lie in {UTM_MIN_LATITUDE_DEG:g} .. "
                             f"{UTM_MAX_LATITUDE_DEG:g} deg (80 S .. 84 N, where UTM and robot_localization "
                             f"work), got {lat}")
        self.origin_lat_deg, self.origin_lon_deg = lat, lon
        phi, lam = math.radians(lat), math.radians(lon)
        sp, cp, sl, cl = math.sin(phi), math.cos(phi), math.sin(lam), math.cos(lam)
        self._east = (-sl, cl, 0.0)
        self._north = (-sp * cl, -sp * sl, cp)
        self._up = (cp * cl, cp * sl, sp)
        self._origin = _ecef(lat, lon)

    def to_enu(self, lat_deg: float, lon_deg: float) -> Tuple[float, float]:
        """A point on the ellipsoid -> (east, north) [m] from the origin."""
        lat, lon = check_latlon(lat_deg, lon_deg)
        p = _ecef(lat, lon)
        d = (p[0] - self._origin[0], p[1] - self._origin[1], p[2] - self._origin[2])
        distance = math.sqrt(_dot(d, d))
        if distance > MAX_DISTANCE_FROM_DATUM_M:
            raise ValueError(f"({lat}, {lon}) lies {distance / 1000.0:.1f} km from the GPS datum "
                             f"({self.origin_lat_deg}, {self.origin_lon_deg}); the local map covers "
                             f"{MAX_DISTANCE_FROM_DATUM_M / 1000.0:g} km (a route of another farm?)")
        return _dot(self._east, d), _dot(self._north, d)

    def from_enu(self, east_m: float, north_m: float) -> Tuple[float, float]:
        """(east, north) [m] -> (lat, lon) [deg]: the exact inverse of :meth:`to_enu`."""
        for name, v in (("east_m", east_m), ("north_m", north_m)):
            if not math.isfinite(float(v)):
                raise ValueError(f"{name} must be finite, got {v!r}")
        east_m, north_m = float(east_m), float(north_m)
        if math.hypot(east_m, north_m) > MAX_DISTANCE_FROM_DATUM_M:
            raise ValueError(f"map point ({east_m:.1f}, {north_m:.1f}) m lies more than "
                             f"{MAX_DISTANCE_FROM_DATUM_M / 1000.0:g} km from the GPS datum")
        o, up = self._origin, self._up
        # the horizontal offset, then the height u along the origin's normal that puts it on the ellipsoid:
        # A u^2 + B u + C = 0 with C written relative to the origin (on the ellipsoid) to keep precision
        h = tuple(east_m * e + north_m * n for e, n in zip(self._east, self._north))
        q = (o[0] + h[0], o[1] + h[1], o[2] + h[2])
        a_coef = _wdot(up, up)
        b_coef = 2.0 * _wdot(q, up)
        c_coef = (_wdot(o, o) - 1.0) + 2.0 * _wdot(o, h) + _wdot(h, h)
        disc = b_coef * b_coef - 4.0 * a_coef * c_coef
        u = -2.0 * c_coef / (b_coef + math.sqrt(max(disc, 0.0)))     # the root near the plane (b > 0 here)
        x, y, z = q[0] + u * up[0], q[1] + u * up[1], q[2] + u * up[2]
        lat = math.degrees(math.atan2(z, (1.0 - WGS84_E2) * math.hypot(x, y)))
        lon = math.degrees(math.atan2(y, x))
        return lat, lon


@dataclass(frozen=True)
class NavsatConfig:
    """navsat_transform parameters (robot_localization names).

    yaw_offset [rad]: added to the IMU yaw so 0 means east (the original:
    1.570796327); magnetic_declination_radians [rad] (original 0);
    zero_altitude: report z = 0 (original true); wait_for_datum / datum:
    use (lat deg, lon deg, yaw rad) instead of the first fix (datum yaw is
    the IMU-frame heading like robot_localization's datum parameter; the
    latitude must lie in 80 S .. 84 N); frequency [Hz] and delay [s] are for
    the ROS node (original 30, 3).
    """

    yaw_offset: float = 1.570796327
    magnetic_declination_radians: float = 0.0
    zero_altitude: bool = True
    wait_for_datum: bool = False
    datum: Optional[Tuple[float, float, float]] = None
    frequency: float = 30.0
    delay: float = 3.0

    def __post_init__(self) -> None:
        require_fields(self, finite=("yaw_offset", "magnetic_declination_radians"), positive=("frequency",),
                       non_negative=("delay",))
        if self.datum is not None:
            if len(self.datum) != 3:
                raise ValueError("datum must be (latitude deg, longitude deg, yaw rad)")
            EnuTangentPlane(self.datum[0], self.datum[1])          # validates the position
            if not math.isfinite(self.datum[2]):
                raise ValueError("datum yaw must be finite")
        if self.wait_for_datum and self.datum is None:
            raise ValueError("wait_for_datum is true but no datum is given")


class NavsatTransform:
    """GPS fix <-> map x/y, fixed at a datum (the ENU tangent plane there, placed in the robot's map).

    ``set_datum(lat, lon, imu_yaw_rad, robot_x_m=0, robot_y_m=0, robot_yaw_rad=0)``
    -- or the first ``fix_to_map`` call when no datum is set -- anchors the
    transform: the fix at the datum is the robot's map position then, and
    the map is the ENU frame turned by ``robot_yaw_rad - enu_yaw`` (see the
    module docstring; 0 for an ENU map).
    """

    def __init__(self, config: NavsatConfig = NavsatConfig()):
        self.config = config
        self._plane: Optional[EnuTangentPlane] = None
        self._anchor = (0.0, 0.0, 0.0)      # (rotation ENU -> map [rad], robot x [m], robot y [m])
        self.datum_latlon: Optional[Tuple[float, float]] = None
        if config.datum is not None:
            self.set_datum(config.datum[0], config.datum[1], config.datum[2])

    @property
    def has_datum(self) -> bool:
        return self._plane is not None

    @property
    def enu_to_map_rotation_rad(self) -> float:
        """Angle [rad] the map's axes are turned against ENU (0 for an ENU map); needs a datum."""
        self._require_datum()
        return self._anchor[0]

    def set_datum(self, lat: float, lon: float, imu_yaw_rad: float = 0.0, robot_x_m: float = 0.0,
                  robot_y_m: float = 0.0, robot_yaw_rad: float = 0.0) -> None:
        for name, v in (("imu_yaw_rad", imu_yaw_rad), ("robot_x_m", robot_x_m), ("robot_y_m", robot_y_m),
                        ("robot_yaw_rad", robot_yaw_rad)):
            if not math.isfinite(float(v)):
                raise ValueError(f"{name} must be finite, got {v!r}")
        plane = EnuTangentPlane(lat, lon)
        # the robot's heading in ENU (IMU + corrections) against its heading in the map
        enu_yaw = imu_yaw_rad + self.config.magnetic_declination_radians + self.config.yaw_offset
        self._plane = plane
        self._anchor = (float(robot_yaw_rad) - enu_yaw, float(robot_x_m), float(robot_y_m))
        self.datum_latlon = (plane.origin_lat_deg, plane.origin_lon_deg)

    def _require_datum(self) -> EnuTangentPlane:
        if self._plane is None:
            raise ValueError("navsat transform has no datum yet (no fix received, no datum parameter)")
        return self._plane

    def fix_to_map(self, lat: float, lon: float, alt: float = 0.0, imu_yaw_rad: float = 0.0
                   ) -> Tuple[float, float, float]:
        """A fix -> (x, y, z) in the map frame [m]; the first fix becomes the datum if none is set."""
        lat, lon = check_latlon(lat, lon)
        if not math.isfinite(float(alt)):
            raise ValueError(f"altitude must be finite, got {alt!r}")
        if self._plane is None:
            self.set_datum(lat, lon, imu_yaw_rad)
        east, north = self._plane.to_enu(lat, lon)
        rot, rx, ry = self._anchor
        c, s = math.cos(rot), math.sin(rot)
        z = 0.0 if self.config.zero_altitude else float(alt)
        return rx + c * east - s * north, ry + s * east + c * north, z

    def map_to_latlon(self, x_m: float, y_m: float) -> Tuple[float, float]:
        """Map x/y [m] -> (lat, lon) [deg] (for GPS waypoints and the filtered fix): the exact inverse."""
        plane = self._require_datum()
        for name, v in (("x_m", x_m), ("y_m", y_m)):
            if not math.isfinite(float(v)):
                raise ValueError(f"{name} must be finite, got {v!r}")
        rot, rx, ry = self._anchor
        dx, dy = float(x_m) - rx, float(y_m) - ry
        c, s = math.cos(rot), math.sin(rot)
        return plane.from_enu(c * dx + s * dy, -s * dx + c * dy)

    def map_yaw_from_enu(self, enu_yaw_rad: float) -> float:
        """A heading in ENU [rad, 0 = east, true north = pi/2] -> the same heading in the map [rad]."""
        return float(enu_yaw_rad) + self.enu_to_map_rotation_rad

    def enu_yaw_from_map(self, map_yaw_rad: float) -> float:
        """A heading in the map [rad] -> ENU [rad, 0 = east, true north = pi/2]."""
        return float(map_yaw_rad) - self.enu_to_map_rotation_rad
