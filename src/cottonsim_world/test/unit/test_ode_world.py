"""OdeWorld: straight driving, spin in place, rest, plant contacts, determinism."""
import math

import numpy as np
import pytest

from cottonsim_world.farm.model import Plant, PlantModel, Pose2D, Primitive
from cottonsim_world.physics.diff_drive import DiffDriveController
from cottonsim_world.physics.husky_params import DriveLimits, HuskyParams
from cottonsim_world.physics.ode_world import OdeWorld, PhysicsConfig

HP = HuskyParams()


def make_plant(plant_id, x, y, yaw=0.0, prims=None):
    prims = prims or [Primitive("cylinder", (0.0, 0.0, 0.5), (0.0, 0.0, 0.0, 1.0), (0.05, 1.0), "stem")]
    model = PlantModel(meshes={}, collision=prims, boll_centres=np.zeros((0, 3)), boll_radii=np.zeros(0),
                       height_m=1.0, width_m=0.7)
    return Plant(plant_id=plant_id, row=0, index_in_row=plant_id, x_m=x, y_m=y, yaw_rad=yaw, model=model)


def drive(world, v, w, duration_s):
    for _ in range(int(round(duration_s / world.config.step_s))):
        world.set_command(v, w)
        world.step()


def expected_distance(v, duration_s, step_s, settle_s):
    """Integral of the controller's rate-limited speed (the ideal, slip-free answer)."""
    ctrl = DiffDriveController(HP, DriveLimits())
    dist, t, n = 0.0, 0.0, int(round((duration_s + settle_s) / step_s))
    out = None
    period = 1.0 / 50.0
    next_control = 0.0
    for i in range(n):
        t = i * step_s
        if i < int(round(duration_s / step_s)):
            ctrl.set_command(v, 0.0, t)
        if t >= next_control - 1e-9:
            out = ctrl.update(t)
            next_control += period
        dist += out.linear_x_m_s * step_s
    return dist


def test_drives_5_m_straight_within_5_cm():
    world = OdeWorld()
    world.spawn_robot(Pose2D(2.0, -1.0, math.pi / 2))        # drive along +y
    world.step_for(0.2)
    start = world.robot_state().position_m.copy()
    drive(world, 0.5, 0.0, 10.0)
    world.step_for(1.0)                                      # time-out and stop
    end = world.robot_state().position_m
    want = expected_distance(0.5, 10.0, world.config.step_s, 1.0)
    assert want == pytest.approx(5.125, abs=0.02)             # sanity of the reference
    assert abs(end[0] - start[0]) < 0.05
    assert end[1] - start[1] == pytest.approx(want, abs=0.05)
    assert np.linalg.norm(world.robot_state().linear_velocity_world_m_s) < 1e-3


def test_spin_in_place_under_rotates_like_a_skid_steer():
    world = OdeWorld()
    world.spawn_robot(Pose2D(0.0, 0.0, 0.0))
    world.step_for(0.2)
    drive(world, 0.0, 1.0, 1.5)
    rates = []
    for _ in range(250):                                     # 0.5 s of steady turning
        world.set_command(0.0, 1.0)
        world.step()
        rates.append(world.robot_state().angular_velocity_world_rad_s[2])
    rate = float(np.mean(rates))
    # ideal 2-wheel kinematics with the 1.875-wide track would turn at 1.875 rad/s;
    # isotropic tyre slip gives b^2 / (a^2 + b^2) of that (a, b half wheelbase / track)
    a, b = HP.wheelbase_m / 2, HP.track_m / 2
    assert rate < 1.875 * 0.7
    assert rate == pytest.approx(1.875 * b * b / (a * a + b * b), rel=0.1)
    assert np.linalg.norm(world.robot_state().position_m[:2]) < 0.05   # turns on the spot


def test_rest_is_stable():
    world = OdeWorld()
    world.spawn_robot(Pose2D(1.0, 1.0, 0.3))
    world.step_for(0.5)
    zs, speeds = [], []
    for _ in range(250):
        world.step()
        s = world.robot_state()
        zs.append(s.position_m[2])
        speeds.append(np.linalg.norm(s.linear_velocity_world_m_s))
    s = world.robot_state()
    assert abs(zs[-1] - HP.base_link_height_m) < 0.002       # no sinking
    assert np.ptp(zs) < 1e-5 and max(speeds) < 1e-3          # no jitter or bounce
    assert s.linear_acceleration_body_m_s2 == pytest.approx([0.0, 0.0, 9.8], abs=0.01)
    assert s.yaw_rad == pytest.approx(0.3, abs=1e-3)
    assert np.linalg.norm(s.position_m[:2] - [1.0, 1.0]) < 1e-3
    assert np.sum(s.orientation_xyzw ** 2) == pytest.approx(1.0)


def test_driving_into_a_plant_is_stopped_and_counted_once():
    world = OdeWorld()
    world.add_plants([make_plant(7, 1.6, 0.0), make_plant(8, 1.6, 3.0)])
    world.spawn_robot(Pose2D(0.0, 0.0, 0.0))
    events = []
    for _ in range(8):                                       # 4 s at 0.5 m/s, pushing on
        drive(world, 0.5, 0.0, 0.5)
        events += world.contacts_since_last_call()
    state = world.robot_state()
    front = state.position_m[0] + HP.lower_box_size_m[0] / 2
    assert front < 1.6                                       # stopped at the stem (radius 0.05)
    assert front > 1.4
    assert [(e.plant_id, e.part) for e in events] == [(7, "chassis")]
    assert events[0].point_m[0] == pytest.approx(1.55, abs=0.03)
    assert world.total_contact_events == 1 and world.plants_touched == {7}
    assert world.contacts_since_last_call() == []
    # back off and touch again: a second event
    drive(world, -0.5, 0.0, 1.0)
    drive(world, 0.5, 0.0, 1.5)
    again = world.contacts_since_last_call()
    assert [(e.plant_id, e.part) for e in again] == [(7, "chassis")]
    assert world.total_contact_events == 2


def test_plant_primitives_follow_plant_yaw():
    # the box sits 0.6 m along the plant's local x; yawed by +90 deg it lands on
    # the robot's path at (1.6, 0); without the rotation it would be at (2.2, -0.6)
    box = Primitive("box", (0.6, 0.0, 0.3), (0.0, 0.0, 0.0, 1.0), (0.05, 0.05, 0.3), "branch")
    world = OdeWorld()
    world.add_plants([make_plant(3, 1.6, -0.6, math.pi / 2, [box])])
    world.spawn_robot(Pose2D(0.0, 0.0, 0.0))
    drive(world, 0.5, 0.0, 3.5)
    assert world.plants_touched == {3}
    assert world.robot_state().position_m[0] + HP.lower_box_size_m[0] / 2 < 1.6


def test_same_inputs_give_identical_states():
    def run():
        world = OdeWorld(PhysicsConfig(seed=4))
        world.add_plants([make_plant(1, 1.0, 0.8)])
        world.spawn_robot(Pose2D(0.0, 0.0, 0.1))
        drive(world, 0.6, 0.4, 1.0)
        drive(world, 0.2, -0.8, 0.5)
        return world.robot_state()
    a, b = run(), run()
    for name in ("position_m", "orientation_xyzw", "linear_velocity_world_m_s", "angular_velocity_body_rad_s",
                 "linear_acceleration_body_m_s2", "wheel_angles_rad", "wheel_velocities_rad_s"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_state_fields_are_consistent():
    world = OdeWorld()
    world.spawn_robot(Pose2D(0.0, 0.0, math.pi / 2))
    drive(world, 0.5, 0.0, 1.0)
    s = world.robot_state()
    assert s.linear_velocity_body_m_s[0] == pytest.approx(0.5, abs=0.01)   # forward in the body
    assert s.linear_velocity_world_m_s[1] == pytest.approx(0.5, abs=0.01)  # = +y in the world
    assert np.allclose(s.wheel_velocities_rad_s, 0.5 / HP.wheel_radius_m, rtol=0.02)
    # unwrapped wheel angle ~ distance / radius (> 2 pi, so no wrapping)
    assert np.allclose(s.wheel_angles_rad, s.position_m[1] / HP.wheel_radius_m, rtol=0.05)
    assert world.sim_time_s == pytest.approx(1.0)


def test_bad_inputs_give_clear_errors():
    world = OdeWorld()
    with pytest.raises(RuntimeError, match="spawn_robot"):
        world.step()
    world.spawn_robot(Pose2D(0.0, 0.0, 0.0))
    assert "not a finite number" in world.set_command(math.nan, 0.0)
    world.step_for(0.2)
    assert np.all(np.isfinite(world.robot_state().position_m))
    with pytest.raises(ValueError, match="unknown shape"):
        world.add_static_obstacles(1, [Primitive("cone", (0, 0, 0), (0, 0, 0, 1), (1.0,))])
    with pytest.raises(ValueError, match="sizes must be finite"):
        world.add_static_obstacles(1, [Primitive("sphere", (0, 0, 0), (0, 0, 0, 1), (math.nan,))])
    with pytest.raises(ValueError, match="position"):
        world.add_static_obstacles(1, [Primitive("sphere", (0, math.inf, 0), (0, 0, 0, 1), (0.1,))])
    with pytest.raises(ValueError, match="Pose2D.x_m must be a finite number"):   # no spawn pose can hold NaN
        world.spawn_robot(Pose2D(math.nan, 0.0, 0.0))
    with pytest.raises(ValueError, match="step_s"):
        PhysicsConfig(step_s=0.0)
    with pytest.raises(ValueError, match="solver_iterations"):
        PhysicsConfig(solver_iterations=0)
