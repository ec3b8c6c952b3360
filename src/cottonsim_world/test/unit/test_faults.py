"""Sensor faults: the schedule's validation and the injector's effect on each kind of reading."""
import math

import numpy as np
import pytest

from cottonsim_world.faults import (GPS_STATUS_FIX, GPS_STATUS_GBAS_FIX, GPS_STATUS_NO_FIX, GPS_STATUS_SBAS_FIX,
                                    FaultInjector, FaultScheduleConfig, FaultSpec, fault_from_mapping,
                                    fault_schedule_from_list)
from cottonsim_world.geodesy import HectorGeodesy
from cottonsim_world.sensors.camera import CameraFrame
from cottonsim_world.sensors.cloud_filters import LaserScanConfig
from cottonsim_world.sensors.lidar import LidarScan
from cottonsim_world.readings import CameraReading, GpsReading, LidarReading

GEO = HectorGeodesy()
CAMERAS = ("realsense_p", "realsense_secondary")
TRUE_XY = (-6.0, 1.0)
NOMINAL_VAR = 1e-8


def injector(*specs, seed=0):
    return FaultInjector(FaultScheduleConfig(tuple(specs), seed), CAMERAS, GEO.radius_north_m, GEO.radius_east_m)


def fix(t):
    lat, lon, alt = GEO.world_to_geodetic(TRUE_XY[0], TRUE_XY[1], 0.5)
    return GpsReading(t, "base_link", lat, lon, alt, NOMINAL_VAR)


def world_xy(r):
    x, y, _ = GEO.geodetic_to_world(r.latitude_deg, r.longitude_deg, r.altitude_m)
    return np.array([x, y])


def camera_reading(t, camera="realsense_p", with_cloud=True):
    rgb = np.full((4, 6, 3), 120, np.uint8)
    frame = CameraFrame(rgb=rgb, depth_m=np.full((4, 6), 2.0, np.float32), semantic=np.ones((4, 6), np.uint8),
                        plant_id=None, world_T_optical=np.eye(4))
    packed = np.ones((24, 4), np.float32) if with_cloud else None
    return CameraReading(t, camera, f"{camera}_color_optical_frame", frame, intrinsics=None,
                         cloud_xyz=None if packed is None else packed[:, :3],
                         cloud_rgb=None if packed is None else np.ones((24, 3), np.uint8), cloud_xyzrgb=packed)


def lidar_reading(t):
    n = 50
    scan = LidarScan(points=np.ones((n, 3), np.float32), ring=np.zeros(n, np.uint16),
                     intensity=np.ones(n, np.float32), azimuth_rad=np.zeros(n, np.float32),
                     semantic=np.zeros(n, np.uint8), plant_id=np.full(n, -1, np.int32))
    return LidarReading(t, "velodyne", scan, np.ones((10, 3), np.float32), np.full(90, 3.0, np.float32),
                        LaserScanConfig(), np.full(360, 4.0, np.float32), LaserScanConfig())


# ---------------------------------------------------------------------------- the schedule
def test_schedule_from_yaml_entries_with_the_kinds_defaults():
    sched = fault_schedule_from_list([
        {"kind": "gps_outage", "start_s": 30, "duration_s": 15},
        {"kind": "gps_degraded", "start_s": 0, "duration_s": 5, "fix_type": "single"},
        {"kind": "gps_degraded", "start_s": 0, "duration_s": 5},
        {"kind": "camera_blackout", "start_s": 1, "duration_s": math.inf},
        {"kind": "lidar_dropout", "start_s": 1, "duration_s": 2},
    ])
    outage, single, degraded, cam, lidar = sched.faults
    assert (outage.start_s, outage.end_s, outage.target) == (30.0, 45.0, "gps")
    assert (single.fix_type, single.noise_std_m) == ("single", 2.5)
    assert (degraded.fix_type, degraded.noise_std_m, degraded.correlation_time_s) == ("float", 0.3, 0.0)
    assert (cam.camera, cam.mode, cam.target, cam.end_s) == ("all", "black", "all", math.inf)
    assert (lidar.mode, lidar.target) == ("drop", "lidar")
    assert fault_schedule_from_list(None).faults == () and fault_schedule_from_list([]).faults == ()


@pytest.mark.parametrize("entry, message", [
    ({"kind": "gps_blackout", "start_s": 0, "duration_s": 1}, r"faults\[0\].kind must be one of"),
    ({"kind": "gps_outage", "duration_s": 1}, r"faults\[0\] \(gps_outage\) lacks start_s"),
    ({"kind": "gps_outage", "start_s": 0, "duration_s": 1, "mode": "drop"}, "unknown key.*mode for gps_outage"),
    ({"kind": "gps_outage", "start_s": -1, "duration_s": 1}, "start_s must be a finite sim time >= 0"),
    ({"kind": "gps_outage", "start_s": 0, "duration_s": 0}, "duration_s must be > 0"),
    ({"kind": "gps_outage", "start_s": 0, "duration_s": "long"}, "duration_s must be a number"),
    ({"kind": "gps_degraded", "start_s": 0, "duration_s": 1, "fix_type": "rtk"}, "fix_type must be one of"),
    ({"kind": "gps_degraded", "start_s": 0, "duration_s": 1, "noise_std_m": -0.1}, "noise_std_m must be a finite"),
    ({"kind": "gps_degraded", "start_s": 0, "duration_s": 1, "correlation_time_s": math.inf},
     "correlation_time_s must be finite"),
    ({"kind": "gps_jump", "start_s": 0, "duration_s": 1}, "a jump needs offset_north_m or offset_east_m"),
    ({"kind": "camera_blackout", "start_s": 0, "duration_s": 1, "mode": "empty"}, "mode must be one of black, drop"),
    ({"kind": "lidar_dropout", "start_s": 0, "duration_s": 1, "mode": "black"}, "mode must be one of drop, empty"),
])
def test_bad_entries_are_refused_naming_the_problem(entry, message):
    with pytest.raises(ValueError, match=message):
        fault_schedule_from_list([entry])


def test_a_key_of_another_kind_is_refused_in_the_dataclass_too():
    with pytest.raises(ValueError, match="key 'camera' does not apply to lidar_dropout"):
        FaultSpec("lidar_dropout", 0.0, 1.0, camera="realsense_p")
    with pytest.raises(ValueError, match="must be a list of faults"):
        fault_schedule_from_list({"kind": "gps_outage"})
    with pytest.raises(ValueError, match="must be a mapping"):
        fault_from_mapping("gps_outage")


def test_camera_blackout_must_name_a_simulated_camera():
    with pytest.raises(ValueError, match="'realsense_x' is not a simulated camera"):
        injector(FaultSpec("camera_blackout", 0.0, 1.0, camera="realsense_x"))
    inj = injector()
    with pytest.raises(ValueError, match="not a simulated camera"):
        inj.add(FaultSpec("camera_blackout", 0.0, 1.0, camera="realsense_tertiary"))


# ---------------------------------------------------------------------------- GPS
def test_gps_outage_drops_fixes_only_inside_its_window():
    inj = injector(FaultSpec("gps_outage", 10.0, 15.0))
    kept = [t for t in np.arange(0.0, 40.0, 0.025) if inj.gps(fix(t)) is not None]
    assert min(t for t in np.arange(0.0, 40.0, 0.025) if t not in kept) == pytest.approx(10.0)
    dropped = [t for t in np.arange(0.0, 40.0, 0.025) if inj.gps(fix(t)) is None]
    assert dropped[0] >= 10.0 and dropped[-1] < 25.0 and len(dropped) == 600      # 15 s at 40 Hz
    assert inj.gps(fix(25.0)) is not None and inj.gps(fix(9.999)) is not None


def test_gps_no_fix_keeps_messages_with_status_no_fix_and_no_position():
    inj = injector(FaultSpec("gps_no_fix", 1.0, 2.0))
    r = inj.gps(fix(1.5))
    assert r.status == GPS_STATUS_NO_FIX
    assert math.isnan(r.latitude_deg) and math.isnan(r.longitude_deg) and math.isnan(r.position_variance_m2)
    assert inj.gps(fix(3.0)).status == GPS_STATUS_FIX
    assert inj.affected["gps_no_fix"] == 1


@pytest.mark.parametrize("fix_type, status", [("float", GPS_STATUS_GBAS_FIX), ("sbas", GPS_STATUS_SBAS_FIX),
                                              ("single", GPS_STATUS_FIX)])
def test_degraded_fix_has_the_noise_and_the_covariance_it_states(fix_type, status):
    std = 0.8
    inj = injector(FaultSpec("gps_degraded", 0.0, 1000.0, fix_type=fix_type, noise_std_m=std), seed=7)
    out = [inj.gps(fix(t)) for t in np.arange(0.0, 100.0, 0.025)]      # 4000 fixes
    assert {r.status for r in out} == {status}
    assert [r.position_variance_m2 for r in out] == pytest.approx([NOMINAL_VAR + std ** 2] * len(out))
    err = np.array([world_xy(r) for r in out]) - TRUE_XY
    assert np.abs(err.mean(axis=0)).max() < 0.05
    assert err.std(axis=0) == pytest.approx([std, std], rel=0.05)      # the stated variance is the true one
    alt_err = np.array([r.altitude_m for r in out]) - 0.5
    assert alt_err.std() == pytest.approx(std, rel=0.05)
    # white by default: neighbouring fixes are uncorrelated
    assert abs(np.corrcoef(err[:-1, 0], err[1:, 0])[0, 1]) < 0.06


def test_degraded_noise_with_a_correlation_time_wanders():
    tau, dt = 5.0, 0.1
    inj = injector(FaultSpec("gps_degraded", 0.0, 1e4, noise_std_m=0.5, correlation_time_s=tau), seed=3)
    out = [inj.gps(fix(t)) for t in np.arange(0.0, 2000.0, dt)]
    x, y, _ = GEO.geodetic_to_world(np.array([r.latitude_deg for r in out]), np.array([r.longitude_deg for r in out]))
    err = np.stack([x, y], axis=1) - TRUE_XY
    lag = int(1.0 / dt)                                                 # 1 s apart
    assert np.corrcoef(err[:-lag, 0], err[lag:, 0])[0, 1] == pytest.approx(math.exp(-1.0 / tau), abs=0.08)
    assert err[:, 0].std() == pytest.approx(0.5, rel=0.15)


def test_degraded_noise_is_deterministic_from_the_seed():
    spec = FaultSpec("gps_degraded", 0.0, 10.0)
    run = lambda seed: [world_xy(injector(spec, seed=seed).gps(fix(t))) for t in (0.0, 0.5, 1.0)]
    assert np.array_equal(run(5), run(5))
    assert not np.array_equal(run(5), run(6))


def test_gps_jump_moves_the_fix_by_its_offset_and_keeps_status_and_covariance():
    inj = injector(FaultSpec("gps_jump", 2.0, 3.0, offset_north_m=2.0, offset_east_m=-1.5))
    r = inj.gps(fix(3.0))
    # world x is north and y west at heading 0: north +2 m, east -1.5 m = west +1.5 m
    assert world_xy(r) == pytest.approx(np.array(TRUE_XY) + (2.0, 1.5), abs=1e-6)
    assert (r.status, r.position_variance_m2) == (GPS_STATUS_FIX, NOMINAL_VAR)
    assert world_xy(inj.gps(fix(5.0))) == pytest.approx(TRUE_XY, abs=1e-9)


def test_overlapping_gps_faults_combine():
    inj = injector(FaultSpec("gps_jump", 0.0, 10.0, offset_north_m=1.0),
                   FaultSpec("gps_degraded", 0.0, 10.0, fix_type="single", noise_std_m=0.0),
                   FaultSpec("gps_degraded", 0.0, 10.0, fix_type="float", noise_std_m=0.0),
                   FaultSpec("gps_no_fix", 5.0, 2.0), FaultSpec("gps_outage", 6.0, 2.0))
    r = inj.gps(fix(1.0))
    assert world_xy(r) == pytest.approx(np.array(TRUE_XY) + (1.0, 0.0), abs=1e-6)
    assert r.status in (GPS_STATUS_FIX, GPS_STATUS_GBAS_FIX)
    assert inj.gps(fix(5.5)).status == GPS_STATUS_NO_FIX     # no fix beats degradation
    assert inj.gps(fix(6.5)) is None                          # an outage beats everything


# ---------------------------------------------------------------------------- cameras and LiDAR
def test_camera_blackout_black_keeps_frames_without_pixels_or_depth():
    inj = injector(FaultSpec("camera_blackout", 1.0, 1.0, camera="realsense_p"))
    r = inj.camera(camera_reading(1.5))
    assert r.frame.rgb.shape == (4, 6, 3) and not r.frame.rgb.any()
    assert np.isnan(r.frame.depth_m).all()
    assert r.cloud_xyzrgb.shape == (0, 4) and r.cloud_xyz.shape == (0, 3) and r.cloud_rgb.shape == (0, 3)
    assert (r.frame.semantic == 1).all()                      # ground truth is not the sensor's
    other = camera_reading(1.5, "realsense_secondary")
    assert inj.camera(other) is other                         # another camera is untouched
    assert inj.camera(camera_reading(2.0)).frame.rgb.all()    # over at start + duration
    assert inj.camera(camera_reading(1.5, with_cloud=False)).cloud_xyzrgb is None


def test_camera_blackout_drop_and_all_cameras():
    inj = injector(FaultSpec("camera_blackout", 0.0, 1.0, mode="drop"))
    assert inj.camera(camera_reading(0.5)) is None
    assert inj.camera(camera_reading(0.5, "realsense_secondary")) is None
    assert inj.camera(camera_reading(1.0)) is not None


def test_lidar_dropout_drop_and_empty():
    inj = injector(FaultSpec("lidar_dropout", 0.0, 1.0), FaultSpec("lidar_dropout", 2.0, 1.0, mode="empty"))
    assert inj.lidar(lidar_reading(0.5)) is None
    r = inj.lidar(lidar_reading(2.5))
    assert len(r.scan.points) == 0 and len(r.scan.ring) == 0 and r.scan.points.shape == (0, 3)
    assert len(r.passthrough_points) == 0
    assert np.isinf(r.scan_ranges).all() and len(r.scan_ranges) == 90
    assert np.isinf(r.scan_360_ranges).all() and len(r.scan_360_ranges) == 360
    assert len(inj.lidar(lidar_reading(3.0)).scan.points) == 50


# ---------------------------------------------------------------------------- run time
def test_run_time_faults_and_clear():
    inj = injector()
    assert inj.idle and inj.active(0.0) == []
    inj.add(FaultSpec("gps_outage", 5.0, math.inf))
    inj.add(FaultSpec("lidar_dropout", 6.0, 1.0, mode="empty"))
    assert not inj.idle
    assert [f.kind for f in inj.active(6.5)] == ["gps_outage", "lidar_dropout"]
    assert inj.gps(fix(100.0)) is None
    assert inj.clear(8.0) == 1                                 # only the outage was not over
    assert inj.gps(fix(8.0)) is not None and inj.gps(fix(7.9)) is None
    active = inj.active(7.9)
    assert [(f.kind, f.end_s) for f in active] == [("gps_outage", 8.0)]
    assert inj.ended_by(8.0) and not inj.ended_by(7.0)


# ---------------------------------------------------------------------------- in the Simulator
def _sim_config(faults, sensor_workers=0):
    from cottonsim_world.config_io import simulator_config_from_dict
    return simulator_config_from_dict({
        "farm": {"rows": 2, "plants_per_row": 4, "plant_detail": "low"},
        "cameras": {"realsense_p": {"width": 64, "height": 48, "rate_hz": 10.0},
                    "realsense_secondary": {"enabled": False}, "realsense_tertiary": {"enabled": False}},
        "lidar": {"samples_per_ring": 90, "backend": "numba"}, "sensor_workers": sensor_workers,
        "faults": faults})


SIM_FAULTS = [{"kind": "gps_outage", "start_s": 0.3, "duration_s": 0.3},
              {"kind": "camera_blackout", "start_s": 0.2, "duration_s": 0.3, "camera": "realsense_p"},
              {"kind": "lidar_dropout", "start_s": 0.5, "duration_s": 0.3}]


def _run(config, seconds=1.0):
    import pathlib
    from cottonsim_world.robot.urdf_model import UrdfModel
    from cottonsim_world.simulator import Simulator
    urdf = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"
    sim = Simulator(config, UrdfModel.from_file(urdf))
    out = []
    while sim.time_s < seconds - 1e-9:
        sim.command_velocity(0.4, 0.2)
        out.extend(sim.step())
    out.extend(sim.flush_readings())
    sim.close()
    return out


def test_scheduled_faults_in_the_simulator_touch_only_their_sensor_and_window():
    faulty, clean = _run(_sim_config(SIM_FAULTS)), _run(_sim_config([]))
    stamps = lambda rs, kind: [r.stamp_s for r in rs if isinstance(r, kind)]
    gps_f, gps_c = stamps(faulty, GpsReading), stamps(clean, GpsReading)
    assert [t for t in gps_c if not 0.3 <= t < 0.6] == gps_f and len(gps_c) - len(gps_f) == 12   # 0.3 s at 40 Hz
    # the other fixes are exactly the clean run's: a fault does not shift the noise streams
    fixes = lambda rs: {r.stamp_s: (r.latitude_deg, r.longitude_deg) for r in rs if isinstance(r, GpsReading)}
    assert all(fixes(clean)[t] == v for t, v in fixes(faulty).items())
    assert [t for t in stamps(clean, LidarReading) if not 0.5 <= t < 0.8] == stamps(faulty, LidarReading)
    cams = [r for r in faulty if isinstance(r, CameraReading)]
    assert len(cams) == len(stamps(clean, CameraReading))                 # black frames keep coming
    for r in cams:
        assert (not r.frame.rgb.any()) == (0.2 <= r.stamp_s < 0.5), r.stamp_s


def test_pipelined_sensors_see_the_same_faults():
    serial, pipelined = _run(_sim_config(SIM_FAULTS)), _run(_sim_config(SIM_FAULTS, sensor_workers=1))
    key = lambda rs: [(type(r).__name__, r.stamp_s) for r in rs if isinstance(r, (GpsReading, CameraReading,
                                                                                  LidarReading))]
    assert key(serial) == key(pipelined)
    black = lambda rs: [r.stamp_s for r in rs if isinstance(r, CameraReading) and not r.frame.rgb.any()]
    assert black(serial) == black(pipelined) and black(serial)
