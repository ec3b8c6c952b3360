"""The mapper's IMU heading filter: the fused heading follows an absolute yaw, not the gyro's drift."""
import math

import numpy as np
import pytest

from cottonsim_navigation.localization.sensor_models import simulate_scan
from cottonsim_navigation.mapping.heading_fusion import HeadingFuser
from cottonsim_navigation.mapping.scan_matcher import ScanMatcherConfig
from cottonsim_navigation.mapping.slam import RbpfSlam, SlamConfig
from nav_synthetic_maps import field_map


def _drive(fuser, seconds, rng, drift_rad_s=0.0002, imu_sd_rad=0.005, imu_bias_rad=0.0, still_s=3.0):
    """Robot stands still_s, then drives a circle-ish path; odometry yaw drifts linearly, the IMU is the true
    yaw + a constant bias + white noise (an unknown start offset of 1.0 rad: any reference)."""
    true = np.zeros(3)
    odom = np.zeros(3)
    out = []
    dt = 0.1
    for k in range(int(seconds / dt)):
        t = k * dt
        if t >= still_s:
            w = 0.3 * math.sin(0.05 * t)
            true = true + [0.05 * math.cos(true[2]), 0.05 * math.sin(true[2]), w * dt]
            odom_yaw = odom[2] + w * dt + drift_rad_s * dt
            odom = odom + [0.05 * math.cos(odom[2]), 0.05 * math.sin(odom[2]), 0.0]
            odom[2] = odom_yaw
        imu = 1.0 + true[2] + imu_bias_rad + rng.normal(0.0, imu_sd_rad)
        out.append((true.copy(), odom.copy(), fuser.update(odom, imu, t)))
    return out


def test_fused_heading_follows_the_imu_not_the_drift():
    rng = np.random.default_rng(1)
    track = _drive(HeadingFuser(tau_s=10.0), 300.0, rng)
    true, odom, fused = (np.array(a) for a in zip(*track))
    odom_err = np.abs(np.remainder(odom[:, 2] - true[:, 2] + math.pi, 2 * math.pi) - math.pi)
    fused_err = np.abs(np.remainder(fused[:, 2] - true[:, 2] + math.pi, 2 * math.pi) - math.pi)
    assert odom_err[-1] > 0.05                       # 0.06 rad of gyro drift after 300 s ...
    assert fused_err.max() < 0.01                   # ... the fused heading stays within the IMU's noise
    assert fused_err[-1000:].mean() < 0.004         # averaged: better than one IMU sample (0.005)
    # the fused position integrates the same displacements turned by the correction: closer to the truth
    assert np.hypot(*(fused[-1, :2] - true[-1, :2])) < 0.3 * np.hypot(*(odom[-1, :2] - true[-1, :2]))


def test_standing_start_defines_the_reference_and_a_bias_is_a_constant_rotation():
    rng = np.random.default_rng(2)
    fuser = HeadingFuser(tau_s=10.0)
    track = _drive(fuser, 60.0, rng, drift_rad_s=0.0, imu_bias_rad=0.0)
    true, odom, fused = (np.array(a) for a in zip(*track))
    # 30 samples at rest average the IMU's white noise: the start heading is known to ~0.005 / sqrt(30)
    assert abs(fused[35, 2] - true[35, 2]) < 0.004
    np.testing.assert_allclose(fused[:30], odom[:30], atol=1e-12)     # standing: the odometry pose unchanged


def test_without_imu_samples_the_odometry_passes_through():
    fuser = HeadingFuser()
    for k in range(20):
        pose = np.array([0.1 * k, 0.01 * k, 0.02 * k])
        np.testing.assert_allclose(fuser.update(pose, None, 0.1 * k), pose, atol=1e-12)


@pytest.mark.parametrize("args", [((0, 0, float("nan")), 0.0, 0.0), ((0, 0), 0.0, 0.0),
                                  ((0, 0, 0), float("inf"), 0.0), ((0, 0, 0), 0.0, float("nan"))])
def test_bad_input_is_refused(args):
    with pytest.raises(ValueError):
        HeadingFuser().update(*args)


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="tau_s"):
        HeadingFuser(tau_s=0.0)
    with pytest.raises(ValueError, match="heading_tau_s"):
        SlamConfig(heading_tau_s=-1.0)
    with pytest.raises(ValueError, match="heading_sigma_rad"):
        SlamConfig(heading_sigma_rad=float("nan"))


def test_slam_with_imu_keeps_the_heading_of_a_drifting_odometry():
    """A drive along a lane whose odometry yaw drifts 0.004 rad/m: with the IMU yaw the SLAM heading stays true."""
    spec, occ = field_map()
    start = np.array([0.0, -0.5, math.pi / 2])
    rng = np.random.default_rng(3)
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    c, s = math.cos(start[2]), math.sin(start[2])
    results = {}
    for use_imu in (False, True):
        # this odometry drifts ~20x faster than the simulator's gyro: a 1 s filter time constant follows it
        slam = RbpfSlam(SlamConfig(particles=5, xmin_m=-10, ymin_m=-10, xmax_m=25, ymax_m=10, heading_tau_s=1.0,
                                   matcher=ScanMatcherConfig(prior_sigma_yaw_rad=0.005)),
                        rng=np.random.default_rng(4))
        true_o = np.zeros(3)
        odom = np.zeros(3)
        for k in range(150):
            if k >= 10:
                true_o = true_o + [0.1, 0.0, 0.0]
                odom = odom + [0.1 * math.cos(odom[2]), 0.1 * math.sin(odom[2]), 0.0004]
            world = (start[0] + c * true_o[0] - s * true_o[1], start[1] + s * true_o[0] + c * true_o[1], start[2])
            scan = simulate_scan(occ, spec, world, angles, range_max_m=20.0, noise_sd_m=0.01, rng=rng)
            imu = 0.3 + true_o[2] + rng.normal(0.0, 0.003) if use_imu else None
            res = slam.update(odom, scan, 0.1 * k, imu)
        results[use_imu] = abs(res.pose.yaw_rad)
    assert results[True] < 0.02                      # within a few particle-noise sigmas (0.005)
    assert results[True] < 0.5 * results[False]


def test_a_steady_drift_is_followed_without_the_low_pass_lag():
    """Gyro drift 0.0015 rad/s (~0.08 deg/s, the EKF odometry's drift on the mapping drive): the first-order
    low-pass lags it by drift * tau; the rate-tracking loop follows it to within the IMU's averaged noise."""
    errors = {}
    for track in (False, True):
        rng = np.random.default_rng(5)
        fuser = HeadingFuser(tau_s=5.0, track_rate=track)
        true, odom, fused = (np.array(a) for a in zip(*_drive(fuser, 300.0, rng, drift_rad_s=0.0015)))
        err = np.remainder(fused[:, 2] - true[:, 2] + math.pi, 2 * math.pi) - math.pi
        errors[track] = np.abs(err[-1000:]).mean()          # the last 100 s, after the loop settled
        if track:
            assert fuser.drift_rate_rad_s == pytest.approx(-0.0015, abs=3e-4)   # IMU - odometry falls
    assert errors[False] == pytest.approx(0.0015 * 5.0, rel=0.3)                 # the lag drift * tau
    assert errors[True] < 0.002
    assert errors[True] < 0.25 * errors[False]


def test_track_rate_must_be_a_bool():
    with pytest.raises(ValueError, match="track_rate"):
        HeadingFuser(track_rate="yes")
    with pytest.raises(ValueError, match="heading_track_rate"):
        SlamConfig(heading_track_rate=1)
