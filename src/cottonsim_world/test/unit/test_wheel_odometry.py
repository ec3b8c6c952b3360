"""WheelOdometry against closed-form straight lines and circular arcs."""
import math

import numpy as np
import pytest

from cottonsim_world.physics.wheel_odometry import WheelOdometry, WheelOdometryConfig

CFG = WheelOdometryConfig()
R = 0.1651
WS = 0.5708 * 1.875


def drive(odo, left, right, duration, dt=0.02):
    for _ in range(int(round(duration / dt))):
        assert odo.update([left, right, left, right], dt) is None
    return odo.estimate()


def test_straight_line():
    odo = WheelOdometry(CFG)
    est = drive(odo, 3.0, 3.0, 4.0)
    assert est.x_m == pytest.approx(3.0 * R * 4.0, rel=1e-9)
    assert est.y_m == pytest.approx(0.0, abs=1e-12)
    assert est.yaw_rad == pytest.approx(0.0, abs=1e-12)
    assert est.linear_x_m_s == pytest.approx(3.0 * R)


def test_arc_matches_circle():
    odo = WheelOdometry(CFG)
    left, right = 2.0, 4.0
    v = 0.5 * (left + right) * R
    w = (right - left) * R / WS
    t = 3.0
    est = drive(odo, left, right, t)
    radius = v / w
    assert est.x_m == pytest.approx(radius * math.sin(w * t), abs=1e-9)
    assert est.y_m == pytest.approx(radius * (1.0 - math.cos(w * t)), abs=1e-9)
    assert est.yaw_rad == pytest.approx(w * t, abs=1e-12)
    assert est.angular_z_rad_s == pytest.approx(w)


def test_spin_in_place_uses_effective_track():
    odo = WheelOdometry(CFG)
    est = drive(odo, -2.0, 2.0, 0.5)
    assert est.yaw_rad == pytest.approx(4.0 * R / WS * 0.5)
    assert abs(est.x_m) < 1e-12 and abs(est.y_m) < 1e-12


def test_covariance_as_husky_publishes():
    est = WheelOdometry(CFG).estimate()
    assert np.allclose(np.diag(est.pose_covariance), [0.001] * 5 + [0.03])
    assert np.allclose(np.diag(est.twist_covariance), [0.001] * 5 + [0.03])


def test_nan_and_bad_shapes_are_refused():
    odo = WheelOdometry(CFG)
    drive(odo, 1.0, 1.0, 1.0)
    before = odo.estimate()
    assert "NaN" in odo.update([1.0, math.nan, 1.0, 1.0], 0.02)
    assert "4 wheel velocities" in odo.update([1.0, 1.0], 0.02)
    assert "dt_s" in odo.update([1.0] * 4, -0.1)
    after = odo.estimate()
    assert after.x_m == before.x_m and len(odo.rejections) == 3


def test_config_validation():
    with pytest.raises(ValueError, match="track_m"):
        WheelOdometryConfig(track_m=-0.5)
