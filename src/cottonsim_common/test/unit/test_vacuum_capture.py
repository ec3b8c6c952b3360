"""The vacuum nozzle's capture rule."""
import math

import numpy as np
import pytest

from cottonsim_common.kinematics.ur5e import forward_kinematics
from cottonsim_common.testing import assert_config_rejects
from cottonsim_common.vacuum_capture import CaptureConfig, check_capture, find_capture, nozzle_tip

BOLL = np.array([0.6, 0.1, 0.2])
OUTWARD = np.array([-1.0, 0.0, 0.0])      # the nozzle must point along +x


def turned(angle_rad):
    """The inward direction +x turned by angle_rad about z."""
    return np.array([math.cos(angle_rad), math.sin(angle_rad), 0.0])


def test_capture_radius_and_cone():
    cfg = CaptureConfig(capture_radius_m=0.02, cone_half_angle_rad=math.radians(45))
    assert check_capture(BOLL, [1, 0, 0], BOLL, OUTWARD, cfg).captured
    inside = check_capture(BOLL + [0, 0.019, 0], [1, 0, 0], BOLL, OUTWARD, cfg)
    assert inside.captured and inside.distance_m == pytest.approx(0.019)
    far = check_capture(BOLL + [0, 0.021, 0], [1, 0, 0], BOLL, OUTWARD, cfg)
    assert not far.captured and far.reason == "too_far"
    ok = check_capture(BOLL, turned(math.radians(40)), BOLL, OUTWARD, cfg)
    assert ok.captured and ok.angle_rad == pytest.approx(math.radians(40))
    skew = check_capture(BOLL, turned(math.radians(50)), BOLL, OUTWARD, cfg)
    assert not skew.captured and skew.reason == "misaligned"
    backwards = check_capture(BOLL, [-1, 0, 0], BOLL, OUTWARD, cfg)
    assert backwards.reason == "misaligned" and backwards.angle_rad == pytest.approx(math.pi)
    # The axis need not be unit length; a boll on the stem axis accepts any direction.
    assert check_capture(BOLL, [5, 0, 0], BOLL, OUTWARD, cfg).captured
    assert check_capture(BOLL, [-1, 0, 0], BOLL, [0, 0, 0], cfg).captured


def test_find_capture_takes_the_nearest_qualifying_boll():
    centres = np.array([BOLL + [0.015, 0, 0], BOLL + [0.005, 0, 0], BOLL + [0.0, 0.03, 0], BOLL + [0.001, 0, 0]])
    outwards = np.array([OUTWARD, OUTWARD, OUTWARD, [1.0, 0, 0]])   # the last faces the other way
    assert find_capture(BOLL, [1, 0, 0], centres, outwards) == 1
    assert find_capture(BOLL + [0, 0.03, 0], [1, 0, 0], centres, outwards) == 2
    assert find_capture(BOLL + [0, 0, 0.1], [1, 0, 0], centres, outwards) == -1
    assert find_capture(BOLL, [1, 0, 0], np.zeros((0, 3)), np.zeros((0, 3))) == -1


def test_nozzle_tip_on_the_flange():
    q = np.array([0.3, -1.2, 1.1, -1.4, -1.5, 0.2])
    pose = forward_kinematics(q)
    tip, axis = nozzle_tip(pose, 0.15)
    np.testing.assert_allclose(tip, pose[:3, 3] + 0.15 * pose[:3, 2])
    np.testing.assert_allclose(axis, pose[:3, 2])


def test_bad_input():
    assert_config_rejects(CaptureConfig, ("capture_radius_m", 0.0), ("cone_half_angle_rad", 4.0))
    with pytest.raises(ValueError, match="nozzle tip"):
        check_capture([np.nan, 0, 0], [1, 0, 0], BOLL, OUTWARD)
    with pytest.raises(ValueError, match="axis must not be zero"):
        check_capture(BOLL, [0, 0, 0], BOLL, OUTWARD)
    with pytest.raises(ValueError, match="differ in number"):
        find_capture(BOLL, [1, 0, 0], np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="nozzle_length_m"):
        nozzle_tip(np.eye(4), -0.1)
