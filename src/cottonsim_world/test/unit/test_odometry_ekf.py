"""OdometryEkf: converges on a noisy synthetic circle, refuses NaN."""
import math

import numpy as np
import pytest

from cottonsim_world.estimation.odometry_ekf import OdometryEkf, OdometryEkfConfig


def truth_circle(v, w, t):
    r = v / w
    return r * math.sin(w * t), r * (1 - math.cos(w * t)), w * t


def run_circle(ekf, seed, duration=20.0, dt=0.02, v=0.5, w=0.2, history=None):
    rng = np.random.default_rng(seed)
    for _ in range(int(round(duration / dt))):
        assert ekf.predict(dt) is None
        assert ekf.update_wheel_odometry(v + 0.03 * rng.standard_normal(), w + 0.03 * rng.standard_normal(),
                                         (0.03 ** 2, 0.03 ** 2)) is None
        assert ekf.update_imu(w + 0.01 * rng.standard_normal(), 0.01 ** 2) is None
        if history is not None:
            history.append(ekf.state.copy())
    return ekf.output()


def test_converges_to_truth_on_circle():
    ekf = OdometryEkf()
    history = []
    out = run_circle(ekf, seed=0, history=history)
    tx, ty, tyaw = truth_circle(0.5, 0.2, 20.0)
    assert math.hypot(out.x_m - tx, out.y_m - ty) < 0.1        # 10 m of path
    assert abs((out.yaw_rad - tyaw + math.pi) % (2 * math.pi) - math.pi) < 0.02
    # after the start-up second, the filtered speeds are closer to the truth
    # than the raw measurements (odometry noise 0.03, IMU rate noise 0.01)
    late = np.array(history[50:])
    assert np.sqrt(np.mean((late[:, 3] - 0.5) ** 2)) < 0.03
    assert np.sqrt(np.mean((late[:, 4] - 0.2) ** 2)) < 0.01
    # fusing the more precise IMU rate shrinks the yaw-rate variance below the odometry's
    assert out.twist_covariance[5, 5] < 0.01 ** 2
    assert out.pose_covariance[0, 0] > 0 and np.allclose(out.pose_covariance, out.pose_covariance.T)


def test_imu_yaw_removes_heading_error():
    ekf = OdometryEkf()
    ekf.reset(yaw_rad=0.5)                  # wrong start heading
    for _ in range(200):
        ekf.predict(0.02)
        ekf.update_imu(0.0, 1e-4, yaw=0.0, yaw_cov=1e-4)
    assert abs(ekf.output().yaw_rad) < 0.01


def test_yaw_innovation_wraps_at_pi():
    ekf = OdometryEkf()
    ekf.reset(yaw_rad=math.pi - 0.05)
    ekf.update_imu(0.0, 1e-4, yaw=-math.pi + 0.05, yaw_cov=1e-12)
    # nearest way round is +0.1 rad through pi, not -6.18 rad
    assert abs(abs(ekf.output().yaw_rad) - math.pi) < 0.06


def test_nan_inputs_are_refused_and_state_unchanged():
    ekf = OdometryEkf()
    run_circle(ekf, seed=1, duration=1.0)
    state, cov = ekf.state.copy(), ekf.covariance.copy()
    assert "NaN" in ekf.update_wheel_odometry(math.nan, 0.0, (1e-3, 1e-3))
    assert "NaN" in ekf.update_imu(math.inf, 1e-3)
    assert "NaN" in ekf.update_imu(0.0, 1e-3, yaw=math.nan, yaw_cov=1e-3)
    assert "variance" in ekf.update_imu(0.0, math.nan)
    assert "dt_s" in ekf.predict(math.nan)
    assert "dt_s" in ekf.predict(-1.0)
    assert np.array_equal(ekf.state, state) and np.array_equal(ekf.covariance, cov)
    assert len(ekf.rejections) == 6


def test_accepts_ros_6x6_twist_covariance():
    ekf = OdometryEkf()
    cov = np.diag([0.001] * 5 + [0.03])
    for _ in range(100):
        ekf.predict(0.02)
        assert ekf.update_wheel_odometry(0.3, 0.0, cov) is None
    assert ekf.state[3] == pytest.approx(0.3, abs=0.01)


def test_transform_output():
    ekf = OdometryEkf()
    ekf.reset(1.0, 2.0, math.pi / 2)
    trans, rot = ekf.output().transform_odom_to_base_link()
    assert trans == (1.0, 2.0, 0.0)
    assert rot[2] == pytest.approx(math.sin(math.pi / 4)) and rot[3] == pytest.approx(math.cos(math.pi / 4))


def test_config_validation():
    with pytest.raises(ValueError, match="process_noise_diag"):
        OdometryEkfConfig(process_noise_diag=(0.1, 0.1, 0.1, 0.1))
