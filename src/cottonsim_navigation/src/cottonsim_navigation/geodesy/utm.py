"""UTM conversions and a navsat_transform core (robot_localization equivalent).

UTM (WGS84) via pyproj. Zones come from the longitude (6 degree bands) with
the Norway (32V) and Svalbard (31X..37X) exceptions; the band letter comes
from the latitude (C..X, no I/O).

:class:`NavsatTransform` does what robot_localization's navsat_transform does
for the planar case: the first fix (or a datum parameter) fixes a UTM origin;
every later fix is converted in the *datum's* zone (pyproj extends a
transverse Mercator zone past its 6 degree edge without a jump), so a route
that crosses a zone edge stays continuous in the map frame. UTM east/north is
then rotated into the map frame by the map's heading:

    map = R(-(yaw_map)) * (utm - utm_datum),   yaw_map = imu_yaw + magnetic_declination + yaw_offset

where imu_yaw is the robot's heading reported by the IMU (ENU, 0 = east) at
the datum fix, and ``yaw_offset`` corrects an IMU whose zero is not east
(the original: pi/2, an IMU reading 0 when facing north). The robot's own map
yaw at the datum is ``datum_robot_yaw_rad`` (0 when the map frame starts at
the robot). Altitude is dropped when zero_altitude (the original: true).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Optional, Tuple

from pyproj import Transformer

_BANDS = "CDEFGHJKLMNPQRSTUVWXX"


def _check_latlon(lat: float, lon: float) -> Tuple[float, float]:
    try:
        lat = float(lat)
        lon = float(lon)
    except (TypeError, ValueError):
        raise ValueError(f"latitude/longitude must be numbers, got {lat!r}, {lon!r}") from None
    if math.isnan(lat) or not -90.0 <= lat <= 90.0:
        raise ValueError(f"latitude must lie in [-90, 90] deg, got {lat}")
    if math.isnan(lon) or not -180.0 <= lon <= 180.0:
        raise ValueError(f"longitude must lie in [-180, 180] deg, got {lon}")
    return lat, lon


def utm_zone(lat: float, lon: float) -> int:
    """UTM zone number 1..60 for a WGS84 position, with the Norway/Svalbard exceptions."""
    lat, lon = _check_latlon(lat, lon)
    zone = int((lon + 180.0) // 6.0) + 1
    if zone > 60:
        zone = 60
    if 56.0 <= lat < 64.0 and 3.0 <= lon < 12.0:
        zone = 32
    if 72.0 <= lat < 84.0 and 0.0 <= lon < 42.0:
        if lon < 9.0:
            zone = 31
        elif lon < 21.0:
            zone = 33
        elif lon < 33.0:
            zone = 35
        else:
            zone = 37
    return zone


def utm_band(lat: float) -> str:
    """Latitude band letter C..X (X spans 72..84 deg); polar latitudes clamp to C / X."""
    lat = float(lat)
    i = int((min(max(lat, -80.0), 84.0) + 80.0) // 8.0)
    return _BANDS[min(i, len(_BANDS) - 1)]


@lru_cache(maxsize=32)
def _transformers(zone: int, northern: bool):
    epsg = (32600 if northern else 32700) + zone
    fwd = Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True)
    inv = Transformer.from_crs(f"EPSG:{epsg}", "EPSG:4326", always_xy=True)
    return fwd, inv


def latlon_to_utm(lat: float, lon: float, zone: Optional[int] = None,
                  northern: Optional[bool] = None) -> Tuple[float, float, int, str]:
    """WGS84 lat/lon [deg] -> (easting m, northing m, zone, band letter).

    ``zone`` / ``northern`` force a zone and hemisphere (used to keep one
    zone for a whole route); by default they follow the position.
    """
    lat, lon = _check_latlon(lat, lon)
    if zone is None:
        zone = utm_zone(lat, lon)
    if not 1 <= int(zone) <= 60:
        raise ValueError(f"zone must lie in 1..60, got {zone}")
    if northern is None:
        northern = lat >= 0.0
    e, n = _transformers(int(zone), bool(northern))[0].transform(lon, lat)
    return float(e), float(n), int(zone), utm_band(lat)


def utm_to_latlon(easting: float, northing: float, zone: int, northern: bool) -> Tuple[float, float]:
    """UTM (easting, northing) [m] in ``zone`` / hemisphere -> (lat, lon) [deg]."""
    for name, v in (("easting", easting), ("northing", northing)):
        if not math.isfinite(float(v)):
            raise ValueError(f"{name} must be finite, got {v!r}")
    if not 1 <= int(zone) <= 60:
        raise ValueError(f"zone must lie in 1..60, got {zone}")
    lon, lat = _transformers(int(zone), bool(northern))[1].transform(float(easting), float(northing))
    return float(lat), float(lon)


@dataclass(frozen=True)
class NavsatConfig:
    """navsat_transform parameters (robot_localization names).

    yaw_offset [rad]: added to the IMU yaw so 0 means east (the original:
    1.570796327); magnetic_declination_radians [rad] (original 0);
    zero_altitude: report z = 0 (original true); wait_for_datum / datum:
    use (lat deg, lon deg, yaw rad) instead of the first fix (datum yaw is
    the IMU-frame heading like robot_localization's datum parameter);
    frequency [Hz] and delay [s] are for the ROS node (original 30, 3).
    """

    yaw_offset: float = 1.570796327
    magnetic_declination_radians: float = 0.0
    zero_altitude: bool = True
    wait_for_datum: bool = False
    datum: Optional[Tuple[float, float, float]] = None
    frequency: float = 30.0
    delay: float = 3.0

    def __post_init__(self) -> None:
        for name in ("yaw_offset", "magnetic_declination_radians", "frequency", "delay"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)!r}")
        if self.frequency <= 0:
            raise ValueError(f"frequency must be > 0, got {self.frequency}")
        if self.delay < 0:
            raise ValueError(f"delay must be >= 0, got {self.delay}")
        if self.datum is not None:
            if len(self.datum) != 3:
                raise ValueError("datum must be (latitude deg, longitude deg, yaw rad)")
            _check_latlon(self.datum[0], self.datum[1])
            if not math.isfinite(self.datum[2]):
                raise ValueError("datum yaw must be finite")
        if self.wait_for_datum and self.datum is None:
            raise ValueError("wait_for_datum is true but no datum is given")


class NavsatTransform:
    """GPS fix <-> map x/y, fixed at a datum.

    ``set_datum(lat, lon, imu_yaw_rad, robot_x_m=0, robot_y_m=0, robot_yaw_rad=0)``
    -- or the first ``fix_to_map`` call when no datum is set -- anchors the
    transform: the fix at the datum is the robot's map position then.
    """

    def __init__(self, config: NavsatConfig = NavsatConfig()):
        self.config = config
        self._datum = None   # (e0, n0, zone, northern, map_yaw_rad, robot_x, robot_y, robot_yaw)
        self.datum_latlon: Optional[Tuple[float, float]] = None
        if config.datum is not None:
            self.set_datum(config.datum[0], config.datum[1], config.datum[2])

    @property
    def has_datum(self) -> bool:
        return self._datum is not None

    def set_datum(self, lat: float, lon: float, imu_yaw_rad: float = 0.0, robot_x_m: float = 0.0,
                  robot_y_m: float = 0.0, robot_yaw_rad: float = 0.0) -> None:
        lat, lon = _check_latlon(lat, lon)
        for name, v in (("imu_yaw_rad", imu_yaw_rad), ("robot_x_m", robot_x_m), ("robot_y_m", robot_y_m),
                        ("robot_yaw_rad", robot_yaw_rad)):
            if not math.isfinite(float(v)):
                raise ValueError(f"{name} must be finite, got {v!r}")
        e, n, zone, _ = latlon_to_utm(lat, lon)
        # heading of UTM east measured in the map frame: the robot's yaw in ENU
        # (IMU + corrections) against its yaw in the map
        enu_yaw = imu_yaw_rad + self.config.magnetic_declination_radians + self.config.yaw_offset
        rot = robot_yaw_rad - enu_yaw
        self._datum = (e, n, zone, lat >= 0.0, rot, float(robot_x_m), float(robot_y_m))
        self.datum_latlon = (lat, lon)

    def fix_to_map(self, lat: float, lon: float, alt: float = 0.0, imu_yaw_rad: float = 0.0
                   ) -> Tuple[float, float, float]:
        """A fix -> (x, y, z) in the map frame [m]; the first fix becomes the datum if none is set."""
        lat, lon = _check_latlon(lat, lon)
        if not math.isfinite(float(alt)):
            raise ValueError(f"altitude must be finite, got {alt!r}")
        if self._datum is None:
            self.set_datum(lat, lon, imu_yaw_rad)
        e0, n0, zone, northern, rot, rx, ry = self._datum
        e, n, _, _ = latlon_to_utm(lat, lon, zone=zone, northern=northern)
        de, dn = e - e0, n - n0
        c, s = math.cos(rot), math.sin(rot)
        z = 0.0 if self.config.zero_altitude else float(alt)
        return rx + c * de - s * dn, ry + s * de + c * dn, z

    def map_to_latlon(self, x_m: float, y_m: float) -> Tuple[float, float]:
        """Map x/y [m] -> (lat, lon) [deg] (for GPS waypoints and the filtered fix)."""
        if self._datum is None:
            raise ValueError("navsat transform has no datum yet (no fix received, no datum parameter)")
        for name, v in (("x_m", x_m), ("y_m", y_m)):
            if not math.isfinite(float(v)):
                raise ValueError(f"{name} must be finite, got {v!r}")
        e0, n0, zone, northern, rot, rx, ry = self._datum
        dx, dy = x_m - rx, y_m - ry
        c, s = math.cos(rot), math.sin(rot)
        de, dn = c * dx + s * dy, -s * dx + c * dy
        return utm_to_latlon(e0 + de, n0 + dn, zone, northern)
