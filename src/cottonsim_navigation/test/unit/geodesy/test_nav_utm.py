"""UTM checks with independently known values (the GPS map frame itself: test_nav_navsat.py)."""
import math

import pytest

from cottonsim_navigation.geodesy.utm import (latlon_to_utm, utm_band, utm_meridian_convergence_rad, utm_to_latlon,
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


def test_utm_limits_refused_clearly():
    # UTM spans 80 S .. 84 N: the limits themselves are inside, anything beyond is refused by name
    assert latlon_to_utm(84.0, 20.0)[3] == "X" and latlon_to_utm(-80.0, -70.0)[3] == "C"
    assert utm_band(83.9999) == "X" and utm_zone(84.0, 20.0) == 34
    for lat in (84.0001, -80.0001, 90.0, -90.0):
        for call in (lambda: latlon_to_utm(lat, 10.0), lambda: utm_zone(lat, 10.0), lambda: utm_band(lat),
                     lambda: utm_meridian_convergence_rad(lat, 10.0)):
            with pytest.raises(ValueError, match="UTM is defined for latitudes -80 .. 84"):
                call()


def _grid_bearing_of_true_north_rad(lat, lon, zone=None):
    """Bearing (clockwise from grid north) of a 1 m segment along the meridian, projected into UTM."""
    dlat = 1.0 / 111_000.0
    e0, n0, zone, _ = latlon_to_utm(lat - dlat / 2, lon, zone=zone, northern=lat >= 0)
    e1, n1, _, _ = latlon_to_utm(lat + dlat / 2, lon, zone=zone, northern=lat >= 0)
    return math.atan2(e1 - e0, n1 - n0)


@pytest.mark.parametrize("lat,lon,zone,approx_deg", [
    (49.9, 8.9, None, -0.077), (33.4, -101.0, None, -1.10), (-30.3, 149.8, None, -1.41),
    (-33.9, 18.4, None, 1.45), (60.0, 4.0, None, -4.33), (78.0, 20.9, None, 5.77), (10.0, 6.002, 31, 0.521)])
def test_meridian_convergence_matches_a_projected_true_north_segment(lat, lon, zone, approx_deg):
    # PROJ's gamma, checked against UTM itself: true north lies at grid bearing -gamma
    gamma = utm_meridian_convergence_rad(lat, lon, zone)
    assert math.degrees(gamma) == pytest.approx(approx_deg, abs=0.01)
    assert _grid_bearing_of_true_north_rad(lat, lon, zone) == pytest.approx(-gamma, abs=1e-6)
