"""Pipelined sensors (SimulatorConfig.sensor_workers > 0): same readings as serial, bounded lag."""
import dataclasses
import math
import sys
import time

import numpy as np
import pytest

from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.readings import CameraReading, LidarReading
from cottonsim_world.simulator import Simulator
from cottonsim_world.simulator_config import SimulatorConfig


def config(workers, seed=5):
    """Two cameras at different rates (with their clouds), the LiDAR, every light sensor."""
    return simulator_config_from_dict({
        "seed": seed,
        "sensor_workers": workers,
        "farm": {"rows": 2, "plants_per_row": 4, "plant_detail": "low"},
        "cameras": {"realsense_p": {"width": 64, "height": 48, "rate_hz": 30.0},
                    "realsense_secondary": {"width": 48, "height": 32, "rate_hz": 10.0},
                    "realsense_tertiary": {"enabled": False}},
        "lidar": {"samples_per_ring": 90},
        "gps_noise": {"gaussian_noise_m": [0.05, 0.05, 0.0]},
    })


def drive(sim, seconds, on_step=None):
    """Step with an arc command for ``seconds`` of sim time; every reading, then the pending ones."""
    out = []
    while sim.time_s < seconds - 1e-9:
        sim.command_velocity(0.4, 0.3)
        got = sim.step()
        if on_step is not None:
            on_step(sim, got)
        out.extend(got)
    out.extend(sim.flush_readings())
    return out


def assert_same(a, b, path="reading"):
    """Equal values, arrays bit for bit (NaN where NaN), recursing into dataclasses."""
    assert type(a) is type(b), f"{path}: {type(a).__name__} vs {type(b).__name__}"
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{path}.{f.name}")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, f"{path}: {a.dtype}{a.shape} vs {b.dtype}{b.shape}"
        assert np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"), f"{path} differs"
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), f"{path}: length {len(a)} vs {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]")
    else:
        assert a == b, f"{path}: {a!r} vs {b!r}"


def run_stream(urdf, workers, seconds=0.6, slow_lidar_s=0.0, on_step=None):
    sim = Simulator(config(workers), urdf)
    if slow_lidar_s > 0.0:           # a scan that takes long in wall time: physics must wait for it
        scan = sim.lidar.scan
        sim.lidar.scan = lambda pose, visibility: (time.sleep(slow_lidar_s), scan(pose, visibility))[1]
    try:
        return drive(sim, seconds, on_step), sim.sensor_names
    finally:
        sim.close()


@pytest.mark.parametrize("workers", [1, 2])
def test_pipelined_readings_equal_the_serial_ones(urdf, workers):
    serial, names = run_stream(urdf, 0)
    piped, _ = run_stream(urdf, workers)
    kinds = {type(r).__name__ for r in serial}
    assert {"CameraReading", "LidarReading", "ImuReading", "GpsReading", "OdometryReading"} <= kinds
    assert len(piped) == len(serial)
    for i, (a, b) in enumerate(zip(serial, piped)):
        assert_same(a, b, f"reading {i} ({type(a).__name__} at {a.stamp_s:.3f} s)")
    assert any(isinstance(r, CameraReading) and r.cloud_xyzrgb is not None for r in piped)


def test_physics_runs_at_most_one_sensor_period_ahead(urdf):
    """A slow LiDAR job: readings come out late, but in order and within the longest sensor period.

    A reading waits for the jobs ahead of it, so the bound of every reading is the longest
    period of the pipelined sensors (0.1 s); the LiDAR is due every 0.1 s.
    """
    longest_period_s = 0.1
    seen = []
    sims = []
    clock = [0.0]
    lags = []

    def check(sim, got):
        assert sim.pipelined
        sims.append(sim)
        delivered = sim.delivered_time_s
        assert delivered <= sim.time_s + 1e-12
        assert delivered >= clock[-1], "delivered_time_s (the bridge's /clock) went back"
        clock.append(delivered)
        lags.append(sim.time_s - delivered)
        for r in got:
            assert r.stamp_s <= delivered + 1e-12, "a reading stamped after delivered_time_s"
            assert sim.time_s <= r.stamp_s + longest_period_s + 1e-9, f"{r} at {r.stamp_s} came at {sim.time_s}"
            seen.append((r.stamp_s, sim.time_s))
        assert sim.time_s - delivered <= longest_period_s + 1e-9

    piped, _ = run_stream(urdf, 1, seconds=0.5, slow_lidar_s=0.05, on_step=check)
    stamps = [r.stamp_s for r in piped]
    assert stamps == sorted(stamps)
    assert max(t - s for s, t in seen) > 0.05, "nothing was returned late: the jobs did not run on a worker"
    assert sims[-1].sensor_wait_s > 0.0, "the physics never waited for the slow scans"
    assert max(lags) > 0.05, "delivered_time_s never lagged the physics"
    serial, _ = run_stream(urdf, 0, seconds=0.5)
    assert [type(r) for r in piped] == [type(r) for r in serial]
    assert [r.stamp_s for r in piped] == [r.stamp_s for r in serial]


def test_serial_mode_returns_each_reading_in_its_own_step(urdf):
    def check(sim, got):
        assert not sim.pipelined
        assert sim.delivered_time_s == sim.time_s
        assert sim.sensor_wait_s == 0.0
        assert all(r.stamp_s == sim.time_s for r in got)

    run_stream(urdf, 0, seconds=0.3, on_step=check)


def test_close_with_pending_jobs_returns(urdf):
    sim = Simulator(config(1), urdf)
    scan = sim.lidar.scan
    sim.lidar.scan = lambda pose, visibility: (time.sleep(0.2), scan(pose, visibility))[1]
    sim.step_for(0.05)
    assert sim.delivered_time_s < sim.time_s          # the first LiDAR scan is still pending
    sim.close()
    assert sim.flush_readings() == []


@pytest.mark.parametrize("bad", [-1, 9, 1.0, True, None])
def test_sensor_workers_is_validated(bad):
    with pytest.raises(ValueError, match="sensor_workers"):
        SimulatorConfig(sensor_workers=bad)


def test_switch_interval_is_set_while_pipelined_and_restored(urdf):
    python_default = sys.getswitchinterval()
    faster = dataclasses.replace(config(0), sensor_switch_interval_s=0.0005)
    serial = Simulator(faster, urdf)
    assert sys.getswitchinterval() == python_default            # serial: never touched
    serial.close()
    piped = Simulator(dataclasses.replace(faster, sensor_workers=1), urdf)
    assert sys.getswitchinterval() == pytest.approx(0.0005)
    piped.close()
    assert sys.getswitchinterval() == python_default
    default = Simulator(config(1), urdf)                          # default 0: left as Python has it
    assert sys.getswitchinterval() == python_default
    default.close()
    with pytest.raises(ValueError, match="sensor_switch_interval_s"):
        SimulatorConfig(sensor_switch_interval_s=-0.001)


def test_two_workers_refuse_the_pybullet_backends():
    from cottonsim_world.sensors.lidar import LidarConfig
    with pytest.raises(ValueError, match="lidar"):
        SimulatorConfig(sensor_workers=2, lidar=LidarConfig(backend="pybullet"))
    SimulatorConfig(sensor_workers=1, lidar=LidarConfig(backend="pybullet"))       # one at a time is fine
    SimulatorConfig(sensor_workers=2, lidar=LidarConfig(backend="pybullet"), lidar_enabled=False)


def test_no_workers_without_heavy_sensors(urdf):
    cfg = simulator_config_from_dict({"sensor_workers": 2, "lidar_enabled": False,
                                      "farm": {"rows": 2, "plants_per_row": 4, "plant_detail": "low"},
                                      "cameras": {c: {"enabled": False} for c in
                                                  ("realsense_p", "realsense_secondary", "realsense_tertiary")}})
    sim = Simulator(cfg, urdf)
    assert not sim.pipelined
    assert math.isclose(sim.step_for(0.1)[-1].stamp_s, 0.1)
    sim.close()


def test_a_failing_job_raises_in_the_stepping_thread(urdf):
    sim = Simulator(config(1), urdf)

    def broken(pose, visibility):
        raise RuntimeError("scan failed")

    sim.lidar.scan = broken
    try:
        with pytest.raises(RuntimeError, match="scan failed"):
            sim.step_for(0.3)       # the first scan is due at once and must be in by its next one
    finally:
        sim.close()


def test_commands_and_teleports_at_the_same_steps_give_the_same_readings(urdf):
    """Inputs act on the physics step they are given at, pipelined or not: same stream as serial."""
    def scripted(workers):
        sim = Simulator(config(workers), urdf)
        out = []
        try:
            for i in range(140):
                sim.command_velocity(0.6 if i < 70 else -0.3, 0.4 if i % 30 < 15 else -0.2)
                if i == 55:              # a kidnap while camera and LiDAR jobs are pending
                    sim.teleport_robot(-4.0, 2.0, 1.0)
                out.extend(sim.step())
            out.extend(sim.flush_readings())
        finally:
            sim.close()
        return out

    serial, piped = scripted(0), scripted(1)
    assert len(piped) == len(serial)
    for i, (a, b) in enumerate(zip(serial, piped)):
        assert_same(a, b, f"reading {i} ({type(a).__name__} at {a.stamp_s:.3f} s)")
