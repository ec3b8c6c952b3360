"""GPS outages of a run: gaps in the fixes, the navigator's pauses, the pose error during them."""
import math

import numpy as np
import pytest

from cottonsim_navigation.evaluation.gps_outages import (GpsOutageConfig, estimates_in_world, fix_outages,
                                                         gps_outage_report, paused_intervals, position_errors)
from cottonsim_world.geodesy import HectorGeodesy


def fixes_except(*gaps, end=120.0):
    t = np.arange(0.0, end, 0.025)
    keep = np.ones(len(t), bool)
    for a, b in gaps:
        keep &= ~((t >= a) & (t < b))
    return t[keep]


def test_gaps_longer_than_the_minimum_are_outages():
    out = fix_outages(fixes_except((30.0, 45.0), (60.0, 60.5), (80.0, 120.0)), 10.0, 100.0)
    assert out.shape == (2, 2)
    assert out[0] == pytest.approx([29.975, 45.0])           # last fix before, first after
    assert out[1] == pytest.approx([79.975, 100.0])          # still on at the end: open until it
    assert len(fix_outages(fixes_except((60.0, 60.5)), 0.0, 100.0, GpsOutageConfig(min_gap_s=0.4))) == 1


def test_outages_are_cut_to_the_route_and_a_run_without_fixes_is_one_outage():
    out = fix_outages(fixes_except((0.0, 20.0)), 10.0, 50.0)
    assert out.tolist() == [[10.0, 20.0]]
    assert fix_outages([], 5.0, 8.0).tolist() == [[5.0, 8.0]]
    assert fix_outages(fixes_except(), 0.0, 100.0).shape == (0, 2)
    assert fix_outages([1.0], 5.0, 5.0).shape == (0, 2)
    with pytest.raises(ValueError, match="min_gap_s"):
        GpsOutageConfig(min_gap_s=0.0)
    with pytest.raises(ValueError, match="finite"):
        fix_outages([], 0.0, math.inf)


def test_paused_intervals_from_the_navigator_states():
    states = [(1.0, "waiting"), (2.0, "navigating"), (40.0, "paused"), (61.0, "navigating"), (62.0, "navigating"),
              (90.0, "paused")]
    assert paused_intervals(states, 100.0).tolist() == [[40.0, 61.0], [90.0, 100.0]]
    assert paused_intervals([], 10.0).shape == (0, 2)


def test_report_counts_outages_their_errors_and_pauses():
    outages = np.array([[30.0, 45.0], [60.0, 100.0]])
    errors = np.array([[29.0, 0.5], [31.0, 0.02], [44.0, 0.09], [70.0, 0.3], [99.0, 0.2], [110.0, 0.9]])
    paused = np.array([[80.0, 101.0]])
    r = gps_outage_report(outages, errors, paused)
    assert (r["gps_outages"], r["gps_outage_total_s"], r["gps_outage_max_s"]) == (2, 55.0, 40.0)
    assert r["gps_outage_max_position_error_m"] == pytest.approx(0.3)      # 0.5 and 0.9 lie outside
    assert (r["navigator_pauses"], r["navigator_paused_s"]) == (1, 21.0)
    first, second = r["gps_outage_list"]
    assert (first["max_position_error_m"], first["paused_s"]) == (pytest.approx(0.09), 0.0)
    assert (second["duration_s"], second["paused_s"]) == (40.0, 20.0)
    none = gps_outage_report(np.zeros((0, 2)), None, np.zeros((0, 2)))
    assert (none["gps_outages"], none["gps_outage_total_s"], none["gps_outage_max_position_error_m"],
            none["navigator_paused_s"], none["gps_outage_list"]) == (0, 0.0, None, 0.0, [])
    assert gps_outage_report(outages, None, paused)["gps_outage_max_position_error_m"] is None


def test_estimates_are_brought_into_the_world_and_compared_with_the_truth():
    geo = HectorGeodesy()
    # a stand-in for navsat's map -> lat/lon: ENU at the world origin (east = -world y, north = world x)
    to_latlon = lambda x, y: geo.world_to_geodetic(y, -x, 0.0)[:2]
    est_map = np.array([[1.0, 0.0, 2.0], [2.0, -1.0, 2.0], [3.0, float("nan"), 0.0]])
    world = estimates_in_world(est_map, to_latlon, geo)
    assert world == pytest.approx(np.array([[1.0, 2.0, 0.0], [2.0, 2.0, 1.0]]), abs=1e-6)
    traj = np.array([[0.0, 2.0, -1.0, 0.0], [2.0, 2.0, 3.0, 0.0]])    # truth at (2, 1) at t = 1, (2, 3) at t = 2
    err = position_errors(world, traj)
    assert err[:, 0].tolist() == [1.0, 2.0]
    assert err[:, 1] == pytest.approx([1.0, 2.0], abs=1e-6)
    assert position_errors(world, traj[:1]).shape == (0, 2)
