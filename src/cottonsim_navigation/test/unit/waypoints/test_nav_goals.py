"""Goal poses of a route: headings towards the next waypoint, GPS -> map placement."""
import math

import numpy as np
import pytest

from cottonsim_navigation.geodesy.utm import NavsatConfig, NavsatTransform, latlon_to_utm
from cottonsim_navigation.waypoints.files import GpsWaypoint, MapWaypoint, load_gps_waypoints, load_map_waypoints
from cottonsim_navigation.waypoints.goals import gps_goals_in_map, map_goals, route_headings

PKG = __import__("pathlib").Path(__file__).resolve().parents[3]


def test_headings_face_the_next_waypoint_and_keep_the_last_leg():
    # east, then north, then west: a serpentine corner
    xy = [(0, 0), (10, 0), (10, 2), (0, 2)]
    yaw = route_headings(xy)
    assert yaw == pytest.approx([0.0, math.pi / 2, math.pi, math.pi])


def test_headings_final_yaw_and_repeated_points():
    xy = [(0, 0), (0, 0), (0, 5), (0, 5)]
    yaw = route_headings(xy, final_yaw_rad=-1.0)
    # the duplicate start takes the heading of the first real leg; the duplicate end the leg before it
    assert yaw[0] == pytest.approx(math.pi / 2)
    assert yaw[1] == pytest.approx(math.pi / 2)
    assert yaw[2] == pytest.approx(math.pi / 2)
    assert yaw[3] == pytest.approx(-1.0)
    assert route_headings([(1, 1), (1, 1)]) == pytest.approx([0.0, 0.0])
    assert route_headings([(3, 4)], final_yaw_rad=0.5) == pytest.approx([0.5])


@pytest.mark.parametrize("bad,what", [([], "no waypoints"), ([(0, np.nan)], "non-finite"),
                                      ([(1, 2, 3)], "shape")])
def test_headings_reject_bad_input(bad, what):
    with pytest.raises(ValueError, match=what):
        route_headings(np.array(bad, dtype=float).reshape(-1, 3 if bad and len(bad[0]) == 3 else 2))


def test_gps_goals_are_enu_metres_from_the_datum():
    nav = NavsatTransform(NavsatConfig(yaw_offset=0.0))
    lat0, lon0 = 49.9, 8.9
    nav.set_datum(lat0, lon0, 0.0, 0.0, 0.0, 0.0)
    # about 11 m north, then about 7 m east of that (1e-4 deg lat ~ 11.1 m, 1e-4 deg lon ~ 7.2 m here)
    wps = [GpsWaypoint(lat0 + 1e-4, lon0), GpsWaypoint(lat0 + 1e-4, lon0 + 1e-4, "b")]
    goals = gps_goals_in_map(wps, nav)
    e0, n0, zone, _ = latlon_to_utm(lat0, lon0)
    for w, g in zip(wps, goals):
        e, n, _, _ = latlon_to_utm(w.lat, w.lon, zone=zone)
        assert (g.x_m, g.y_m) == pytest.approx((e - e0, n - n0), abs=1e-6)
    assert goals[0].y_m == pytest.approx(11.1, abs=0.1) and abs(goals[0].x_m) < 0.1
    assert goals[1].x_m - goals[0].x_m == pytest.approx(7.2, abs=0.1)
    # first goal faces the second (east, with UTM grid convergence of ~0.1 deg), last keeps that heading
    assert goals[0].yaw_rad == pytest.approx(0.0, abs=0.01)
    assert goals[1].yaw_rad == pytest.approx(goals[0].yaw_rad)
    assert [g.label for g in goals] == ["1", "b"]


def test_gps_goals_need_a_datum():
    with pytest.raises(ValueError, match="datum"):
        gps_goals_in_map([GpsWaypoint(49.9, 8.9)], NavsatTransform(NavsatConfig()))


def test_map_goals_fix_the_originals_return_pass_yaw():
    wps = load_map_waypoints(PKG / "config" / "waypoints" / "original_map_waypoints.csv")
    assert len(wps) == 30
    assert wps[3].yaw_rad == pytest.approx(1.0)          # the original's defect (return pass: should be ~pi)
    goals = map_goals(wps)
    # waypoints 4-6 drive back along -x in the map (the second lane): heading ~ pi
    assert abs(math.remainder(goals[3].yaw_rad - math.pi, 2 * math.pi)) < 0.15
    assert abs(goals[0].yaw_rad) < 0.15                   # first lane along +x
    kept = map_goals(wps, "file")
    assert [g.yaw_rad for g in kept] == [w.yaw_rad for w in wps]
    with pytest.raises(ValueError, match="goal_yaw"):
        map_goals(wps, "sideways")


def test_shipped_route_files_read_and_match():
    """The lane-centred GPS route and the map route of the default farm describe the same points."""
    from cottonsim_world.geodesy import HectorGeodesy
    gps = load_gps_waypoints(PKG / "config" / "waypoints" / "route_gps.txt")
    home = load_map_waypoints(PKG / "config" / "waypoints" / "route_map.csv")
    orig = load_gps_waypoints(PKG / "config" / "waypoints" / "original_gps_waypoints.txt")
    assert len(gps) == len(home) == len(orig) == 30
    x, y, _ = HectorGeodesy().geodetic_to_world(np.array([w.lat for w in gps]), np.array([w.lon for w in gps]))
    # Home (spawn) is world (-6, 1) facing +y: map x = world y - 1, map y = -(world x + 6)
    assert np.allclose(np.array([w.x_m for w in home]), y - 1.0, atol=1e-3)
    assert np.allclose(np.array([w.y_m for w in home]), -(x + 6.0), atol=1e-3)
    # lane centres at x = -1.43 - 1.8 k
    lanes = np.round((-1.43 - x) / 1.8)
    assert np.allclose(x, -1.43 - 1.8 * lanes, atol=1e-3)


def test_pass_through_flags_mark_straight_on_waypoints_not_turns():
    from cottonsim_navigation.waypoints.goals import pass_through_flags
    # a serpentine over two lanes: entry, middle, exit, (90 deg) entry, middle, exit
    xy = np.array([[0, 0], [10, 0], [20, 0], [20, 2], [10, 2], [0, 2.0]])
    assert pass_through_flags(xy, math.radians(20)).tolist() == [False, True, False, False, True, False]
    # a slight kink (the original's uneven lanes) still passes; 0 rad demands a perfectly straight line
    kinked = np.array([[0, 0], [10, 0.3], [20, 0.0]])
    assert pass_through_flags(kinked, math.radians(20)).tolist() == [False, True, False]
    assert pass_through_flags(kinked, 0.0).tolist() == [False, False, False]
    # a repeated point has no direction
    assert not pass_through_flags(np.array([[0, 0], [1, 0], [1, 0], [2, 0.0]]), 0.5).any()
    with pytest.raises(ValueError, match="max_turn_rad"):
        pass_through_flags(xy, -0.1)
    with pytest.raises(ValueError, match="non-finite"):
        pass_through_flags(np.array([[0, 0], [np.nan, 1]]), 0.3)
