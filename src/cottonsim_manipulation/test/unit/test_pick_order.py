"""Pick order: greedy nearest-next in joint space with 2-opt, deterministic, shorter than input order."""
import numpy as np
import pytest

from cottonsim_manipulation.harvest.pick_order import (PickOrderConfig, approach_blockers, clear_approaches_first,
                                                       order_picks, path_joint_travel_rad)

START = np.array([1.57, -2.2, 2.4, -1.77, -1.57, 0.0])


def random_targets(seed, n):
    rng = np.random.default_rng(seed)
    return list(range(100, 100 + n)), START + rng.uniform(-1.5, 1.5, size=(n, 6))


@pytest.mark.parametrize("seed", range(10))
def test_order_is_shorter_than_input_order_and_visits_each_target_once(seed):
    ids, q = random_targets(seed, 8)
    order = order_picks(ids, q, START)
    assert sorted(order.target_ids) == ids
    by_id = dict(zip(ids, q))
    travel = path_joint_travel_rad(START, [by_id[i] for i in order.target_ids])
    assert travel == pytest.approx(order.joint_travel_rad)
    assert travel < path_joint_travel_rad(START, q)


def test_two_opt_never_lengthens_the_greedy_path_and_shortens_some():
    shorter = 0
    for seed in range(20):
        ids, q = random_targets(seed, 10)
        greedy = order_picks(ids, q, START, PickOrderConfig(two_opt_passes=0))
        improved = order_picks(ids, q, START)
        assert improved.joint_travel_rad <= greedy.joint_travel_rad + 1e-9
        shorter += improved.joint_travel_rad < greedy.joint_travel_rad - 1e-9
    assert shorter >= 1


def test_order_is_deterministic_and_finds_the_obvious_line():
    ids, q = random_targets(3, 9)
    assert order_picks(ids, q, START) == order_picks(ids, q.copy(), START.copy())
    # Targets on a line in joint space, given shuffled: picked along the line from the start.
    line = START + np.outer(np.arange(1, 6) * 0.3, np.ones(6))
    shuffled = [3, 0, 4, 1, 2]
    order = order_picks([10 + k for k in shuffled], line[shuffled], START)
    assert order.target_ids == [10, 11, 12, 13, 14]


def test_no_targets_and_bad_input():
    assert order_picks([], np.zeros((0, 6)), START).target_ids == []
    with pytest.raises(ValueError, match="unique"):
        order_picks([1, 1], np.zeros((2, 6)), START)
    with pytest.raises(ValueError, match="one row"):
        order_picks([1, 2], np.zeros((3, 6)), START)
    with pytest.raises(ValueError, match="finite"):
        order_picks([1], np.full((1, 6), np.nan), START)
    with pytest.raises(ValueError, match="two_opt_passes"):
        PickOrderConfig(two_opt_passes=-1)


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
