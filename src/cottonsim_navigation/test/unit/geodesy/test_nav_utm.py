"""UTM and navsat transform checks with independently known values."""
import math

import pytest

from cottonsim_navigation.geodesy.utm import (NavsatConfig, NavsatTransform, latlon_to_utm, utm_to_latlon,
                                              utm_zone)


def test_known_points():
    # (0, 3 deg E) lies on the central meridian of zone 31: easting 500000 m exactly, northing 0
    e, n, zone, band = latlon_to_utm(0.0, 3.0)
    assert zone == 31 and e == pytest.approx(500000.0, abs=1e-6) and n == pytest.approx(0.0, abs=1e-6)
    # southern hemisphere: false northing 10,000 km at the equator side
    e, n, zone, band = latlon_to_utm(-0.000001, 3.0)
    assert n == pytest.approx(10_000_000.0, abs=0.5) and band == "M"
    # on a central meridian the northing is k0 * meridian arc: 45 deg N -> 0.9996 * 4,984,944.4 m
    e, n, zone, band = latlon_to_utm(45.0, 9.0)
    assert zone == 32 and band == "T" and e == pytest.approx(500000.0, abs=1e-6)
    assert n == pytest.approx(0.9996 * 4984944.4, abs=1.0)


def test_zones_and_exceptions():
    assert utm_zone(49.9, 8.9) == 32
    assert utm_zone(0, 5.999999) == 31 and utm_zone(0, 6.0) == 32
    assert utm_zone(60.0, 5.0) == 32          # Norway
    assert utm_zone(78.0, 10.0) == 33         # Svalbard
    assert utm_zone(0, 180.0) == 60 and utm_zone(0, -180.0) == 1
    for bad in ((91, 0), (0, 181), (float("nan"), 0)):
        with pytest.raises(ValueError, match="latitude|longitude"):
            utm_zone(*bad)


@pytest.mark.parametrize("lat,lon", [(49.9, 8.9), (-33.9, 18.4), (0.5, 5.999), (-45.0, -71.0), (70.0, 25.0)])
def test_round_trip(lat, lon):
    e, n, zone, _ = latlon_to_utm(lat, lon)
    la, lo = utm_to_latlon(e, n, zone, lat >= 0)
    assert la == pytest.approx(lat, abs=1e-9) and lo == pytest.approx(lon, abs=1e-9)


def test_navsat_datum_is_origin_and_axes():
    # IMU heading 0 = north with yaw_offset pi/2 means the robot faces north; map x = forward = north
    nt = NavsatTransform(NavsatConfig())
    x, y, z = nt.fix_to_map(49.9, 8.9, 120.0, imu_yaw_rad=0.0)
    assert (x, y, z) == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
    dlat = 10.0 / 6371000.0 * 180 / math.pi            # ~10 m north
    x, y, _ = nt.fix_to_map(49.9 + dlat, 8.9)
    assert x == pytest.approx(10.0, rel=2e-3) and abs(y) < 0.05
    dlon = dlat / math.cos(math.radians(49.9))          # ~10 m east -> map -y (right of the robot)
    x, y, _ = nt.fix_to_map(49.9, 8.9 + dlon)
    assert y == pytest.approx(-10.0, rel=5e-3) and abs(x) < 0.05
    la, lo = nt.map_to_latlon(3.0, -4.0)
    x, y, _ = nt.fix_to_map(la, lo)
    assert (x, y) == pytest.approx((3.0, -4.0), abs=1e-6)


def test_navsat_continuous_across_zone_edge():
    nt = NavsatTransform(NavsatConfig(yaw_offset=0.0))       # ENU map
    lat = 10.0
    nt.set_datum(lat, 5.9999)
    x1, _, _ = nt.fix_to_map(lat, 5.99995)
    x2, _, _ = nt.fix_to_map(lat, 6.00005)                    # other zone, same datum zone
    step = (0.0001 * math.pi / 180) * 6378137 * math.cos(math.radians(lat))
    assert x2 - x1 == pytest.approx(step, rel=1e-2)
    with pytest.raises(ValueError, match="datum"):
        NavsatTransform().map_to_latlon(0, 0)
