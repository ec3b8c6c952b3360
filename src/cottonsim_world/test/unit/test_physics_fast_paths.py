"""The per-step fast paths: merged wheel contacts, plain-float EKF, idle arm.

Each fast path is checked against an independent reference: ODE's own
cylinder-plane contacts, a textbook numpy Kalman filter, the per-point
contact model.
"""
import math

import numpy as np
import ode
import pytest

from cottonsim_world.estimation.odometry_ekf import OdometryEkf, OdometryEkfConfig
from cottonsim_world.farm.model import Pose2D
from cottonsim_world.physics.husky_params import HuskyParams
from cottonsim_world.physics.ode_world import OdeWorld, PhysicsConfig

HP = HuskyParams()


def test_merged_wheel_contact_is_the_mean_of_odes_rim_contacts():
    world = OdeWorld(PhysicsConfig())
    world.spawn_robot(Pose2D(0.0, 0.0, 0.0))
    geom, body, is_wheel = world._ground_pairs[2]              # the first wheel
    assert is_wheel
    captured = []
    world._add_wheel_contact = lambda g, b, n, pos, normal, depth, axle: captured.append((n, pos, depth))
    rng = np.random.default_rng(7)
    checked = {1: 0, 2: 0}
    for _ in range(300):
        # random heading, small roll / pitch, centre height around the radius
        roll, pitch, yaw = rng.normal(0.0, 0.15), rng.normal(0.0, 0.3), rng.uniform(-math.pi, math.pi)
        cr, sr, cp, sp, cy, sy = (math.cos(roll / 2), math.sin(roll / 2), math.cos(pitch / 2),
                                  math.sin(pitch / 2), math.cos(yaw / 2), math.sin(yaw / 2))
        body.setQuaternion((cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy))
        body.setPosition((rng.normal(), rng.normal(), HP.wheel_radius_m + rng.uniform(-0.02, 0.01)))
        captured.clear()
        assert world._merged_wheel_contact(geom, body)
        reference = ode.collide(geom, world._ground)
        if not reference:
            assert captured == []
            continue
        points = np.array([c.getContactGeomParams()[0] for c in reference])
        depths = [c.getContactGeomParams()[2] for c in reference]
        n, pos, depth = captured[0]
        assert n == len(reference)
        assert np.allclose(pos, points.mean(axis=0), atol=1e-9)
        assert depth == pytest.approx(np.mean(depths), abs=1e-9)
        checked[n] += 1
    assert checked[1] > 10 and checked[2] > 10                 # both cases were exercised


def spin_and_drive(merge):
    world = OdeWorld(PhysicsConfig(merge_wheel_contacts=merge))
    world.spawn_robot(Pose2D(0.0, 0.0, 0.0))
    for _ in range(300):                      # 1.5 s at 1 rad/s
        world.set_command(0.0, 1.0)
        world.step()
    spin_rate = world.robot_state().angular_velocity_world_rad_s[2]
    start = world.robot_state().position_m.copy()
    for _ in range(600):                      # 3 s at 0.5 m/s
        world.set_command(0.5, 0.0)
        world.step()
    return spin_rate, np.linalg.norm(world.robot_state().position_m[:2] - start[:2])


def test_merged_contacts_drive_like_one_joint_per_rim_point():
    rate_merged, dist_merged = spin_and_drive(True)
    rate_points, dist_points = spin_and_drive(False)
    a, b = HP.wheelbase_m / 2, HP.track_m / 2
    # merged: the closed form of isotropic point contacts at the wheel centres
    assert rate_merged == pytest.approx(1.875 * b * b / (a * a + b * b), rel=0.01)
    # per-point joints add the tyre's scrubbing torque: a little slower, not more
    assert 0.95 * rate_merged < rate_points < rate_merged
    assert dist_merged == pytest.approx(dist_points, abs=0.01)


def test_merge_flag_is_validated():
    with pytest.raises(ValueError, match="merge_wheel_contacts"):
        PhysicsConfig(merge_wheel_contacts=1)


class NumpyEkf:
    """Textbook EKF with dense matrices: the reference for the plain-float filter."""

    def __init__(self, cfg):
        self.x = np.zeros(5)
        self.p = np.diag(cfg.initial_covariance_diag)
        self.q = np.diag(cfg.process_noise_diag)

    def predict(self, dt):
        x = self.x
        f = np.eye(5)
        f[0, 2], f[0, 3] = -x[3] * math.sin(x[2]) * dt, math.cos(x[2]) * dt
        f[1, 2], f[1, 3] = x[3] * math.cos(x[2]) * dt, math.sin(x[2]) * dt
        f[2, 4] = dt
        self.x = x + dt * np.array([x[3] * math.cos(x[2]), x[3] * math.sin(x[2]), x[4], 0.0, 0.0])
        self.p = f @ self.p @ f.T + self.q * dt

    def update(self, rows, z, r):
        h = np.eye(5)[rows]
        y = np.asarray(z) - h @ self.x
        s = h @ self.p @ h.T + np.diag(r)
        k = self.p @ h.T @ np.linalg.inv(s)
        self.x = self.x + k @ y
        i_kh = np.eye(5) - k @ h
        self.p = i_kh @ self.p @ i_kh.T + k @ np.diag(r) @ k.T


def test_plain_float_ekf_matches_a_dense_numpy_ekf():
    cfg = OdometryEkfConfig()
    ekf, ref = OdometryEkf(cfg), NumpyEkf(cfg)
    rng = np.random.default_rng(3)
    for _ in range(400):                      # yaw stays well inside (-pi, pi): no wrapping here
        dt, v, w = 0.02, rng.normal(0.4, 0.1), rng.normal(0.0, 0.2)
        ekf.predict(dt)
        ref.predict(dt)
        ekf.update_wheel_odometry(v, w, (1e-3, 0.03))
        ref.update([3, 4], [v, w], [1e-3, 0.03])
        ekf.update_imu(w + 0.01, 5e-5)
        ref.update([4], [w + 0.01], [5e-5])
    ekf.update_imu(0.0, 5e-5, yaw=0.3, yaw_cov=1e-2)
    ref.update([2, 4], [0.3, 0.0], [1e-2, 5e-5])
    assert abs(ref.x[2]) < 2.5
    assert np.allclose(ekf.state, ref.x, rtol=1e-9, atol=1e-12)
    assert np.allclose(ekf.covariance, ref.p, rtol=1e-7, atol=1e-15)
    assert np.allclose(ekf.covariance, ekf.covariance.T, atol=1e-15)
    out = ekf.output()
    assert out.pose_covariance[5, 5] == pytest.approx(ref.p[2, 2])
    assert out.twist_covariance[0, 5] == pytest.approx(ref.p[3, 4])


def test_idle_arm_still_follows_a_new_command():
    import pathlib
    from cottonsim_world.config_io import simulator_config_from_dict
    from cottonsim_world.robot.urdf_model import UrdfModel
    from cottonsim_world.simulator import Simulator
    urdf = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"
    off = {"enabled": False}
    sim = Simulator(simulator_config_from_dict({
        "farm": {"rows": 1, "plants_per_row": 2, "plant_detail": "low"}, "lidar_enabled": False,
        "cameras": {"realsense_p": off, "realsense_secondary": off, "realsense_tertiary": off}}),
        UrdfModel.from_file(urdf))
    sim.step_for(0.1)                                         # at its start pose: the arm goes idle
    start = sim.arm.positions
    target = start + np.array([0.3, -0.2, 0.1, 0.0, 0.0, 0.2])
    sim.command_arm(target)
    sim.step_for(0.1)
    moved = sim.arm.positions
    assert np.all(np.abs(moved - target) <= np.abs(start - target) + 1e-12)
    assert np.linalg.norm(moved - start) > 0.01               # it moves after the idle spell
    sim.step_for(3.0)
    assert np.allclose(sim.arm.positions, target, atol=1e-6)  # and arrives
    sim.close()
