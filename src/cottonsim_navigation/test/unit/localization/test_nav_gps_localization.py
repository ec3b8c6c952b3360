"""GPS/IMU complementary filter for map -> odom, and the IMU-mount yaw conversion."""
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cottonsim_common.angles import wrap_angle
from cottonsim_common.pose import Pose2D, compose, inverse
from cottonsim_navigation.localization.gps_localization import (REJECTED_JUMP, REJECTED_VARIANCE,
                                                                STATE_DEAD_RECKONING, STATE_GPS, STATE_GPS_LOST,
                                                                STATE_WAITING, GpsLocalizationConfig, GpsLocalizer,
                                                                enu_yaw, robot_yaw_from_imu)

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
    # a wide jump gate: the 2.2 m correction is meant, not multipath
    cfg = GpsLocalizationConfig(position_time_constant_s=0.5, yaw_time_constant_s=2.0, jump_gate_m=5.0)
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
    # a wide jump gate: the 1.4 m step between the two fixes is meant, not multipath
    f = GpsLocalizer(GpsLocalizationConfig(position_time_constant_s=0.0, yaw_time_constant_s=0.0, jump_gate_m=5.0))
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
        f.update_heading(t, odom, float(wrap_angle(truth.yaw_rad + rng.normal(0, 0.005))))
        f.update_gps(t, odom, truth.x_m + rng.normal(0, 0.01), truth.y_m + rng.normal(0, 0.01))
        est = f.map_pose(odom)
        errors.append((math.hypot(est.x_m - truth.x_m, est.y_m - truth.y_m),
                       abs(wrap_angle(est.yaw_rad - truth.yaw_rad))))
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
                          ({"max_dt_s": "1"}, "max_dt_s"), ({"max_fix_variance_m2": 0.0}, "max_fix_variance_m2"),
                          ({"dead_reckoning_limit_s": -1.0}, "dead_reckoning_limit_s"),
                          ({"jump_gate_timeout_s": -1.0}, "jump_gate_timeout_s"),
                          ({"reference_fix_variance_m2": 1.0}, "max_fix_variance_m2")):
        with pytest.raises(ValueError, match=named):
            GpsLocalizationConfig(**kwargs)


# ---------------------------------------------------------------------------- degraded and lost fixes
def started(config=GpsLocalizationConfig()):
    f = GpsLocalizer(config)
    f.update_heading(0.0, Pose2D(0, 0, 0), 0.0)
    assert f.update_gps(0.0, Pose2D(0, 0, 0), 0.0, 0.0)
    return f


def test_a_fix_above_the_variance_gate_is_refused_and_counted():
    f = started()
    assert f.update_gps(0.1, Pose2D(0, 0, 0), 0.4, 0.0, variance_m2=6.25) is False     # a single-point fix
    assert f.last_rejection == REJECTED_VARIANCE and f.rejected[REJECTED_VARIANCE] == 1
    assert f.map_pose(Pose2D(0, 0, 0)).x_m == 0.0
    assert f.update_gps(0.2, Pose2D(0, 0, 0), 0.4, 0.0, variance_m2=0.25) is True      # at the gate: used
    with pytest.raises(ValueError, match="variance_m2"):
        f.update_gps(0.3, Pose2D(0, 0, 0), 0.4, 0.0, variance_m2=-1.0)
    with pytest.raises(ValueError, match="variance_m2"):
        f.update_gps(0.3, Pose2D(0, 0, 0), 0.4, 0.0, variance_m2=float("nan"))


@pytest.mark.parametrize("variance, scale", [(0.0, 1.0), (1e-8, 1.0), (0.0025, 1.0), (0.09, 36.0)])
def test_a_noisier_fix_corrects_with_a_proportionally_longer_time_constant(variance, scale):
    f = started()
    f.update_gps(0.1, Pose2D(0, 0, 0), 0.5, 0.0, variance_m2=variance)
    expected = 0.5 * (1.0 - math.exp(-0.1 / (0.5 * scale)))
    assert f.map_pose(Pose2D(0, 0, 0)).x_m == pytest.approx(expected, rel=1e-12)


def test_a_jump_is_refused_until_no_fix_was_used_for_the_gate_time_out():
    f = started(GpsLocalizationConfig(jump_gate_timeout_s=5.0))
    odom = Pose2D(0, 0, 0)
    for k in range(1, 200):                                    # 3 m multipath jump for 5 s at 40 Hz
        t = 0.025 * k
        used = f.update_gps(t, odom, 3.0, 0.0)
        assert used is False and f.last_rejection == REJECTED_JUMP, t
    assert f.map_pose(odom).x_m == 0.0
    assert f.state(4.9) == STATE_DEAD_RECKONING
    # a good fix within the gate is used again at once
    assert f.update_gps(4.95, odom, 0.2, 0.0) is True
    # a jump that lasts beyond the time-out wins: the estimate may be the one that is off
    for k in range(1, 201):
        f.update_gps(4.95 + 0.025 * k, odom, 3.0, 0.0)
    assert f.update_gps(10.0, odom, 3.0, 0.0) is True
    assert f.map_pose(odom).x_m > 2.0


def test_states_and_localized_through_an_outage():
    f = GpsLocalizer(GpsLocalizationConfig(dead_reckoning_limit_s=20.0))
    assert f.state(0.0) == STATE_WAITING and f.localized(0.0) and f.seconds_since_fix(0.0) == math.inf
    f.update_heading(0.0, Pose2D(0, 0, 0), 0.0)
    f.update_gps(1.0, Pose2D(0, 0, 0), 0.0, 0.0)
    assert f.state(1.5) == STATE_GPS and f.localized(1.5)
    assert f.state(3.0) == STATE_DEAD_RECKONING and f.localized(3.0)
    assert f.seconds_since_fix(15.0) == pytest.approx(14.0)
    assert f.state(21.0) == STATE_DEAD_RECKONING and f.state(21.1) == STATE_GPS_LOST and not f.localized(21.1)
    # refused fixes do not count as fixes
    f.update_gps(30.0, Pose2D(0, 0, 0), 0.0, 0.0, variance_m2=4.0)
    assert f.state(30.0) == STATE_GPS_LOST
    assert f.update_gps(40.0, Pose2D(0, 0, 0), 0.1, 0.0)
    assert f.state(40.0) == STATE_GPS and f.localized(40.0)


def test_a_15_s_outage_in_a_lane_is_bridged_by_the_odometry_and_the_fix_takes_over_after():
    """Straight lane at 0.5 m/s with a 1 % odometry scale error: no GPS for 15 s; the map pose drifts only by
    the odometry's error (7.5 m x 1 % = 7.5 cm), the gap exceeds no gate, and the first fixes after it pull
    the pose back."""
    f = GpsLocalizer()
    dt, truth_x, odom_x = 0.025, 0.0, 0.0
    f.update_heading(0.0, Pose2D(0, 0, 0), 0.0)
    errors = {}
    for k in range(2400):                                      # 60 s
        t = k * dt
        truth_x += 0.5 * dt
        odom_x += 0.5 * dt * 1.01
        odom = Pose2D(odom_x, 0.0, 0.0)
        f.update_heading(t, odom, 0.0)
        if not 20.0 <= t < 35.0:
            f.update_gps(t, odom, truth_x, 0.0, variance_m2=1e-8)
        errors[round(t, 3)] = abs(f.map_pose(odom).x_m - truth_x)
        assert f.localized(t)
        if 21.0 < t < 35.0:
            assert f.state(t) == STATE_DEAD_RECKONING
    assert errors[34.975] == pytest.approx(0.075, abs=0.01)
    assert errors[37.0] < 0.01
    assert f.rejected == {REJECTED_VARIANCE: 0, REJECTED_JUMP: 0}


def test_the_shipped_config_file_lists_every_key_with_its_default():
    import dataclasses
    import pathlib
    from cottonsim_common.config.yaml_files import load_yaml_file
    path = pathlib.Path(__file__).resolve().parents[3] / "config" / "gps_localization.yaml"
    values = load_yaml_file(path)["gps_localization"]
    fields = {f.name for f in dataclasses.fields(GpsLocalizationConfig)} - {"yaw_offset", "magnetic_declination_radians"}
    assert set(values) == fields
    assert GpsLocalizationConfig(**values) == GpsLocalizationConfig()
