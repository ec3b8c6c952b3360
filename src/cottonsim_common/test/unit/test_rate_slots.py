"""rate_slots: slot boundaries that float and nanosecond stamps agree on; the first stamp of each slot."""
import numpy as np
import pytest

from cottonsim_common.rate_slots import FirstOfSlotGate, slot_index


@pytest.mark.parametrize("stamp_s, rate_hz, slot", [(0.0, 5.0, 0), (0.199, 5.0, 0), (0.2, 5.0, 1), (1.0, 5.0, 5),
                                                    (0.7, 20.0, 14), (0.5, 2.0, 1), (0.49, 2.0, 0)])
def test_slot_index(stamp_s, rate_hz, slot):
    assert slot_index(stamp_s, rate_hz) == slot


def test_a_float_stamp_and_its_nanoseconds_fall_into_the_same_slot():
    steps = np.arange(0, 4000) * 0.005                  # physics steps, floats summed as the simulator does
    for stamp in steps:
        ns = int(round(stamp * 1e9))
        assert slot_index(stamp, 5.0) == slot_index(ns * 1e-9, 5.0)
        assert slot_index(stamp, 2.0) == slot_index(ns * 1e-9, 2.0)


def test_the_gate_takes_the_first_stamp_of_each_slot_and_the_same_from_a_thinned_stream():
    every = [float(s) for s in np.ceil(np.arange(0, 24 * 5) / 24.0 / 0.005 - 1e-9) * 0.005]   # 24 fps on 5 ms steps
    gate = FirstOfSlotGate(5.0)
    taken = [s for s in every if gate.take(s)]
    assert len(taken) == 25
    assert [slot_index(s, 5.0) for s in taken] == list(range(25))
    # a consumer at the same rate that gets only these frames (the simulator's render_rate_hz) takes all of them,
    # whichever frame it starts with
    for start in range(5):
        later = FirstOfSlotGate(5.0)
        assert [s for s in taken[start:] if later.take(s)] == taken[start:]
