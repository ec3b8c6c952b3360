"""Localisation error of map-frame estimates against a world-frame ground-truth trajectory."""
import math

import numpy as np
import pytest

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.evaluation.localization_error import localization_errors, localization_summary

HOME = Pose2D(-6.0, 1.0, math.pi / 2)


def _truth():
    t = np.linspace(0.0, 20.0, 201)
    # the robot drives along world +y from Home at 0.5 m/s
    return np.column_stack([t, np.full_like(t, -6.0), 1.0 + 0.5 * t, np.full_like(t, math.pi / 2)])


def test_a_perfect_estimate_has_zero_error_and_offsets_come_out_in_metres():
    traj = _truth()
    t = np.array([1.05, 7.33, 19.9])
    exact = np.column_stack([t, 0.5 * t, np.zeros_like(t)])            # map x = along the drive
    np.testing.assert_allclose(localization_errors(exact, traj, HOME), 0.0, atol=1e-9)
    # 3 cm to the robot's left in the map frame (map +y) is 3 cm towards world -x
    shifted = exact + [0.0, 0.0, 0.03]
    np.testing.assert_allclose(localization_errors(shifted, traj, HOME), 0.03, atol=1e-9)
    s = localization_summary(localization_errors(np.vstack([exact, shifted]), traj, HOME))
    assert s["localization_samples"] == 6
    assert s["localization_error_mean_m"] == pytest.approx(0.015)
    assert s["localization_error_max_m"] == pytest.approx(0.03)
    assert s["localization_error_rmse_m"] == pytest.approx(math.sqrt(0.03 ** 2 / 2))


def test_estimates_outside_the_truth_span_and_nan_are_left_out():
    traj = _truth()
    est = np.array([[-1.0, 0.0, 0.0], [25.0, 0.0, 0.0], [5.0, float("nan"), 0.0], [5.0, 2.5, 0.1]])
    e = localization_errors(est, traj, HOME)
    np.testing.assert_allclose(e, [0.1], atol=1e-9)


def test_no_estimates_give_none_and_bad_trajectories_are_refused():
    assert localization_summary(localization_errors(np.zeros((0, 3)), _truth(), HOME))["localization_error_mean_m"] is None
    with pytest.raises(ValueError, match="trajectory"):
        localization_errors([[0.0, 0.0, 0.0]], np.zeros((5, 2)), HOME)
    with pytest.raises(ValueError, match="decrease"):
        localization_errors([[0.0, 0.0, 0.0]], _truth()[::-1], HOME)
