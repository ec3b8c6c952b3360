"""The GPS map frame (ENU tangent plane at the datum) at datums all over the UTM range.

References are independent of the code under test: pyproj's geodesic (Geod: true
distance and azimuth from true north on WGS84) and the simulator's hector geodesy
(cottonsim_world.geodesy), whose world frame the robot's map must match up to a
translation (and the reference heading's fixed rotation).
"""
import math

import numpy as np
import pytest
from pyproj import Geod

from cottonsim_navigation.geodesy.navsat import (MAX_DISTANCE_FROM_DATUM_M, EnuTangentPlane, NavsatConfig,
                                                 NavsatTransform)
from cottonsim_navigation.geodesy.utm import utm_meridian_convergence_rad, utm_zone

GEOD = Geod(ellps="WGS84")
FARM_EXTENT_M = 100.0            # lanes up to this far from the datum must keep true north along the map's y

# (name, lat, lon): both hemispheres, both sides of a central meridian, zone edges, the UTM limits,
# the Norway / Svalbard zones, the equator and the antimeridian
DATUMS = [
    ("default farm 49.9N 8.9E, zone 32", 49.9, 8.9),
    ("Lubbock 2 deg W of zone 14's meridian", 33.4, -101.0),
    ("Oklahoma 2.5 deg E of zone 14's meridian", 35.0, -96.5),
    ("Narrabri, south, 2.8 deg E of zone 55's", -30.3, 149.8),
    ("Western Cape, south, 2.6 deg W of zone 34's", -33.9, 18.4),
    ("on the zone 31/32 edge", 10.0, 6.0),
    ("just inside 84 N", 83.99, 20.0),
    ("just inside 80 S", -79.99, -70.0),
    ("Norway zone 32V, 5 deg W of its meridian", 60.0, 4.0),
    ("Svalbard zone 33X, 5.9 deg E of its meridian", 78.0, 20.9),
    ("equator", 0.0, -60.0),
    ("antimeridian, south", -17.0, 179.9995),
]
IDS = [d[0] for d in DATUMS]


def _enu_from_geodesic(lat0, lon0, lat, lon):
    """(east, north) [m] of a point from the geodesic distance and true azimuth at the datum."""
    az, _, d = GEOD.inv(lon0, lat0, lon, lat)
    return d * math.sin(math.radians(az)), d * math.cos(math.radians(az))


def _along(lat, lon, azimuth_deg, distance_m):
    lon2, lat2, _ = GEOD.fwd(lon, lat, azimuth_deg, distance_m)
    return lat2, (lon2 + 180.0) % 360.0 - 180.0


def _map_bearing_deg(nav, a, b):
    """Direction of the map segment a -> b, clockwise from the map's +y axis [deg]."""
    (xa, ya, _), (xb, yb, _) = nav.fix_to_map(*a), nav.fix_to_map(*b)
    return math.degrees(math.atan2(xb - xa, yb - ya))


def _enu_nav(lat, lon):
    nav = NavsatTransform(NavsatConfig(yaw_offset=0.0))
    nav.set_datum(lat, lon, 0.0, 0.0, 0.0, 0.0)                 # the map is ENU at the datum
    return nav


@pytest.mark.parametrize("name,lat0,lon0", DATUMS, ids=IDS)
def test_map_is_true_enu_metres_at_any_datum(name, lat0, lon0):
    nav = _enu_nav(lat0, lon0)
    assert nav.fix_to_map(lat0, lon0) == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
    for az in range(0, 360, 30):
        for d in (1.0, 20.0, 150.0, 500.0):
            lat, lon = _along(lat0, lon0, az, d)
            x, y, _ = nav.fix_to_map(lat, lon)
            e, n = _enu_from_geodesic(lat0, lon0, lat, lon)
            assert math.hypot(x - e, y - n) < 1e-3, f"{name}: az {az} d {d}: map ({x}, {y}) vs ({e}, {n})"


@pytest.mark.parametrize("name,lat0,lon0", DATUMS, ids=IDS)
def test_lanes_along_true_north_and_east_stay_along_the_map_axes(name, lat0, lon0):
    # lanes of 50 m through the datum and through points up to FARM_EXTENT_M away in every direction,
    # laid out along true north (the IMU's reference) and along true east: < 0.01 deg off the axes
    nav = _enu_nav(lat0, lon0)
    for az, d in [(0, 0.0)] + [(a, FARM_EXTENT_M) for a in range(0, 360, 45)]:
        start = _along(lat0, lon0, az, d) if d else (lat0, lon0)
        north_end = _along(*start, 0.0, 50.0)
        east_end = _along(*start, 90.0, 50.0)
        assert abs(_map_bearing_deg(nav, start, north_end)) < 0.01, name
        assert abs(_map_bearing_deg(nav, start, east_end) - 90.0) < 0.01, name


@pytest.mark.parametrize("name,lat0,lon0", DATUMS, ids=IDS)
def test_round_trips_are_exact(name, lat0, lon0):
    # an anchored, turned map (datum at map (12, -7), robot facing 1 rad off east) as the navigator makes it
    nav = NavsatTransform(NavsatConfig(yaw_offset=0.0))
    nav.set_datum(lat0, lon0, imu_yaw_rad=0.3, robot_x_m=12.0, robot_y_m=-7.0, robot_yaw_rad=1.3)
    rng = np.random.default_rng(1)
    for x, y in rng.uniform(-600.0, 600.0, (200, 2)):
        lat, lon = nav.map_to_latlon(x, y)
        bx, by, _ = nav.fix_to_map(lat, lon)
        assert math.hypot(bx - x, by - y) < 1e-6, name
    for az, d in zip(rng.uniform(0, 360, 50), rng.uniform(0, 600, 50)):
        lat, lon = _along(lat0, lon0, az, d)
        x, y, _ = nav.fix_to_map(lat, lon)
        la, lo = nav.map_to_latlon(x, y)
        e, n = _enu_from_geodesic(lat, lon, la, lo)
        assert math.hypot(e, n) < 1e-6, name


@pytest.mark.parametrize("name,lat0,lon0", DATUMS, ids=IDS)
def test_simulated_farm_matches_the_map_up_to_a_translation(name, lat0, lon0):
    # the simulator's GPS (hector, heading 0: world x north, y west) on the default farm's lanes (world
    # x -1.43 - 1.8 k, y 8.6 .. 22.6) and Home (-6, 1), where the datum is taken: the robot's ENU map is
    # world rotated by +90 deg (east = -y, north = x) and shifted to Home, within 1 cm and 0.01 deg
    from cottonsim_world.geodesy import HectorGeodesy
    sim = HectorGeodesy(lat0, lon0)
    home = sim.world_to_geodetic(-6.0, 1.0, 0.0)
    nav = _enu_nav(home[0], home[1])
    for k in range(10):
        ends = []
        for wy in (8.6, 22.6):
            wx = -1.43 - 1.8 * k
            lat, lon, _ = sim.world_to_geodetic(wx, wy, 0.0)
            x, y, _ = nav.fix_to_map(lat, lon)
            assert math.hypot(x - (-(wy - 1.0)), y - (wx + 6.0)) < 0.01, name
            ends.append((x, y))
        (x0, y0), (x1, y1) = ends
        lane_yaw = math.degrees(math.atan2(y1 - y0, x1 - x0))      # world +y = west = 180 deg in ENU
        assert abs(abs(lane_yaw) - 180.0) < 0.01, f"{name}: lane {k} at {lane_yaw} deg"


def test_a_utm_grid_map_would_be_turned_by_the_convergence():
    # why the map is not UTM: at Lubbock true north is 1.1 deg off the UTM grid's; the ENU map has 0
    lat0, lon0 = 33.4, -101.0
    gamma = utm_meridian_convergence_rad(lat0, lon0)
    assert utm_zone(lat0, lon0) == 14 and abs(math.degrees(gamma)) > 1.0
    nav = _enu_nav(lat0, lon0)
    assert abs(_map_bearing_deg(nav, (lat0, lon0), _along(lat0, lon0, 0.0, 30.0))) < 1e-4


def test_farm_across_a_zone_edge_is_continuous():
    # datum in zone 31 (lon 5.999), farm reaching into zone 32 (6.0 +- 0.002): one frame, true metres
    lat0, lon0 = 10.0, 5.999
    assert utm_zone(lat0, 5.9999) == 31 and utm_zone(lat0, 6.0001) == 32
    nav = _enu_nav(lat0, lon0)
    lons = np.linspace(5.998, 6.002, 41)
    xs = [nav.fix_to_map(lat0, lon)[0] for lon in lons]
    steps = np.diff(xs)
    metres_per_step = GEOD.inv(5.998, lat0, 5.9981, lat0)[2]
    assert np.allclose(steps, metres_per_step, rtol=1e-6)
    a, b = (lat0 + 0.0001, 6.001), (lat0 - 0.0001, 6.001)      # a north-south lane in zone 32
    assert abs(abs(_map_bearing_deg(nav, a, b)) - 180.0) < 0.01


def test_datum_inside_the_utm_range_only():
    for lat in (84.0, -80.0):
        assert EnuTangentPlane(lat, 10.0).origin_lat_deg == lat
        _enu_nav(lat, 10.0)
    for lat in (84.0001, -80.0001, 89.0, -90.0):
        with pytest.raises(ValueError, match=r"80 S \.\. 84 N"):
            EnuTangentPlane(lat, 10.0)
        with pytest.raises(ValueError, match=r"80 S \.\. 84 N"):
            NavsatTransform().set_datum(lat, 10.0)
        with pytest.raises(ValueError, match=r"80 S \.\. 84 N"):
            NavsatConfig(datum=(lat, 10.0, 0.0))
        with pytest.raises(ValueError, match=r"80 S \.\. 84 N"):
            NavsatTransform().fix_to_map(lat, 10.0)           # a first fix becomes the datum
    for bad in ((91.0, 0.0), (0.0, 181.0), (float("nan"), 0.0), ("north", 0.0)):
        with pytest.raises(ValueError, match="latitude|longitude"):
            EnuTangentPlane(*bad)


def test_fixes_and_points_far_from_the_datum_are_refused():
    nav = _enu_nav(33.4, -101.0)
    near = _along(33.4, -101.0, 45.0, 0.99 * MAX_DISTANCE_FROM_DATUM_M)
    assert math.hypot(*nav.fix_to_map(*near)[:2]) == pytest.approx(0.99 * MAX_DISTANCE_FROM_DATUM_M, rel=1e-3)
    with pytest.raises(ValueError, match="km from the GPS datum"):
        nav.fix_to_map(49.9, 8.9)                               # the default farm's route at Lubbock
    with pytest.raises(ValueError, match="km from the GPS datum"):
        nav.fix_to_map(0.0, 0.0)                                # a glitched fix
    with pytest.raises(ValueError, match="km from the GPS datum"):
        nav.map_to_latlon(2 * MAX_DISTANCE_FROM_DATUM_M, 0.0)
    with pytest.raises(ValueError, match="x_m"):
        nav.map_to_latlon(float("nan"), 0.0)
    with pytest.raises(ValueError, match="datum"):
        NavsatTransform().map_to_latlon(0, 0)


def test_imu_yaw_offset_and_heading_conversion():
    # IMU heading 0 = north with yaw_offset pi/2: the robot faces north; map x = forward = north
    nav = NavsatTransform(NavsatConfig())
    x, y, z = nav.fix_to_map(49.9, 8.9, 120.0, imu_yaw_rad=0.0)
    assert (x, y, z) == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
    x, y, _ = nav.fix_to_map(*_along(49.9, 8.9, 0.0, 10.0))
    assert (x, y) == pytest.approx((10.0, 0.0), abs=1e-6)
    x, y, _ = nav.fix_to_map(*_along(49.9, 8.9, 90.0, 10.0))   # 10 m east -> map -y (right of the robot)
    assert (x, y) == pytest.approx((0.0, -10.0), abs=1e-6)
    assert nav.enu_to_map_rotation_rad == pytest.approx(-math.pi / 2, abs=1e-9)
    assert nav.map_yaw_from_enu(math.pi / 2) == pytest.approx(0.0, abs=1e-9)     # facing north = map yaw 0
    assert nav.enu_yaw_from_map(0.0) == pytest.approx(math.pi / 2, abs=1e-9)
    # the navsat node's and the navigator's anchoring (robot map yaw = its ENU heading): no rotation
    enu = NavsatTransform(NavsatConfig())
    enu.set_datum(33.4, -101.0, imu_yaw_rad=0.4, robot_yaw_rad=0.4 + math.pi / 2)
    assert enu.enu_to_map_rotation_rad == pytest.approx(0.0, abs=1e-9)
    assert enu.map_yaw_from_enu(1.0) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="datum"):
        NavsatTransform().map_yaw_from_enu(0.0)
    # altitude is kept when zero_altitude is off
    assert NavsatTransform(NavsatConfig(zero_altitude=False)).fix_to_map(49.9, 8.9, 120.0)[2] == 120.0
