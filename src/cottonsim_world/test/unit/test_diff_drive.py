"""DiffDriveController: velocity / acceleration limits, time-out, NaN refusal."""
import math

import pytest

from cottonsim_world.physics.diff_drive import DiffDriveController
from cottonsim_world.physics.husky_params import DriveLimits, HuskyParams

HP = HuskyParams()
LIM = DriveLimits()
R = HP.wheel_radius_m
HALF_TRACK_EFF = 0.5 * HP.track_m * 1.875


def run(ctrl, t0, t1, dt=0.02, v=None, w=None):
    """Update at dt from t0 to t1 (re-sending the command if given); return last output."""
    out = None
    n = int(round((t1 - t0) / dt))
    for i in range(n + 1):
        t = t0 + i * dt
        if v is not None:
            ctrl.set_command(v, w, t)
        out = ctrl.update(t)
    return out


def test_wheel_speeds_follow_diff_drive_kinematics_with_multiplier():
    ctrl = DiffDriveController(HP, LIM)
    out = run(ctrl, 0.0, 2.0, v=0.4, w=0.5)
    assert out.linear_x_m_s == pytest.approx(0.4)
    assert out.angular_z_rad_s == pytest.approx(0.5)
    assert out.left_rad_s == pytest.approx((0.4 - 0.5 * HALF_TRACK_EFF) / R)
    assert out.right_rad_s == pytest.approx((0.4 + 0.5 * HALF_TRACK_EFF) / R)


def test_velocity_limits_clamp_both_signs():
    ctrl = DiffDriveController(HP, LIM)
    out = run(ctrl, 0.0, 2.0, v=5.0, w=-9.0)
    assert out.linear_x_m_s == pytest.approx(1.0)
    assert out.angular_z_rad_s == pytest.approx(-2.0)


def test_acceleration_limit_ramps_linearly():
    ctrl = DiffDriveController(HP, LIM)
    ctrl.set_command(1.0, 2.0, 0.0)
    ctrl.update(0.0)
    out = None
    for k in range(1, 6):                       # 0.1 s in 0.02 s periods
        ctrl.set_command(1.0, 2.0, 0.02 * k)
        out = ctrl.update(0.02 * k)
    assert out.linear_x_m_s == pytest.approx(3.0 * 0.1)      # 3 m/s^2
    assert out.angular_z_rad_s == pytest.approx(6.0 * 0.1)   # 6 rad/s^2


def test_timeout_zeroes_command_after_0_25_s_then_decelerates():
    ctrl = DiffDriveController(HP, LIM)
    out = run(ctrl, 0.0, 1.0, v=0.6, w=0.0)
    assert out.linear_x_m_s == pytest.approx(0.6) and not out.timed_out
    # no new command: still driving at 1.24 s (0.24 s after the last one) ...
    out = run(ctrl, 1.02, 1.24)
    assert out.linear_x_m_s == pytest.approx(0.6) and not out.timed_out
    # ... timed out right after 0.25 s, output decays at the acceleration limit
    out = ctrl.update(1.26)
    assert out.timed_out
    assert out.linear_x_m_s == pytest.approx(0.6 - 3.0 * 0.02)
    out = run(ctrl, 1.28, 2.0)
    assert out.linear_x_m_s == 0.0 and out.left_rad_s == 0.0 and out.right_rad_s == 0.0


def test_no_command_means_zero():
    ctrl = DiffDriveController(HP, LIM)
    out = run(ctrl, 0.0, 0.5)
    assert out.timed_out and out.linear_x_m_s == 0.0


@pytest.mark.parametrize("bad", [(math.nan, 0.0, 0.0), (0.1, math.inf, 0.0), (0.1, 0.0, math.nan), ("x", 0, 0)])
def test_non_finite_commands_are_refused_and_keep_previous(bad):
    ctrl = DiffDriveController(HP, LIM)
    assert ctrl.set_command(0.3, 0.0, 0.0) is None
    reason = ctrl.set_command(*bad)
    assert reason is not None and "not a finite number" in reason
    assert ctrl.rejections == [reason]
    out = run(ctrl, 0.0, 0.2)
    assert math.isfinite(out.left_rad_s) and out.linear_x_m_s == pytest.approx(0.3)


def test_bad_limits_raise_naming_parameter():
    with pytest.raises(ValueError, match="max_linear_m_s"):
        DriveLimits(max_linear_m_s=-1.0)
    with pytest.raises(ValueError, match="cmd_timeout_s"):
        DriveLimits(cmd_timeout_s=math.nan)
    with pytest.raises(ValueError, match="wheel_radius_m"):
        HuskyParams(wheel_radius_m=0.0)
