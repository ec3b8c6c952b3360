"""OdometryEkf: converges on a noisy synthetic circle, refuses NaN."""
import math

import numpy as np
import pytest

from cottonsim_world.estimation.odometry_ekf import OdometryEkf, OdometryEkfConfig, forward_acceleration


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


G = 9.8


def drive_then_pin(ekf, seed, pinned_after_s=3.0, duration_s=8.0, dt=0.02, v=0.5, pitch_rad=0.0):
    """Straight drive: wheels and IMU agree while the robot accelerates to v and cruises; at pinned_after_s
    a plant stops it within 0.1 s (IMU: -v/0.1 m/s^2) while the wheels keep reporting v. The IMU reads the
    specific force (gravity included) with the robot pitched by pitch_rad (nose down > 0). Returns the
    true distance driven and the EKF's x."""
    rng = np.random.default_rng(seed)
    q = (0.0, math.sin(pitch_rad / 2), 0.0, math.cos(pitch_rad / 2))
    true_v, true_x = 0.0, 0.0
    for k in range(int(round(duration_s / dt))):
        t = k * dt
        if t < pinned_after_s:
            a = min(1.0, (v - true_v) / dt)            # 1 m/s^2 up to v
        elif true_v > 0:
            a = -min(v / 0.1, true_v / dt)             # the plant stops it
        else:
            a = 0.0
        true_v += a * dt
        true_x += true_v * dt
        wheel_v = true_v if t < pinned_after_s else v  # pinned: the wheels spin on
        # specific force in body axes of a robot pitched nose down about y: the upward g leaks into -x
        f = (a - G * math.sin(pitch_rad) + 0.02 * rng.standard_normal(), 0.0, G * math.cos(pitch_rad))
        assert ekf.update_imu(0.01 * rng.standard_normal(), 0.01 ** 2, accel_body_m_s2=f, orientation_xyzw=q) is None
        assert ekf.predict(dt) is None
        assert ekf.update_wheel_odometry(wheel_v + 0.01 * rng.standard_normal(), 0.01 * rng.standard_normal(),
                                         (0.03 ** 2, 0.03 ** 2)) is None
    return true_x, float(ekf.state[0])


def test_forward_acceleration_removes_gravity():
    assert forward_acceleration((0.3, 0.0, G), None, G) == pytest.approx(0.3)
    # pitched 10 deg nose down (+y rotation): standing still, the specific force shows -g sin(10 deg) in x
    p = math.radians(10.0)
    q = (0.0, math.sin(p / 2), 0.0, math.cos(p / 2))
    assert forward_acceleration((-G * math.sin(p), 0.0, G * math.cos(p)), q, G) == pytest.approx(0.0, abs=1e-12)
    assert forward_acceleration((-G * math.sin(p) + 0.5, 0.0, G * math.cos(p)), q, G) == pytest.approx(0.5)
    with pytest.raises(ValueError, match="finite"):
        forward_acceleration((float("nan"), 0.0, G), None, G)
    with pytest.raises(ValueError, match="zero quaternion"):
        forward_acceleration((0.0, 0.0, G), (0.0, 0.0, 0.0, 0.0), G)


@pytest.mark.parametrize("pitch_deg", [0.0, 5.0])
def test_pinned_robot_stops_in_the_filter_although_the_wheels_spin(pitch_deg):
    pitch = math.radians(pitch_deg)
    ekf = OdometryEkf()
    true_x, x = drive_then_pin(ekf, seed=1, pitch_rad=pitch)
    blind = OdometryEkf(OdometryEkfConfig(slip_check=False))
    _, x_blind = drive_then_pin(blind, seed=1, pitch_rad=pitch)
    # 5 s pinned at 0.5 m/s: the wheels alone run 2.5 m away; the slip check keeps the error small
    assert x_blind - true_x > 2.0
    assert abs(x - true_x) < 0.2, (x, true_x)
    assert ekf.slipping and ekf.slip_events == 1
    assert abs(ekf.state[3]) < 0.1                        # the filter's forward speed: standing


def test_no_slip_no_change():
    # the same drive without the plant: never slipping, the same estimate as without the check
    ekf = OdometryEkf()
    true_x, x = drive_then_pin(ekf, seed=2, pinned_after_s=99.0)
    blind = OdometryEkf(OdometryEkfConfig(slip_check=False))
    _, x_blind = drive_then_pin(blind, seed=2, pinned_after_s=99.0)
    assert ekf.slip_events == 0 and not ekf.slipping
    assert x == pytest.approx(x_blind, abs=1e-9) and abs(x - true_x) < 0.1
    # a bad IMU sample is refused and does not feed the check
    assert "IMU rejected" in ekf.update_imu(0.0, 0.01, accel_body_m_s2=(0.0, float("inf"), G))


def test_slip_config_validation():
    for name, value in (("slip_speed_threshold_m_s", 0.0), ("slip_blend_time_s", float("nan")),
                        ("slip_speed_variance_m2_s2", -1.0), ("slip_yaw_rate_variance_scale", 0.5),
                        ("slip_check", "yes")):
        with pytest.raises(ValueError, match=name):
            OdometryEkfConfig(**{name: value})


def test_slip_ends_when_the_wheels_stop_and_the_imu_speed_cannot_run_away():
    # pinned for 10 s with a -0.1 m/s^2 accelerometer bias: integrated alone the IMU speed would reach
    # -1 m/s; then the wheels stop (the navigator cancelled its goal): the robot stands, and so must the
    # filter, the slip being over
    ekf = OdometryEkf()
    drive_then_pin(ekf, seed=4, duration_s=4.0)
    assert ekf.slipping
    dt = 0.02
    for _ in range(500):
        assert ekf.update_imu(0.0, 0.01 ** 2, accel_body_m_s2=(-0.1, 0.0, G)) is None
        ekf.predict(dt)
        ekf.update_wheel_odometry(0.5, 0.0, (0.03 ** 2, 0.03 ** 2))
    assert ekf.slipping and 0.0 <= ekf.imu_speed_m_s <= 0.5     # bounded by the wheels, never backwards
    x = ekf.state[0]
    for _ in range(250):                                   # 5 s, wheels stopped, the bias still there
        ekf.update_imu(0.0, 0.01 ** 2, accel_body_m_s2=(-0.1, 0.0, G))
        ekf.predict(dt)
        ekf.update_wheel_odometry(0.0, 0.0, (0.03 ** 2, 0.03 ** 2))
    assert not ekf.slipping and abs(ekf.state[0] - x) < 0.05


# ---- the compiled kernels against the list code they replaced (the reference, kept here)

def _wrap_ref(angle):
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _predict_ref(s, p, dt, q):
    c, si = math.cos(s[2]), math.sin(s[2])
    f_x_yaw, f_x_vx = -s[3] * si * dt, c * dt
    f_y_yaw, f_y_vx = s[3] * c * dt, si * dt
    s[0] += s[3] * c * dt
    s[1] += s[3] * si * dt
    s[2] = _wrap_ref(s[2] + s[4] * dt)

    def mix(v):
        return [v[0] + f_x_yaw * v[2] + f_x_vx * v[3], v[1] + f_y_yaw * v[2] + f_y_vx * v[3],
                v[2] + dt * v[4], v[3], v[4]]

    fpf = [mix(row) for row in zip(*[mix(col) for col in zip(*p)])]
    for i in range(5):
        fpf[i][i] += q[i] * dt
    return s, fpf


def _update_ref(s, p, rows, z, r_diag):
    innovation = [z[i] - s[row] for i, row in enumerate(rows)]
    innovation = [_wrap_ref(v) if row == 2 else v for v, row in zip(innovation, rows)]
    r0 = rows[0]
    col0 = [p[i][r0] for i in range(5)]
    if len(rows) == 1:
        k0 = [v / (col0[r0] + r_diag[0]) for v in col0]
        s = [s[i] + k0[i] * innovation[0] for i in range(5)]
        a_mat = [[pij - ki * hj for pij, hj in zip(pi, p[r0])] for pi, ki in zip(p, k0)]
        r = r_diag[0]
        p = [[aij - ai[r0] * kj + ki * r * kj for aij, kj in zip(ai, k0)] for ai, ki in zip(a_mat, k0)]
    else:
        r1 = rows[1]
        col1 = [p[i][r1] for i in range(5)]
        a, b, c, d = col0[r0] + r_diag[0], col1[r0], col0[r1], col1[r1] + r_diag[1]
        det = a * d - b * c
        ia, ib, ic, id_ = d / det, -b / det, -c / det, a / det
        k0 = [x * ia + y * ic for x, y in zip(col0, col1)]
        k1 = [x * ib + y * id_ for x, y in zip(col0, col1)]
        s = [s[i] + (k0[i] * innovation[0] + k1[i] * innovation[1]) for i in range(5)]
        a_mat = [[pij - ki * h0 - li * h1 for pij, h0, h1 in zip(pi, p[r0], p[r1])] for pi, ki, li in zip(p, k0, k1)]
        q0, q1 = r_diag
        p = [[aij - ai[r0] * kj - ai[r1] * lj + ki * q0 * kj + li * q1 * lj for aij, kj, lj in zip(ai, k0, k1)]
             for ai, ki, li in zip(a_mat, k0, k1)]
    s[2] = _wrap_ref(s[2])
    return s, p


def test_compiled_kernels_are_bit_identical_to_the_list_arithmetic():
    from cottonsim_world.estimation.odometry_ekf import _predict_kernel, _update_one_kernel, _update_two_kernel
    rng = np.random.default_rng(4)
    q = [0.05, 0.05, 0.06, 0.025, 0.02]
    for trial in range(300):
        m = rng.normal(size=(5, 5))
        p_list = (m @ m.T * 0.1 + np.eye(5) * 1e-3).tolist()
        s_list = rng.normal(size=5).tolist()
        s_list[2] = float(rng.choice([math.pi - 1e-3, -math.pi + 1e-3, rng.uniform(-math.pi, math.pi)]))
        s_arr, p_arr = np.array(s_list), np.array(p_list)
        op = trial % 4
        if op == 0:
            dt = float(rng.choice([0.02, 0.0, 0.5]))
            want_s, want_p = _predict_ref(list(s_list), [row[:] for row in p_list], dt, q)
            _predict_kernel(s_arr, p_arr, math.cos(s_list[2]), math.sin(s_list[2]), dt, np.array(q))
        elif op == 1:
            row, z, r = int(rng.integers(5)), float(rng.normal(scale=4.0)), float(rng.uniform(1e-4, 1.0))
            want_s, want_p = _update_ref(s_list, p_list, (row,), (z,), (r,))
            _update_one_kernel(s_arr, p_arr, row, z, r)
        else:
            rows = (3, 4) if op == 2 else (2, 4)
            z, r = rng.normal(scale=4.0, size=2).tolist(), rng.uniform(1e-4, 1.0, 2).tolist()
            want_s, want_p = _update_ref(s_list, p_list, rows, z, r)
            _update_two_kernel(s_arr, p_arr, rows[0], rows[1], z[0], z[1], r[0], r[1])
        assert s_arr.tolist() == want_s, trial
        assert p_arr.tolist() == want_p, trial


def stand(ekf, seconds, gyro_bias_rad_s, seed=0, dt=0.02):
    """A standing robot: wheels at zero, the gyro reading its bias plus white noise (the IMU model's 0.005)."""
    rng = np.random.default_rng(seed)
    for _ in range(int(round(seconds / dt))):
        assert ekf.predict(dt) is None
        assert ekf.update_wheel_odometry(0.0, 0.0, (0.001, 0.03)) is None
        assert ekf.update_imu(gyro_bias_rad_s + 0.005 * rng.standard_normal(), 2 * 0.005 ** 2) is None


def test_a_standing_robot_keeps_its_heading_although_the_gyro_is_biased():
    ekf = OdometryEkf()
    stand(ekf, 120.0, gyro_bias_rad_s=0.003)
    assert ekf.standing
    assert abs(ekf.state[2]) < 0.005                      # 120 s at 0.003 rad/s would be 0.36 rad
    assert ekf.gyro_bias_rad_s == pytest.approx(0.003, abs=0.001)
    # without the standstill handling the yaw follows the biased gyro
    off = OdometryEkf(OdometryEkfConfig(standstill_yaw_rate_variance=0.03, gyro_bias_time_s=1e9))
    stand(off, 120.0, gyro_bias_rad_s=0.003)
    assert abs(off.state[2]) > 0.2


def test_the_bias_learnt_standing_is_taken_off_the_gyro_while_driving():
    ekf = OdometryEkf()
    stand(ekf, 60.0, gyro_bias_rad_s=0.003)
    rng = np.random.default_rng(1)
    for _ in range(500):                                  # 10 s straight on: wheels say 0 rad/s (noisy, var 0.03)
        ekf.predict(0.02)
        ekf.update_wheel_odometry(0.5, 0.03 * rng.standard_normal(), (0.001, 0.03))
        ekf.update_imu(0.003 + 0.005 * rng.standard_normal(), 2 * 0.005 ** 2)
    assert not ekf.standing
    assert abs(ekf.state[2]) < 0.01                       # 0.03 rad if the bias were integrated
