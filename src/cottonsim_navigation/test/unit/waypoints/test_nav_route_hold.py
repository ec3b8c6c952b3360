"""The route hold (waypoints.route_hold): another node holds the route while it sends fresh requests."""
import math

import pytest

from cottonsim_navigation.waypoints.route_hold import RouteHold, RouteHoldConfig


def test_a_fresh_hold_stops_the_route_and_the_release_resumes_it():
    hold = RouteHold(RouteHoldConfig(max_age_s=1.0))
    assert not hold.step(0.0).halted
    hold.report(True, 0.5)
    d = hold.step(0.6)
    assert d.halted and d.started and not d.ended
    hold.report(True, 1.2)
    d = hold.step(1.5)
    assert d.halted and not d.started
    hold.report(False, 2.0)
    d = hold.step(2.1)
    assert d.ended and not d.halted
    assert hold.holds == 1 and hold.hold_time_s == pytest.approx(1.5)
    assert hold.step(2.2) == hold.step(2.3) and not hold.held     # no second end


def test_a_silent_holder_releases_the_route_after_max_age():
    hold = RouteHold(RouteHoldConfig(max_age_s=1.0))
    hold.report(True, 10.0)
    assert hold.step(10.0).started
    assert hold.step(10.9).halted
    d = hold.step(11.01)                  # no request for more than max_age_s: the holder is gone
    assert d.ended and not d.halted
    assert not hold.step(50.0).halted        # and it stays released until a new request


def test_stale_and_release_requests_never_start_a_hold():
    hold = RouteHold(RouteHoldConfig(max_age_s=0.5))
    hold.report(True, 0.0)
    assert not hold.step(2.0).started      # too old already when first looked at
    hold.report(False, 3.0)
    assert not hold.step(3.0).halted
    assert hold.holds == 0


def test_holds_are_counted_each_time():
    hold = RouteHold()
    for k in range(3):
        hold.report(True, 10.0 * k)
        assert hold.step(10.0 * k).started
        hold.report(False, 10.0 * k + 2.0)
        assert hold.step(10.0 * k + 2.0).ended
    assert hold.holds == 3 and hold.hold_time_s == pytest.approx(6.0)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf, True, "1"])
def test_bad_max_age_is_refused_by_name(bad):
    with pytest.raises(ValueError, match="max_age_s"):
        RouteHoldConfig(max_age_s=bad)


def test_non_finite_times_are_refused():
    hold = RouteHold()
    with pytest.raises(ValueError, match="stamp_s"):
        hold.report(True, math.nan)
    with pytest.raises(ValueError, match="now_s"):
        hold.step(math.inf)
