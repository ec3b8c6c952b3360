"""GPS/IMU complementary filter for map -> odom, and the IMU-mount yaw conversion."""
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cottonsim_navigation.core.geometry import Pose2D, compose, inverse, normalize_angle
from cottonsim_navigation.localization.gps_localization import (GpsLocalizationConfig, GpsLocalizer, enu_yaw,
                                                                robot_yaw_from_imu)

# the IMU mount of the URDF / paper Table 1: rpy (0, -90, 180) deg
MOUNT = Rotation.from_euler("xyz", [0.0, -math.pi / 2, math.pi])


@pytest.mark.parametrize("yaw", [0.0, 0.3, math.pi / 2, -2.5, 3.1])
def test_robot_yaw_through_a_rotated_imu_mount(yaw):
    world_base = Rotation.from_euler("xyz", [0.02, -0.01, yaw])
    world_imu = world_base * MOUNT
    # the IMU's own yaw is meaningless for this mount ...
    got = robot_yaw_from_imu(world_imu.as_quat(), MOUNT.as_quat())
    assert got == pytest.approx(yaw, abs=1e-3)
    # ... and an IMU mounted straight reports the robot's yaw directly
    assert robot_yaw_from_imu(world_base.as_quat()) == pytest.approx(yaw, abs=1e-3)


def test_robot_yaw_refuses_bad_quaternions():
    with pytest.raises(ValueError, match="q_world_imu"):
        robot_yaw_from_imu((0.0, 0.0, float("nan"), 1.0))
    with pytest.raises(ValueError, match="q_base_imu"):
        robot_yaw_from_imu((0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 0.0))


def test_enu_yaw_with_the_originals_offset():
    # the sim's IMU reads 0 facing north (world +x): ENU heading pi/2; facing west (spawn): pi
    assert enu_yaw(0.0, 1.570796327) == pytest.approx(math.pi / 2)
    assert abs(enu_yaw(math.pi / 2, 1.570796327)) == pytest.approx(math.pi)
    assert enu_yaw(0.1, 0.0, 0.05) == pytest.approx(0.15)


def test_nothing_before_the_first_fix_and_a_fix_needs_a_heading():
    f = GpsLocalizer()
    assert not f.ready and f.map_to_odom is None and f.map_pose(Pose2D(0, 0, 0)) is None
    assert f.update_gps(0.0, Pose2D(0, 0, 0), 1.0, 2.0) is False
    assert not f.ready
    f.update_heading(0.0, Pose2D(0, 0, 0), math.pi)
    assert f.update_gps(0.1, Pose2D(0, 0, 0), 1.0, 2.0) is True
    pose = f.map_pose(Pose2D(0, 0, 0))
    assert (pose.x_m, pose.y_m) == pytest.approx((1.0, 2.0)) and abs(pose.yaw_rad) == pytest.approx(math.pi)


def test_first_fix_uses_odometry_turn_since_the_heading():
    f = GpsLocalizer()
    f.update_heading(0.0, Pose2D(0, 0, 0.0), 1.0)              # heading 1.0 when odom yaw was 0
    f.update_gps(0.5, Pose2D(0.3, 0.1, 0.2), 4.0, -1.0)        # robot turned 0.2 since
    pose = f.map_pose(Pose2D(0.3, 0.1, 0.2))
    assert (pose.x_m, pose.y_m, pose.yaw_rad) == pytest.approx((4.0, -1.0, 1.2))


def test_one_correction_moves_by_the_hand_computed_weight():
    cfg = GpsLocalizationConfig(position_time_constant_s=0.5, yaw_time_constant_s=2.0)
    f = GpsLocalizer(cfg)
    odom = Pose2D(0.0, 0.0, 0.0)
    f.update_heading(0.0, odom, 0.0)
    f.update_gps(0.0, odom, 0.0, 0.0)
    f.update_gps(0.1, odom, 1.0, -2.0)                          # 0.1 s later, 1 m / -2 m off
    a = 1.0 - math.exp(-0.1 / 0.5)
    pose = f.map_pose(odom)
    assert (pose.x_m, pose.y_m) == pytest.approx((a * 1.0, -2.0 * a))
    f.update_heading(1.0, odom, 0.4)                           # 1 s after the last heading
    b = 1.0 - math.exp(-1.0 / 2.0)
    pose2 = f.map_pose(odom)
    assert pose2.yaw_rad == pytest.approx(0.4 * b)
    assert (pose2.x_m, pose2.y_m) == pytest.approx((pose.x_m, pose.y_m))   # turned about the robot


def test_zero_time_constants_follow_each_measurement():
    f = GpsLocalizer(GpsLocalizationConfig(position_time_constant_s=0.0, yaw_time_constant_s=0.0))
    odom = Pose2D(2.0, 1.0, 0.5)
    f.update_heading(0.0, odom, -1.0)
    f.update_gps(0.0, odom, 10.0, 20.0)
    f.update_gps(0.05, odom, 11.0, 19.0)
    f.update_heading(0.06, odom, -0.8)
    pose = f.map_pose(odom)
    assert (pose.x_m, pose.y_m, pose.yaw_rad) == pytest.approx((11.0, 19.0, -0.8))


def test_tracks_a_drive_with_drifting_odometry():
    """Truth drives a curve in the map; odometry drifts (scale and heading bias); GPS and IMU are noisy."""
    rng = np.random.default_rng(7)
    f = GpsLocalizer()
    start = Pose2D(3.0, -2.0, math.pi)                          # map pose of the robot at t = 0
    truth = start
    odom = Pose2D(0.0, 0.0, 0.0)
    dt = 0.025
    errors = []
    for k in range(1600):                                      # 40 s at 0.5 m/s: 20 m
        t = k * dt
        w = 0.15 * math.sin(0.2 * t)
        step = Pose2D(0.5 * dt, 0.0, w * dt)
        truth = compose(truth, step)
        odom = compose(odom, Pose2D(0.5 * dt * 1.03, 0.0, w * dt + 0.002 * dt))   # 3 % scale, yaw bias
        f.update_heading(t, odom, float(normalize_angle(truth.yaw_rad + rng.normal(0, 0.005))))
        f.update_gps(t, odom, truth.x_m + rng.normal(0, 0.01), truth.y_m + rng.normal(0, 0.01))
        est = f.map_pose(odom)
        errors.append((math.hypot(est.x_m - truth.x_m, est.y_m - truth.y_m),
                       abs(normalize_angle(est.yaw_rad - truth.yaw_rad))))
    errors = np.array(errors)
    # dead reckoning alone would be ~0.6 m off after 20 m at 3 % scale error
    assert errors[:, 0].max() < 0.05
    assert errors[:, 1].max() < 0.03
    # the correction is real: without it the odometry ends far away
    dead = compose(compose(start, inverse(Pose2D(0, 0, 0))), odom)
    assert math.hypot(dead.x_m - truth.x_m, dead.y_m - truth.y_m) > 0.3


def test_bad_inputs_and_config():
    f = GpsLocalizer()
    with pytest.raises(ValueError, match="map_yaw_rad"):
        f.update_heading(0.0, Pose2D(0, 0, 0), float("nan"))
    with pytest.raises(ValueError, match="x_m"):
        f.update_gps(0.0, Pose2D(0, 0, 0), float("inf"), 0.0)
    with pytest.raises(ValueError, match="stamp_s"):
        f.update_gps(float("nan"), Pose2D(0, 0, 0), 0.0, 0.0)
    with pytest.raises(ValueError, match="odom_pose"):
        f.update_gps(0.0, (0, 0, 0), 0.0, 0.0)
    for kwargs, named in (({"position_time_constant_s": -1.0}, "position_time_constant_s"),
                          ({"frequency": 0.0}, "frequency"), ({"yaw_offset": float("nan")}, "yaw_offset"),
                          ({"max_dt_s": "1"}, "max_dt_s")):
        with pytest.raises(ValueError, match=named):
            GpsLocalizationConfig(**kwargs)
