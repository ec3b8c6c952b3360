"""UTM (WGS84) conversions: what robot_localization's navsat_transform works in.

Via pyproj. Zones come from the longitude (6 degree bands) with the Norway
(32V) and Svalbard (31X..37X) exceptions; the band letter comes from the
latitude (C..X, no I/O). UTM is defined from 80 S to 84 N (the poles use
UPS); positions beyond raise ValueError.

The robot's GPS map frame is *not* UTM but the ENU tangent plane at the
datum (:mod:`cottonsim_navigation.geodesy.navsat` says why): UTM's grid
north differs from true north by the meridian convergence, which
:func:`utm_meridian_convergence_rad` gives, so that a heading in the UTM
grid (a farm plan surveyed in UTM, say) converts to ENU as

    enu_yaw = utm_yaw - gamma        (yaw: 0 = east / grid east, counter-clockwise)
"""
from __future__ import annotations

import math
from functools import lru_cache
from typing import Optional, Tuple

from pyproj import Proj, Transformer

_BANDS = "CDEFGHJKLMNPQRSTUVWXX"
UTM_MIN_LATITUDE_DEG = -80.0
UTM_MAX_LATITUDE_DEG = 84.0


def check_latlon(lat: float, lon: float) -> Tuple[float, float]:
    """(lat, lon) as floats; ValueError unless they are numbers in [-90, 90] / [-180, 180] deg."""
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


def _check_utm_latitude(lat: float) -> None:
    if not UTM_MIN_LATITUDE_DEG <= lat <= UTM_MAX_LATITUDE_DEG:
        raise ValueError(f"UTM is defined for latitudes {UTM_MIN_LATITUDE_DEG:g} .. {UTM_MAX_LATITUDE_DEG:g} deg "
                         f"(80 S .. 84 N; the polar caps use UPS), got {lat}")


def utm_zone(lat: float, lon: float) -> int:
    """UTM zone number 1..60 for a WGS84 position, with the Norway/Svalbard exceptions."""
    lat, lon = check_latlon(lat, lon)
    _check_utm_latitude(lat)
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
    """Latitude band letter C..X (X spans 72..84 deg); ValueError beyond 80 S .. 84 N."""
    lat, _ = check_latlon(lat, 0.0)
    _check_utm_latitude(lat)
    i = int((lat + 80.0) // 8.0)
    return _BANDS[min(i, len(_BANDS) - 1)]


@lru_cache(maxsize=32)
def _transformers(zone: int, northern: bool):
    epsg = (32600 if northern else 32700) + zone
    fwd = Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True)
    inv = Transformer.from_crs(f"EPSG:{epsg}", "EPSG:4326", always_xy=True)
    return fwd, inv


def _checked_zone(zone) -> int:
    if not 1 <= int(zone) <= 60:
        raise ValueError(f"zone must lie in 1..60, got {zone}")
    return int(zone)


def _checked_position_and_zone(lat: float, lon: float, zone: Optional[int]) -> Tuple[float, float, int]:
    """Validated (lat, lon) inside UTM's latitudes and the zone (default: the position's own)."""
    lat, lon = check_latlon(lat, lon)
    _check_utm_latitude(lat)
    return lat, lon, _checked_zone(utm_zone(lat, lon) if zone is None else zone)


def latlon_to_utm(lat: float, lon: float, zone: Optional[int] = None,
                  northern: Optional[bool] = None) -> Tuple[float, float, int, str]:
    """WGS84 lat/lon [deg] -> (easting m, northing m, zone, band letter).

    ``zone`` / ``northern`` force a zone and hemisphere (used to keep one
    zone for a whole route); by default they follow the position.
    """
    lat, lon, zone = _checked_position_and_zone(lat, lon, zone)
    if northern is None:
        northern = lat >= 0.0
    e, n = _transformers(int(zone), bool(northern))[0].transform(lon, lat)
    return float(e), float(n), int(zone), utm_band(lat)


def utm_to_latlon(easting: float, northing: float, zone: int, northern: bool) -> Tuple[float, float]:
    """UTM (easting, northing) [m] in ``zone`` / hemisphere -> (lat, lon) [deg]."""
    for name, v in (("easting", easting), ("northing", northing)):
        if not math.isfinite(float(v)):
            raise ValueError(f"{name} must be finite, got {v!r}")
    zone = _checked_zone(zone)
    lon, lat = _transformers(int(zone), bool(northern))[1].transform(float(easting), float(northing))
    return float(lat), float(lon)


@lru_cache(maxsize=32)
def _projection(zone: int, northern: bool) -> Proj:
    return Proj(f"EPSG:{(32600 if northern else 32700) + zone}")


def utm_meridian_convergence_rad(lat: float, lon: float, zone: Optional[int] = None) -> float:
    """Meridian convergence gamma [rad] of UTM at a position (in ``zone``, default its own).

    gamma is PROJ's: positive east of the zone's central meridian in the
    north, ~ (lon - central meridian) sin(lat). True north lies at a grid
    bearing of -gamma (clockwise from grid north), so a UTM-grid yaw
    converts to ENU as enu_yaw = utm_yaw - gamma. Examples: 49.9 N 8.9 E
    (zone 32): -0.077 deg; 33.4 N 101 W (zone 14): -1.10 deg.
    """
    lat, lon, zone = _checked_position_and_zone(lat, lon, zone)
    factors = _projection(int(zone), lat >= 0.0).get_factors(lon, lat)
    return math.radians(float(factors.meridian_convergence))
