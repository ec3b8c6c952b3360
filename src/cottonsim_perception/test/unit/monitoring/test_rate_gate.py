"""RateGate: at most one frame per slot, the rate kept on average, no catching up, restarts on a clock reset."""
import numpy as np
import pytest

from cottonsim_perception.monitoring.rate_gate import RateGate, check_rate_hz


def _taken(gate, stamps):
    return [s for s in stamps if gate.take(s)]


def test_a_24_fps_camera_through_a_5_hz_gate_gives_5_frames_per_second():
    stamps = np.arange(0, 24 * 10) / 24.0            # 10 s of frames
    taken = _taken(RateGate(5.0), stamps)
    assert len(taken) == 50
    assert np.all(np.diff(taken) >= 0.2 - 1.0 / 24)  # never two frames within one slot


def test_a_rate_above_the_camera_takes_every_frame():
    stamps = np.arange(0, 30) / 10.0
    assert _taken(RateGate(20.0), stamps) == list(stamps)


def test_two_hz_takes_the_first_frame_of_each_slot():
    stamps = np.arange(0, 24 * 3) / 24.0
    assert len(_taken(RateGate(2.0), stamps)) == 6


def test_a_gap_is_not_caught_up_in_a_burst():
    gate = RateGate(5.0)
    assert gate.take(0.0)
    assert gate.take(10.0)               # after a 10 s gap: taken, then the slots start again from here
    assert not gate.take(10.05)
    assert not gate.take(10.15)
    assert gate.take(10.2)


def test_a_clock_that_goes_back_restarts_the_schedule():
    gate = RateGate(1.0)
    assert gate.take(100.0)
    assert not gate.take(100.5)
    assert gate.take(3.0)                # the simulator restarted
    assert not gate.take(3.5)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), "fast", None])
def test_bad_rates_are_refused_with_the_key(bad):
    with pytest.raises(ValueError, match="rate_hz"):
        RateGate(bad)
    with pytest.raises(ValueError, match="~rate_hz"):
        check_rate_hz(bad, "~rate_hz")


def test_slots_are_fixed_in_sim_time_not_started_by_the_first_frame():
    gate = RateGate(5.0)
    assert gate.take(0.19)
    assert gate.take(0.21)               # a new slot (0.2 - 0.4 s), though only 20 ms after the first frame
    assert not gate.take(0.39)
