"""A stop's pick order: a target after the targets on its approach line, else the given order."""
import numpy as np
import pytest

from cottonsim_manipulation.harvest.pick_order import PickOrderConfig, approach_blockers, clear_approaches_first


def test_approach_blockers_are_the_targets_near_each_approach_segment():
    ids = [1, 2, 3, 4]
    positions = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.05, 0.04, 0.0], [0.3, 0.0, 0.0]])
    starts = np.array([[0.10, 0.0, 0.0], [0.15, 0.0, 0.0], [np.nan] * 3, [0.4, 0.0, 0.0]])
    ends = positions.copy()
    blockers = approach_blockers(ids, positions, starts, ends, 0.03)
    assert blockers == {1: {2}, 2: set(), 4: set()}      # 3 has no line; 3 is 4 cm off 1's line; 1 is behind 2's end
    assert approach_blockers(ids, positions, starts, ends, 0.045)[1] == {2, 3}
    with pytest.raises(ValueError, match="ids"):
        approach_blockers(ids, positions[:3], starts, ends, 0.03)
    with pytest.raises(ValueError, match="NaN"):
        approach_blockers(ids, np.full((4, 3), np.nan), starts, ends, 0.03)


def test_a_target_on_anothers_approach_line_is_picked_first_else_the_travel_order_stands():
    assert clear_approaches_first([1, 2, 3], {1: {3}}) == [2, 3, 1]
    assert clear_approaches_first([1, 2, 3], {1: {3}, 3: {2}}) == [2, 3, 1]
    assert clear_approaches_first([1, 2, 3], {}) == [1, 2, 3]
    assert clear_approaches_first([1, 2, 3], {1: {99}}) == [1, 2, 3]          # a blocker outside the stop
    assert clear_approaches_first([1, 2, 3], {1: {2}, 2: {1}}) == [3, 1, 2]   # 3 is clear; then a circle:
    assert clear_approaches_first([1, 2], {1: {2}, 2: {1}}) == [1, 2]         # the travel order goes on
    with pytest.raises(ValueError, match="unique"):
        clear_approaches_first([1, 1], {})


def test_the_clear_radius_is_validated():
    assert PickOrderConfig().clear_approach_radius_m == pytest.approx(0.03)
    for bad in (-0.01, float("nan"), 1.0, "0.03"):
        with pytest.raises(ValueError, match="clear_approach_radius_m"):
            PickOrderConfig(clear_approach_radius_m=bad)
