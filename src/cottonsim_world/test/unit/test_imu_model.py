"""ImuModel: exact without noise, noise statistics, drift, determinism, NaN refusal."""
import math

import numpy as np
import pytest

from cottonsim_world.physics.imu_model import ImuConfig, ImuModel, quat_to_rpy, rpy_to_quat

Q_YAW = rpy_to_quat(0.0, 0.0, 0.7)


def test_rpy_round_trip():
    for rpy in ([0.1, -0.2, 3.0], [0.0, 0.0, -1.2], [-0.4, 0.3, 0.0]):
        assert np.allclose(quat_to_rpy(rpy_to_quat(*rpy)), rpy)


def test_noise_free_model_is_exact():
    cfg = ImuConfig(gyro_noise_rad_s=0, gyro_drift_rad_s=0, accel_noise_m_s2=0, accel_drift_m_s2=0,
                    orientation_noise_rad=0, yaw_drift_rad=0)
    imu = ImuModel(cfg)
    m = imu.measure(0.0, Q_YAW, [0.0, 0.0, 0.3], [0.0, 0.0, 9.8])
    assert np.allclose(m.angular_velocity_rad_s, [0, 0, 0.3])
    assert np.allclose(m.linear_acceleration_m_s2, [0, 0, 9.8])
    assert quat_to_rpy(m.orientation_xyzw)[2] == pytest.approx(0.7)


def test_noise_statistics_match_config():
    imu = ImuModel(ImuConfig(seed=3))
    gyro = np.array([imu.measure(0.02 * k, Q_YAW, [0, 0, 0], [0, 0, 9.8]).angular_velocity_rad_s
                     for k in range(3000)])
    # white noise 0.005 around a bias that hardly moves in 60 s (drift time 3600 s)
    resid = gyro - gyro.mean(axis=0)
    assert np.std(resid[:, 2]) == pytest.approx(0.005, rel=0.1)


def test_bias_drifts_with_short_correlation_time():
    imu = ImuModel(ImuConfig(seed=1, drift_time_s=1.0, gyro_noise_rad_s=0.0, gyro_drift_rad_s=0.05))
    biases = []
    for k in range(2000):
        imu.measure(0.01 * k, Q_YAW, [0, 0, 0], [0, 0, 9.8])
        biases.append(imu.biases["gyro_rad_s"][0])
    biases = np.array(biases)
    assert biases[0] == 0.0 or abs(biases[0]) < 0.01          # starts near zero
    assert np.std(biases[500:]) == pytest.approx(0.05, rel=0.4)  # stationary std = drift


def test_deterministic_per_seed():
    a, b, c = ImuModel(ImuConfig(seed=5)), ImuModel(ImuConfig(seed=5)), ImuModel(ImuConfig(seed=6))
    ma = [a.measure(0.02 * k, Q_YAW, [0, 0, 0.1], [0.1, 0, 9.8]) for k in range(10)]
    mb = [b.measure(0.02 * k, Q_YAW, [0, 0, 0.1], [0.1, 0, 9.8]) for k in range(10)]
    mc = [c.measure(0.02 * k, Q_YAW, [0, 0, 0.1], [0.1, 0, 9.8]) for k in range(10)]
    assert all(np.array_equal(x.angular_velocity_rad_s, y.angular_velocity_rad_s) for x, y in zip(ma, mb))
    assert not np.array_equal(ma[-1].angular_velocity_rad_s, mc[-1].angular_velocity_rad_s)


def test_nan_inputs_raise_and_do_not_advance_state():
    imu = ImuModel(ImuConfig(seed=2))
    imu.measure(0.0, Q_YAW, [0, 0, 0], [0, 0, 9.8])
    with pytest.raises(ValueError, match="angular_velocity_body_rad_s"):
        imu.measure(0.02, Q_YAW, [0, math.nan, 0], [0, 0, 9.8])
    with pytest.raises(ValueError, match="orientation_xyzw"):
        imu.measure(0.02, [0, 0, math.inf, 1], [0, 0, 0], [0, 0, 9.8])
    with pytest.raises(ValueError, match="stamp_s"):
        imu.measure(math.nan, Q_YAW, [0, 0, 0], [0, 0, 9.8])
    # the refused samples consumed no random numbers
    ref = ImuModel(ImuConfig(seed=2))
    ref.measure(0.0, Q_YAW, [0, 0, 0], [0, 0, 9.8])
    m1 = imu.measure(0.02, Q_YAW, [0, 0, 0], [0, 0, 9.8])
    m2 = ref.measure(0.02, Q_YAW, [0, 0, 0], [0, 0, 9.8])
    assert np.array_equal(m1.angular_velocity_rad_s, m2.angular_velocity_rad_s)
    assert np.all(np.isfinite(m1.linear_acceleration_m_s2))


def test_config_validation():
    with pytest.raises(ValueError, match="gyro_noise_rad_s"):
        ImuConfig(gyro_noise_rad_s=-1.0)
    with pytest.raises(ValueError, match="rate_hz"):
        ImuConfig(rate_hz=0.0)
