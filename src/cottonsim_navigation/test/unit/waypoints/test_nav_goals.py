"""Goal poses of a route: headings towards the next waypoint, GPS -> map placement."""
import math

import numpy as np
import pytest
from pyproj import Geod

from cottonsim_navigation.geodesy.navsat import NavsatConfig, NavsatTransform
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
    geod = Geod(ellps="WGS84")           # independent: true distance and azimuth from the datum
    for w, g in zip(wps, goals):
        az, _, d = geod.inv(lon0, lat0, w.lon, w.lat)
        assert (g.x_m, g.y_m) == pytest.approx((d * math.sin(math.radians(az)), d * math.cos(math.radians(az))),
                                               abs=1e-4)
    assert goals[0].y_m == pytest.approx(11.1, abs=0.1) and abs(goals[0].x_m) < 1e-6
    assert goals[1].x_m - goals[0].x_m == pytest.approx(7.2, abs=0.1)
    # first goal faces the second (true east: the map has no grid convergence), last keeps that heading
    assert goals[0].yaw_rad == pytest.approx(0.0, abs=1e-5)
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


def test_snap_to_lanes_moves_only_waypoints_near_a_lane_sideways():
    from cottonsim_navigation.waypoints.goals import snap_to_lanes
    lanes = np.array([[[0.0, 0.0], [0.0, 10.0]], [[2.0, 0.0], [2.0, 10.0]]])   # two lanes along +y
    xy = np.array([[0.3, -3.0],      # 0.3 m beside lane 0, 3 m before its start: snapped
                   [0.2, 5.0],       # in lane 0
                   [1.7, 5.0],       # nearer lane 1 (0.3) than lane 0 (1.7)
                   [1.0, 5.0],       # between the lanes, 1 m from both: beyond max_offset, kept
                   [2.1, 16.0],      # 6 m past lane 1's end: beyond the margin, kept
                   [-0.45, 12.0]])
    out, mask = snap_to_lanes(xy, lanes, max_offset_m=0.5, margin_m=5.0)
    assert mask.tolist() == [True, True, True, False, False, True]
    assert np.allclose(out, [[0.0, -3.0], [0.0, 5.0], [2.0, 5.0], [1.0, 5.0], [2.1, 16.0], [0.0, 12.0]])
    # a slanted lane: the move is perpendicular to it, the position along it is kept
    slanted = np.array([[[0.0, 0.0], [10.0, 10.0]]])
    out, mask = snap_to_lanes(np.array([[5.0, 5.2]]), slanted, 0.5, 0.0)
    assert mask[0] and np.allclose(out[0], [5.1, 5.1])
    with pytest.raises(ValueError, match="lanes_m"):
        snap_to_lanes(xy, np.zeros((0, 2, 2)), 0.5, 5.0)
    with pytest.raises(ValueError, match="coincide"):
        snap_to_lanes(xy, np.zeros((1, 2, 2)), 0.5, 5.0)
    with pytest.raises(ValueError, match="max_offset_m"):
        snap_to_lanes(xy, lanes, -1.0, 5.0)


def test_original_route_snapped_onto_the_default_farm_lanes():
    # the original's 30 waypoints lie up to ~0.35 m off this farm's evenly spaced lanes; with the
    # committed lanes file every one of them moves onto a lane centre, only sideways
    from cottonsim_navigation.waypoints.files import load_gps_lanes
    from cottonsim_navigation.waypoints.goals import gps_lanes_in_map
    wps = load_gps_waypoints(PKG / "config/waypoints/original_gps_waypoints.txt")
    lanes = load_gps_lanes(PKG / "config/waypoints/farm_lanes_gps.txt")
    nav = NavsatTransform(NavsatConfig(yaw_offset=0.0))
    nav.set_datum(wps[0].lat, wps[0].lon, 0.0, 0.0, 0.0, 0.0)
    lanes_m = gps_lanes_in_map(lanes, nav)
    raw = gps_goals_in_map(wps, nav)
    snapped = gps_goals_in_map(wps, nav, lanes_m=lanes_m)
    d = lanes_m[:, 1] - lanes_m[:, 0]
    u = d / np.hypot(d[:, 0], d[:, 1])[:, None]
    for r, s in zip(raw, snapped):
        side = [abs((s.x_m - a[0]) * -e[1] + (s.y_m - a[1]) * e[0]) for a, e in zip(lanes_m[:, 0], u)]
        assert min(side) < 1e-6                                   # on a lane centre line
        k = int(np.argmin(side))
        along_move = (s.x_m - r.x_m) * u[k, 0] + (s.y_m - r.y_m) * u[k, 1]
        assert abs(along_move) < 1e-6                             # moved sideways only
        assert math.hypot(s.x_m - r.x_m, s.y_m - r.y_m) < 0.40
    assert max(math.hypot(s.x_m - r.x_m, s.y_m - r.y_m) for r, s in zip(raw, snapped)) > 0.25
