"""The halt at bolls: dwell, resume, no stall with a boll that stays in view, re-arm after moving on."""
import math

import pytest

from cottonsim_navigation.waypoints.boll_halt import BollHalt, BollHaltConfig, BollVerdicts


def drive(halt, t0_s, t1_s, dt_s, x_of_t, in_reach_of_t):
    """Step the halt from t0_s to t1_s; returns [(t, decision)]."""
    out = []
    n = int(round((t1_s - t0_s) / dt_s))
    for i in range(n + 1):
        t = t0_s + i * dt_s
        out.append((t, halt.step(t, x_of_t(t), 0.0, in_reach_of_t(t))))
    return out


def test_halts_when_bolls_come_into_reach_for_the_dwell_then_resumes():
    halt = BollHalt(BollHaltConfig(dwell_s=2.0, rearm_distance_m=0.7, min_gap_s=0.0))
    assert not halt.step(0.0, 0.0, 0.0, False).halted
    d = halt.step(1.0, 0.5, 0.0, True)
    assert d.started and d.halted and halt.halts == 1
    assert halt.step(2.9, 0.5, 0.0, True).halted
    end = halt.step(3.0, 0.5, 0.0, True)
    assert end.ended and not end.halted and not end.started
    assert halt.halt_time_s == pytest.approx(2.0)


def test_a_boll_that_stays_in_view_never_stalls_a_standing_robot():
    halt = BollHalt(BollHaltConfig(dwell_s=2.0, rearm_distance_m=0.7, min_gap_s=1.0))
    steps = drive(halt, 0.0, 600.0, 0.1, lambda t: 3.0, lambda t: True)     # never moves, boll always there
    assert halt.halts == 1
    halted_s = sum(0.1 for _, d in steps if d.halted)
    assert halted_s == pytest.approx(2.0, abs=0.15)
    assert not steps[-1][1].halted


def test_re_arms_only_after_moving_the_rearm_distance_and_the_gap():
    cfg = BollHaltConfig(dwell_s=1.0, rearm_distance_m=0.7, min_gap_s=1.0)
    halt = BollHalt(cfg)
    assert halt.step(0.0, 0.0, 0.0, True).started                  # halt at x = 0
    assert halt.step(1.0, 0.0, 0.0, True).ended
    assert not halt.step(1.5, 0.69, 0.0, True).halted              # moved 0.69 m: not yet re-armed
    assert not halt.step(1.9, 0.8, 0.0, True).halted               # 0.8 m but only 0.9 s after the halt
    assert halt.step(2.1, 0.8, 0.0, True).started                  # both: halts again
    assert halt.halts == 2


def test_moving_robot_halts_about_once_per_rearm_distance_along_a_row_full_of_bolls():
    cfg = BollHaltConfig(dwell_s=2.0, rearm_distance_m=0.7, min_gap_s=0.0)
    halt = BollHalt(cfg)
    x = 0.0
    t = 0.0
    while x < 7.0:                                  # 0.5 m/s whenever not halted, bolls everywhere
        d = halt.step(t, x, 0.0, True)
        if not d.halted:
            x += 0.05
        t += 0.1
    assert halt.halts == 10                         # x = 0, 0.7, ..., 6.3 (7.0 ends the loop)
    assert 10 * 2.0 <= halt.halt_time_s <= 10 * 2.1 + 1e-9     # each ends on the first 0.1 s step after 2 s


def test_disabled_never_halts_and_no_bolls_never_halts():
    off = BollHalt(BollHaltConfig(enabled=False))
    assert not any(d.halted for _, d in drive(off, 0.0, 10.0, 0.5, lambda t: t, lambda t: True))
    on = BollHalt(BollHaltConfig())
    assert not any(d.halted for _, d in drive(on, 0.0, 10.0, 0.5, lambda t: t, lambda t: False))
    assert off.halts == on.halts == 0


def test_unknown_position_does_not_re_arm_until_a_position_is_known():
    halt = BollHalt(BollHaltConfig(dwell_s=1.0, rearm_distance_m=0.5, min_gap_s=0.0))
    assert halt.step(0.0, None, None, True).started
    assert halt.step(1.0, None, None, True).ended
    assert not halt.step(2.0, math.nan, 0.0, True).halted
    assert not halt.step(3.0, 2.0, 0.0, True).halted                 # first known position: the reference
    assert not halt.step(4.0, 2.4, 0.0, True).halted
    assert halt.step(5.0, 2.5, 0.0, True).started


def test_cancel_ends_a_halt_and_counts_its_time():
    halt = BollHalt(BollHaltConfig(dwell_s=5.0))
    halt.step(10.0, 0.0, 0.0, True)
    assert halt.cancel(11.5) and not halt.halted
    assert halt.halt_time_s == pytest.approx(1.5)
    assert not halt.cancel(12.0)


def test_time_going_back_restarts_the_dwell_instead_of_stalling():
    halt = BollHalt(BollHaltConfig(dwell_s=2.0))
    halt.step(100.0, 0.0, 0.0, True)
    assert halt.step(1.0, 0.0, 0.0, True).halted                    # a sim reset
    assert halt.step(3.0, 0.0, 0.0, True).ended


@pytest.mark.parametrize("key,value", [("dwell_s", 0.0), ("dwell_s", -1.0), ("rearm_distance_m", 0.0),
                                       ("min_gap_s", math.inf), ("max_age_s", 0.0), ("dwell_s", "2"),
                                       ("enabled", 1)])
def test_bad_config_names_the_key(key, value):
    with pytest.raises(ValueError, match=key):
        BollHaltConfig(**{key: value})


def test_verdicts_of_two_cameras_are_or_ed_and_go_stale():
    v = BollVerdicts(max_age_s=0.5)
    assert not v.in_reach(0.0)
    v.report("/boll_detection_left", True, 1.0)
    v.report("/boll_detection_right", False, 1.0)
    assert v.in_reach(1.2)                  # the right camera's false does not hide the left's true
    v.report("/boll_detection_right", False, 1.4)
    assert v.in_reach(1.4)
    assert not v.in_reach(1.6)              # the left's true is 0.6 s old
    v.report("/boll_detection_left", False, 1.7)
    assert not v.in_reach(1.7)
    with pytest.raises(ValueError, match="stamp_s"):
        v.report("x", True, math.nan)
