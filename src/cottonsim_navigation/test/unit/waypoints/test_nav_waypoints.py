"""Waypoint files and the follower state machine."""
import math
import pathlib

import pytest

from cottonsim_navigation.waypoints.files import (WaypointFileError, load_gps_waypoints, load_map_waypoints)
from cottonsim_navigation.waypoints.follower import (FollowerConfig, FollowerState, GoalResult, LocalisationGate,
                                                     WaypointFollower)

WAYPOINT_DIR = pathlib.Path(__file__).resolve().parents[3] / "config" / "waypoints"


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_gps_text_and_yaml(tmp_path):
    p = write(tmp_path, "w.txt", "# route\n49.9 8.9\n\n49.91, 8.91  # second\n")
    w = load_gps_waypoints(p)
    assert [(x.lat, x.lon) for x in w] == [(49.9, 8.9), (49.91, 8.91)]
    y = write(tmp_path, "w.yaml", "- {lat: 1.5, lon: 2.5}\n- {latitude: -3, longitude: 4}\n")
    assert [(x.lat, x.lon) for x in load_gps_waypoints(y)] == [(1.5, 2.5), (-3.0, 4.0)]


@pytest.mark.parametrize("text,line,what", [
    ("49.9 8.9\n49.9 abc\n", 2, "not a number"),
    ("49.9 8.9 1\n", 1, "2 columns"),
    ("\n\n91 8.9\n", 3, "latitude"),
    ("1 2\n1 -181\n", 2, "longitude"),
    ("nan 8.9\n", 1, "not finite"),
    ("1 inf\n", 1, "not finite"),
])
def test_gps_errors_name_line(tmp_path, text, line, what):
    p = write(tmp_path, "bad.txt", text)
    with pytest.raises(WaypointFileError, match=what) as e:
        load_gps_waypoints(p)
    assert e.value.line == line and f"bad.txt:{line}" in str(e.value)


def test_empty_and_missing(tmp_path):
    with pytest.raises(WaypointFileError, match="no waypoints"):
        load_gps_waypoints(write(tmp_path, "e.txt", "# nothing\n\n"))
    with pytest.raises(WaypointFileError, match="not found"):
        load_map_waypoints(tmp_path / "missing.csv")


def test_map_csv_lines_yaml(tmp_path):
    c = write(tmp_path, "m.csv", "label,x,y,yaw_rad\n1-1,3.9,-5.0,0\n1-2,14.5,-5.4,1.5\n")
    w = load_map_waypoints(c)
    assert [(x.label, x.x_m, x.y_m, x.yaw_rad) for x in w] == [("1-1", 3.9, -5.0, 0.0), ("1-2", 14.5, -5.4, 1.5)]
    assert [(x.x_m, x.y_m, x.yaw_rad) for x in load_map_waypoints(write(tmp_path, "m.txt", "1 2 3\n4 5\n"))] == \
        [(1, 2, 3), (4, 5, 0)]
    assert load_map_waypoints(write(tmp_path, "m.yaml", "- {x: 1, y: 2, yaw: 0.5}\n"))[0].yaw_rad == 0.5
    with pytest.raises(WaypointFileError, match="4 columns") as e:
        load_map_waypoints(write(tmp_path, "b.csv", "label,x,y,yaw_rad\na,1,2,3\nb,1,2\n"))
    assert e.value.line == 3


def test_original_reference_files():
    gps = load_gps_waypoints(str(WAYPOINT_DIR / "original_gps_waypoints.txt"))
    m = load_map_waypoints(str(WAYPOINT_DIR / "original_map_waypoints.csv"))
    assert len(gps) == 30 and len(m) == 30
    assert all(49.8 < w.lat < 50.0 for w in gps)


def test_follower_skip_and_stop():
    f = WaypointFollower(["a", "b", "c"], FollowerConfig(on_failure="skip"))
    assert f.next_goal(localization_ready=False) is None and f.state is FollowerState.WAITING
    assert f.next_goal() == "a"
    assert f.next_goal() is None                    # one goal at a time
    f.report_result(GoalResult.SUCCEEDED)
    assert f.next_goal() == "b"
    f.report_result(GoalResult.ABORTED, "goal (2.00, 0.00) is in or next to an obstacle")
    assert f.next_goal() == "c"
    f.report_result(GoalResult.SUCCEEDED)
    assert f.finished and f.summary.succeeded == 2 and f.summary.aborted == 1
    assert f.summary.aborted_waypoints == [{"index": 2, "reason": "goal (2.00, 0.00) is in or next to an obstacle"}]
    g = WaypointFollower(["a", "b", "c"], FollowerConfig(on_failure="stop"))
    g.next_goal()
    g.report_result(GoalResult.ABORTED)
    assert g.finished and g.next_goal() is None and g.summary.skipped == 2
    with pytest.raises(ValueError, match="on_failure"):
        FollowerConfig(on_failure="retry")


def test_follower_battery_low_goes_home_and_stops():
    f = WaypointFollower(["a", "b", "c", "d"], home="H")
    f.next_goal()
    f.report_result(GoalResult.SUCCEEDED)
    f.next_goal()                                   # 'b' active
    f.battery_low()
    assert f.going_home and f.next_goal() == "H"
    f.report_result(GoalResult.SUCCEEDED)
    assert f.finished and f.summary.returned_home and f.summary.home_reached
    assert f.summary.skipped == 3 and f.summary.succeeded == 1
    with pytest.raises(ValueError, match="home"):
        WaypointFollower(["a"]).battery_low()


def test_follower_hold_resends_the_same_goal_and_counts_nothing():
    f = WaypointFollower(["a", "b"], FollowerConfig(on_failure="stop", pass_through_radius_m=1.0), home="H",
                         pass_through=[True, False])
    assert not f.hold()                             # nothing active yet: nothing to hold
    assert f.next_goal() == "a"
    assert f.hold() and f.state is FollowerState.WAITING
    assert not f.hold()                             # already held
    assert not f.passed(0.1)                        # a held goal cannot be driven through
    with pytest.raises(ValueError, match="no active goal"):
        f.report_result(GoalResult.ABORTED)         # a held goal has no result (on_failure=stop untouched)
    assert f.next_goal(localization_ready=False) is None
    assert f.next_goal() == "a"                     # the same goal again, route not cut short
    assert f.hold() and f.next_goal() == "a"
    f.report_result(GoalResult.SUCCEEDED)
    assert f.next_goal() == "b"
    f.hold()
    f.battery_low()                                 # battery low while held: Home next, 'b' skipped
    assert f.next_goal() == "H"
    f.report_result(GoalResult.SUCCEEDED)
    s = f.summary
    assert f.finished and (s.succeeded, s.aborted, s.skipped, s.holds) == (1, 0, 1, 3) and s.home_reached


def test_follower_drives_through_pass_through_waypoints_only_within_the_radius():
    f = WaypointFollower(["a", "b", "c"], FollowerConfig(pass_through_radius_m=0.5), home="H",
                         pass_through=[False, True, False])
    assert f.next_goal() == "a"
    assert not f.passed(0.1)                        # 'a' is a full stop: move_base must report it
    f.report_result(GoalResult.SUCCEEDED)
    assert f.next_goal() == "b"
    assert not f.passed(0.51) and not f.passed(float("nan"))
    assert f.passed(0.49)                           # counted, and the next goal is free to go
    assert f.next_goal() == "c" and not f.passed(0.0)
    f.report_result(GoalResult.SUCCEEDED)
    assert f.finished and f.summary.succeeded == 3 and f.summary.passed == 1
    # radius 0 switches it off; the way Home never passes through
    g = WaypointFollower(["a", "b", "c"], FollowerConfig(), pass_through=[False, True, False])
    g.next_goal(); g.report_result(GoalResult.SUCCEEDED); g.next_goal()
    assert not g.passed(0.0)
    h = WaypointFollower(["a", "b", "c"], FollowerConfig(pass_through_radius_m=1.0), home="H",
                         pass_through=[True, True, True])
    h.next_goal(); h.battery_low(); assert h.next_goal() == "H" and not h.passed(0.0)
    with pytest.raises(ValueError, match="pass_through has 2 flags"):
        WaypointFollower(["a", "b", "c"], pass_through=[True, False])
    with pytest.raises(ValueError, match="pass_through_radius_m"):
        FollowerConfig(pass_through_radius_m=-1.0)


def test_gps_lanes_file(tmp_path):
    from cottonsim_navigation.waypoints.files import load_gps_lanes, save_gps_lanes
    p = tmp_path / "lanes.txt"
    p.write_text("# two lanes\n49.9 8.9 49.9 8.8999\n\n49.8999, 8.9, 49.8999, 8.8999  # comma separated\n")
    lanes = load_gps_lanes(p)
    assert len(lanes) == 2 and lanes[1][0].lat == 49.8999 and lanes[1][1].lon == 8.8999
    q = tmp_path / "again.txt"
    save_gps_lanes(q, lanes, comment="copy")
    assert [(a.lat, a.lon, b.lat, b.lon) for a, b in load_gps_lanes(q)] == \
        [(a.lat, a.lon, b.lat, b.lon) for a, b in lanes]
    for text, what in (("49.9 8.9 49.9\n", "4 columns"), ("49.9 8.9 49.9 x\n", "not a number"),
                       ("49.9 8.9 49.9 8.9\n", "same point"), ("# nothing\n", "no lanes"),
                       ("49.9 8.9 95.0 8.9\n", "latitude")):
        p.write_text(text)
        with pytest.raises(WaypointFileError, match=what):
            load_gps_lanes(p)


def test_localization_gate_is_lost_only_after_having_been_localized():
    g = LocalisationGate()
    assert not g.lost                               # nothing heard
    g.report(False)
    assert not g.lost                               # not localised yet at the start: not "lost"
    g.report(True)
    assert not g.lost
    g.report(False)
    assert g.lost                                   # a kidnap
    g.report(False)
    assert g.lost
    g.report(True)
    assert not g.lost and g.ever_localized          # localised again
    with pytest.raises(ValueError, match="localized"):
        g.report("yes")


def test_a_yaml_waypoint_file_with_a_repeated_key_is_refused_with_its_line(tmp_path):
    path = write(tmp_path, "w.yaml", "- {x: 1, y: 2, yaw: 0.5}\n- x: 3\n  y: 4\n  x: 5\n")
    with pytest.raises(WaypointFileError, match=r"'x' is given twice \(lines 2 and 4\)") as err:
        load_map_waypoints(path)
    assert err.value.line == 4
