"""The in-process Simulator: determinism, sensor schedule, frames of the readings."""
import dataclasses
import math
import pathlib

import numpy as np
import pytest

from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.readings import (CameraReading, GpsReading, GroundTruthReading, ImuReading, LidarReading,
                                      OdometryReading)
from cottonsim_world.simulator import Simulator
from cottonsim_world.simulator_config import SimulatorConfig
from cottonsim_common.transforms import quaternion_to_matrix


def small_config(seed=0):
    return simulator_config_from_dict({
        "seed": seed,
        "farm": {"rows": 2, "plants_per_row": 4, "plant_detail": "low"},
        "cameras": {"realsense_p": {"width": 64, "height": 48, "rate_hz": 10.0},
                    "realsense_secondary": {"enabled": False},
                    "realsense_tertiary": {"enabled": False}},
        "lidar": {"samples_per_ring": 90},
        "gps_noise": {"gaussian_noise_m": [0.05, 0.05, 0.0]},
    })


def run(sim, seconds=1.0):
    readings = []
    while sim.time_s < seconds - 1e-9:
        sim.command_velocity(0.4, 0.3)
        readings.extend(sim.step())
    return readings


def test_same_seed_same_run_different_seed_different_noise(urdf):
    a, b, c = (Simulator(small_config(seed), urdf) for seed in (3, 3, 4))
    ra, rb, rc = run(a), run(b), run(c)
    gps = lambda rs: np.array([(r.latitude_deg, r.longitude_deg) for r in rs if isinstance(r, GpsReading)])
    assert np.array_equal(gps(ra), gps(rb))
    assert not np.array_equal(gps(ra), gps(rc))
    truth = lambda rs: np.array([r.state.position_m for r in rs if isinstance(r, GroundTruthReading)])
    assert np.array_equal(truth(ra), truth(rb))
    scans = lambda rs: [r.scan.points for r in rs if isinstance(r, LidarReading)]
    assert all(np.array_equal(p, q) for p, q in zip(scans(ra), scans(rb)))
    for sim in (a, b, c):
        sim.close()


def test_sensor_rates_follow_the_config(urdf):
    sim = Simulator(small_config(), urdf)
    readings = run(sim, 1.0)
    # sensors fire at the first step and then once per period: 0.002, 0.1, ... 0.9 below 1 s
    count = lambda kind: sum(isinstance(r, kind) and r.stamp_s < 1.0 - 1e-6 for r in readings)
    assert count(CameraReading) == 10          # 10 Hz
    assert count(LidarReading) == 10           # 10 Hz
    assert count(ImuReading) == 50             # 50 Hz
    assert count(GpsReading) == 40             # 40 Hz
    assert count(OdometryReading) == 50
    sim.set_sensor_active("realsense_p", False)
    assert not any(isinstance(r, CameraReading) for r in run(sim, 1.5))
    with pytest.raises(ValueError, match="unknown sensor"):
        sim.set_sensor_active("no_such_sensor", True)
    sim.close()


def test_imu_reading_is_in_imu_link_axes(urdf):
    sim = Simulator(small_config(), urdf)
    readings = run(sim, 0.5)
    imu = [r for r in readings if isinstance(r, ImuReading)][-1]
    truth = [r for r in readings if isinstance(r, GroundTruthReading)][-1]
    r_base_imu = sim.base_T_sensor["imu_link"][:3, :3]
    # gravity (+9.8 up) seen in imu_link axes = R^T (R_world_base^T g)
    r_world_base = quaternion_to_matrix(truth.state.orientation_xyzw)
    expected = r_base_imu.T @ r_world_base.T @ np.array([0.0, 0.0, 9.8])
    assert np.allclose(imu.measurement.linear_acceleration_m_s2, expected, atol=0.5)
    # the orientation is imu_link's: its z axis is where R_world_base @ R_base_imu puts it
    r_world_imu = quaternion_to_matrix(imu.measurement.orientation_xyzw)
    assert np.allclose(r_world_imu, r_world_base @ r_base_imu, atol=0.05)
    sim.close()


def test_odometry_tracks_truth_on_a_short_arc(urdf):
    sim = Simulator(small_config(), urdf)
    readings = run(sim, 3.0)
    odom = [r for r in readings if isinstance(r, OdometryReading)][-1].filtered
    truth = [r for r in readings if isinstance(r, GroundTruthReading)]
    start, end = truth[0].state, truth[-1].state
    moved_truth = np.linalg.norm(end.position_m[:2] - start.position_m[:2])
    assert moved_truth > 0.8
    assert math.hypot(odom.x_m, odom.y_m) == pytest.approx(moved_truth, abs=0.05)
    sim.close()


def test_config_errors_name_the_key():
    with pytest.raises(ValueError, match="lidar.samples_per_rings"):
        simulator_config_from_dict({"lidar": {"samples_per_rings": 10}})
    with pytest.raises(ValueError, match="gps_rate_hz"):
        SimulatorConfig(gps_rate_hz=0.0)
    with pytest.raises(ValueError, match="cameras"):
        simulator_config_from_dict({"cameras": [1, 2]})


def test_shipped_config_files_parse():
    import yaml
    root = pathlib.Path(__file__).resolve().parents[2]
    for path in [root / "config" / "sim.yaml", root / "test" / "rostest" / "sim_ci.yaml",
                 root / "test" / "rostest" / "sim_faults_ci.yaml", root / "test" / "rostest" / "arm_ci.yaml"]:
        config = simulator_config_from_dict(yaml.safe_load(path.read_text()) or {})
        assert isinstance(config, SimulatorConfig), path


def test_teleport_moves_the_truth_but_not_the_odometry(urdf):
    sim = Simulator(small_config(), urdf)
    run(sim, 1.0)                                     # drive a little: odometry and truth move together
    sim.step_for(0.5)                                 # /cmd_vel times out: the robot stops
    before = [r for r in sim.step_for(0.1)]
    odom0 = [r for r in before if isinstance(r, OdometryReading)][-1].filtered
    truth0 = [r for r in before if isinstance(r, GroundTruthReading)][-1].state
    target = (truth0.position_m[0] - 3.0, truth0.position_m[1] + 0.5, 0.4)
    sim.teleport_robot(*target)
    after = sim.step_for(0.5)
    truth1 = [r for r in after if isinstance(r, GroundTruthReading)][-1].state
    odom1 = [r for r in after if isinstance(r, OdometryReading)][-1].filtered
    assert truth1.position_m[:2] == pytest.approx(target[:2], abs=0.02)
    r = quaternion_to_matrix(truth1.orientation_xyzw)
    assert math.atan2(r[1, 0], r[0, 0]) == pytest.approx(target[2], abs=0.02)
    # the kidnap: odometry did not see the 3 m jump
    assert math.hypot(odom1.x_m - odom0.x_m, odom1.y_m - odom0.y_m) < 0.02
    # the robot still drives after the teleport, and odometry follows that motion again
    run(sim, sim.time_s + 1.0)
    truth2 = [r for r in sim.step_for(0.02) if isinstance(r, GroundTruthReading)][-1].state
    assert np.linalg.norm(truth2.position_m[:2] - truth1.position_m[:2]) > 0.2
    for bad in ((math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (0.0, 0.0, "north")):
        with pytest.raises(ValueError, match="teleport pose"):
            sim.teleport_robot(*bad)
    sim.close()


def _camera_stamps(urdf, render_rate_hz):
    config = small_config()
    cameras = dict(config.cameras)
    cameras["realsense_p"] = dataclasses.replace(cameras["realsense_p"], rate_hz=24.0, render_rate_hz=render_rate_hz)
    sim = Simulator(dataclasses.replace(config, cameras=tuple(cameras.items()), lidar_enabled=False), urdf)
    stamps = [r.stamp_s for r in run(sim, 2.0) if isinstance(r, CameraReading) and r.stamp_s < 2.0 - 1e-6]
    sim.close()
    return stamps


def test_render_rate_renders_the_first_frame_of_each_slot_only(urdf):
    every = _camera_stamps(urdf, 0.0)
    rendered = _camera_stamps(urdf, 5.0)
    assert len(every) == 48                      # 24 fps for 2 s
    assert len(rendered) == 10                   # one per 0.2 s slot
    first_of_slot = [s for i, s in enumerate(every) if i == 0 or math.floor(s * 5 + 1e-6) > math.floor(
        every[i - 1] * 5 + 1e-6)]
    assert rendered == first_of_slot             # the same stamps, on the 24 fps grid


@pytest.mark.parametrize("bad", [-1.0, 30.0, float("nan"), "5", True])
def test_a_bad_render_rate_is_refused_with_the_key(bad):
    with pytest.raises(ValueError, match="render_rate_hz"):
        simulator_config_from_dict({"cameras": {"realsense_p": {"rate_hz": 24.0, "render_rate_hz": bad}}})


@pytest.mark.parametrize("keys", [{"consumer_wait_s": -1.0, "render_rate_hz": 5.0}, {"consumer_wait_s": 2.0},
                                  {"consumer_wait_s": "long", "render_rate_hz": 5.0}])
def test_a_bad_consumer_wait_is_refused_with_the_key(keys):
    with pytest.raises(ValueError, match="consumer_wait_s"):
        simulator_config_from_dict({"cameras": {"realsense_p": dict(rate_hz=24.0, **keys)}})
